"""Type stubs of normalfit (the functions are in __init__.py, the classes native)."""

import os
from collections.abc import Sequence
from typing import Any, Literal, final

import numpy as np
import numpy.typing as npt

from . import _normalfit as _normalfit

__version__: str
__all__ = [
    "AxisReport",
    "ConversionSummary",
    "HeightInfo",
    "TilingReport",
    "blend",
    "check_map",
    "check_tiling",
    "convert",
    "curvature",
    "decode_normals",
    "height",
    "height_file",
    "aspect",
    "hillshade",
    "lit_view",
    "mips",
    "normals",
    "slope",
]

_Border = Literal["wrap", "clamp", "mirror"]
_BorderChoice = Literal["wrap", "clamp", "mirror", "auto"]
_Path = str | os.PathLike[str]
_Heights = npt.NDArray[np.uint8] | npt.NDArray[np.uint16] | npt.NDArray[np.float32] | npt.NDArray[np.float64]

@final
class AxisReport:
    """One axis of a tiling report."""

    @property
    def score(self) -> float: ...
    @property
    def seamless(self) -> bool: ...

@final
class TilingReport:
    """The tiling check's verdict on an array."""

    @property
    def kind(self) -> Literal["height", "normal"]: ...
    @property
    def x(self) -> AxisReport: ...
    @property
    def y(self) -> AxisReport: ...
    @property
    def seamless(self) -> bool: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def suggested_borders(self) -> tuple[_Border, _Border]: ...

def normals(
    heights: _Heights,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_BorderChoice, _BorderChoice] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: npt.DTypeLike = ...,
    residual: bool = False,
    out: npt.NDArray[Any] | None = None,
    threads: int | None = None,
    units: Literal["texels", "map"] = "texels",
    pixel_size: float | tuple[float, float] | npt.NDArray[Any] | None = None,
    nodata: float | None = None,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
    _product: dict[str, Any] | None = None,
) -> Any: ...
def slope(
    heights: _Heights, *, slope_units: Literal["degrees", "percent"] = "degrees", **options: Any
) -> npt.NDArray[np.float32]: ...
def aspect(heights: _Heights, *, zero_for_flat: bool = False, **options: Any) -> npt.NDArray[np.float32]: ...
def hillshade(
    heights: _Heights, *, azimuth: float = 315.0, altitude: float = 45.0, **options: Any
) -> npt.NDArray[np.uint8]: ...
def curvature(
    heights: _Heights,
    *,
    patch: int = 3,
    border: str | tuple[_BorderChoice, _BorderChoice] = "wrap",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    threads: int | None = None,
    units: Literal["texels", "map"] = "texels",
    pixel_size: float | tuple[float, float] | npt.NDArray[Any] | None = None,
    nodata: float | None = None,
) -> npt.NDArray[np.float32]: ...
def mips(
    array: _Heights,
    *,
    way: Literal["auto", "fit", "average", "mean"] = "auto",
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_BorderChoice, _BorderChoice] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: npt.DTypeLike = ...,
    roughness: bool = False,
    roughness_base: _Heights | None = None,
) -> Any: ...
@final
class ConversionSummary:
    """What a conversion did."""

    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def input_format(self) -> str: ...
    @property
    def borders(self) -> tuple[_Border, _Border]: ...
    @property
    def streamed(self) -> bool: ...
    @property
    def tiling(self) -> TilingReport | None: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def nodata(self) -> float | None: ...
    @property
    def missing(self) -> int: ...

def check_tiling(
    image: _Heights | _Path,
    *,
    threshold: float = 1.5,
    kind: Literal["auto", "height", "normal"] = "auto",
    channel: str | None = None,
    max_texels: int | None = None,
    layer: str | None = None,
) -> TilingReport: ...
def convert(
    src: _Path,
    dst: _Path,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_BorderChoice, _BorderChoice] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    channel: str | None = None,
    bits: Literal[8, 16, 32] | None = None,
    format: Literal["png", "exr"] | None = None,
    signed: bool = False,
    compression: Literal["fast", "small"] = "fast",
    alpha: Literal["none", "height", "one"] = "none",
    channels: Literal["rgb", "rg"] = "rgb",
    residual: bool = False,
    max_texels: int | None = None,
    layer: str | None = None,
    units: Literal["texels", "map"] = "texels",
    pixel_size: float | tuple[float, float] | None = None,
    band: int | None = None,
    size: tuple[int, int] | str | None = None,
    byte_order: Literal["little", "le", "big", "be"] | None = None,
    decode: Literal["terrain-rgb", "mapbox", "terrarium"] | None = None,
    nodata: float | None = None,
    nodata_tag: bool = True,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
    product: Literal["normals", "slope", "aspect", "hillshade", "curvature"] = "normals",
    slope_units: Literal["degrees", "percent"] = "degrees",
    zero_for_flat: bool = False,
    azimuth: float = 315.0,
    altitude: float = 45.0,
) -> ConversionSummary: ...
def decode_normals(
    path: _Path, *, signed: bool = False, max_texels: int | None = None, layer: str | None = None
) -> npt.NDArray[np.float32]: ...
def lit_view(
    path: _Path,
    *,
    light: tuple[float, float] | None = None,
    azimuth: float | None = None,
    altitude: float | None = None,
    tile: bool = False,
    kind: Literal["auto", "height", "normal"] = "auto",
    channel: str | None = None,
    signed: bool = False,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_BorderChoice, _BorderChoice] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    max_texels: int | None = None,
    layer: str | None = None,
    units: Literal["texels", "map"] = "texels",
    pixel_size: float | tuple[float, float] | None = None,
    band: int | None = None,
    size: tuple[int, int] | str | None = None,
    byte_order: Literal["little", "le", "big", "be"] | None = None,
    decode: Literal["terrain-rgb", "mapbox", "terrarium"] | None = None,
    nodata: float | None = None,
    nodata_tag: bool = True,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
) -> npt.NDArray[np.uint8]: ...
@final
class HeightInfo:
    """What height() and height_file() found besides the heights."""

    @property
    def convention(self) -> Literal["opengl", "directx"]: ...
    @property
    def curl(self) -> tuple[float, float] | None: ...
    @property
    def bad_texels(self) -> int: ...
    @property
    def iterations(self) -> int: ...
    @property
    def converged(self) -> bool: ...
    @property
    def quantisation_error(self) -> float | None: ...
    @property
    def range(self) -> tuple[float, float]: ...
    @property
    def holes(self) -> int: ...
    @property
    def undetermined(self) -> int: ...
    @property
    def png_range(self) -> tuple[float, float] | None: ...
    @property
    def png_scale(self) -> float | None: ...
    @property
    def warnings(self) -> list[str]: ...

def height(
    normals: _Heights,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_Border, _Border] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx", "auto"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    model: Literal["exact", "generic", "frankot-chellappa", "fc"] = "exact",
    step: float | None = None,
    threads: int | None = None,
    holes: npt.ArrayLike | None = None,
) -> tuple[npt.NDArray[np.float64], HeightInfo]: ...
def height_file(
    src: _Path,
    dst: _Path,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: str | tuple[_Border, _Border] = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx", "auto"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    model: Literal["exact", "generic", "frankot-chellappa", "fc"] = "exact",
    signed: bool = False,
    format: Literal["png", "exr"] | None = None,
    max_texels: int | None = None,
    layer: str | None = None,
) -> HeightInfo: ...
def blend(
    base: npt.NDArray[Any],
    detail: npt.NDArray[Any],
    *,
    method: Literal["rnm", "reoriented", "whiteout", "udn", "linear"] = "rnm",
    strength: float = 1.0,
    convention: Literal["opengl", "gl", "directx", "dx", "auto"] = "auto",
    detail_convention: Literal["opengl", "gl", "directx", "dx", "auto"] | None = None,
) -> npt.NDArray[np.float64]: ...
def check_map(
    path: _Path,
    *,
    convention: Literal["opengl", "gl", "directx", "dx", "auto"] = "auto",
    threshold: float | None = None,
    signed: bool = False,
    fix: _Path | None = None,
    to: Literal["opengl", "gl", "directx", "dx"] | None = None,
    max_texels: int | None = None,
    layer: str | None = None,
) -> dict[str, Any]: ...
