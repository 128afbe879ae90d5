"""The native module: every argument positional (normalfit's functions name them)."""

import os
from collections.abc import Sequence
from typing import Any, final

from normalfit import AxisReport as AxisReport, ConversionSummary as ConversionSummary, HeightInfo as HeightInfo, TilingReport as TilingReport

__all__ = [
    "normals",
    "mips",
    "curvature",
    "window_normals",
    "window_plan",
    "window_halo",
    "border_names",
    "geotransform_spacing",
    "centres_geotransform",
    "check_tiling",
    "check_tiling_file",
    "convert",
    "decode_normals",
    "lit_view",
    "height",
    "height_file",
    "blend",
    "check_map",
    "ConversionSummary",
    "HeightInfo",
    "AxisReport",
    "TilingReport",
    "_HeightSeams",
    "_kept_pools",
    "__version__",
]

__version__: str

def _kept_pools() -> list[int]: ...

def normals(
    heights: Any,
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    dtype: Any,
    residual: bool,
    out: Any | None,
    threads: int | None,
    units: str,
    pixel_size: Any | None,
    nodata: float | None,
    detail: Any | None = None,
    weights: str = "uniform",
    product: str | None = None,
    slope_units: str = "degrees",
    zero_for_flat: bool = False,
    azimuth: float = 315.0,
    altitude: float = 45.0,
    transform: Any | None = None,
) -> Any: ...
def curvature(
    heights: Any,
    patch: Any,
    border: Any,
    scale: float | None,
    relief: float | None,
    invert: bool,
    threads: int | None,
    units: str,
    pixel_size: Any | None,
    nodata: float | None,
) -> Any: ...
def mips(
    array: Any,
    way: str,
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    dtype: Any,
    roughness: bool,
    roughness_base: Any | None,
) -> Any: ...
def check_tiling(image: Any, threshold: float, kind: str) -> TilingReport: ...
def check_tiling_file(
    path: str | os.PathLike[str], threshold: float, kind: str, channel: str | None, max_texels: int | None, layer: str | None
) -> TilingReport: ...
def convert(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    channel: str | None,
    bits: int | None,
    format: str | None,
    signed: bool,
    compression: str,
    alpha: str,
    channels: str,
    residual: bool,
    max_texels: int | None,
    layer: str | None,
    units: str,
    pixel_size: tuple[float, float] | None,
    band: Any | None,
    size: Any | None,
    byte_order: str | None,
    decode: str | None,
    nodata: float | None,
    nodata_tag: bool,
    detail: Any | None = None,
    weights: str = "uniform",
    product: str = "normals",
    slope_units: str = "degrees",
    zero_for_flat: bool = False,
    azimuth: float = 315.0,
    altitude: float = 45.0,
) -> ConversionSummary: ...
def blend(
    base: Any, detail: Any, method: str, strength: float, convention: str, detail_convention: str | None
) -> Any: ...
def check_map(
    path: str | os.PathLike[str],
    convention: str,
    threshold: float | None,
    signed: bool,
    fix: str | os.PathLike[str] | None,
    to: str | None,
    max_texels: int | None,
    layer: str | None,
) -> dict[str, Any]: ...
def decode_normals(path: str | os.PathLike[str], signed: bool, max_texels: int | None, layer: str | None) -> Any: ...
def lit_view(
    path: str | os.PathLike[str],
    light: tuple[float, float] | None,
    azimuth: float | None,
    altitude: float | None,
    tile: bool,
    kind: str,
    channel: str | None,
    signed: bool,
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    max_texels: int | None,
    layer: str | None,
    units: str,
    pixel_size: tuple[float, float] | None,
    band: Any | None,
    size: Any | None,
    byte_order: str | None,
    decode: str | None,
    nodata: float | None,
    nodata_tag: bool,
    detail: Any | None = None,
    weights: str = "uniform",
) -> Any: ...
def height(
    normals: Any,
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    model: str,
    step: float | None,
    threads: int | None,
    holes: Any,
) -> tuple[Any, HeightInfo]: ...
def height_file(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    model: str,
    signed: bool,
    format: str | None,
    max_texels: int | None,
    layer: str | None,
) -> HeightInfo: ...
def window_normals(
    heights: Any,
    image: tuple[int, int],
    origin: tuple[int, int],
    halo: tuple[int, int, int, int],
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    dtype: Any,
    residual: bool,
    threads: Any | None,
    nodata: float | None = None,
    detail: Any | None = None,
    units: str = "texels",
    pixel_size: Any | None = None,
    weights: str = "uniform",
    product: str | None = None,
    slope_units: str = "degrees",
    zero_for_flat: bool = False,
    azimuth: float = 315.0,
    altitude: float = 45.0,
    transform: Any | None = None,
) -> Any: ...
def window_plan(
    image: tuple[int, int],
    heights_dtype: Any,
    patch: Any,
    fit: str,
    border: Any,
    convention: str,
    scale: float | None,
    relief: float | None,
    invert: bool,
    dtype: Any,
    threads: Any | None,
    nodata: float | None = None,
    detail: Any | None = None,
    units: str = "texels",
    pixel_size: Any | None = None,
    weights: str = "uniform",
) -> tuple[int, tuple[bool, bool]]: ...
def window_halo(
    image: tuple[int, int],
    origin: tuple[int, int],
    size: tuple[int, int],
    patch: Any,
    border: Any,
    detail: Any | None = None,
    weights: str = "uniform",
) -> tuple[int, int, int, int]: ...
def border_names(border: Any) -> tuple[str, str]: ...
def geotransform_spacing(transform: Any, crs: str | None, unit: int | None, height: int) -> Any: ...
def centres_geotransform(x: Sequence[float], y: Sequence[float]) -> list[float]: ...
@final
class _HeightSeams:
    def __new__(
        cls, width: int, height: int, refuse_non_finite: bool = False, nodata: float | None = None
    ) -> _HeightSeams: ...
    def push(self, rows: Any) -> None: ...
    @property
    def edge_columns(self) -> tuple[tuple[int, int], tuple[int, int]]: ...
    @property
    def edge_rows(self) -> tuple[tuple[int, int], tuple[int, int]]: ...
    def push_columns(self, rows: Any) -> None: ...
    def push_rows(self, rows: Any) -> None: ...
    @property
    def rows(self) -> int: ...
    def finish(self, threshold: float) -> TilingReport: ...
