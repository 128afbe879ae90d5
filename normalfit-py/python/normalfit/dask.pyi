"""Type stubs of normalfit.dask (the functions are in dask.py)."""

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal, overload

from . import TilingReport

__all__ = ["check_tiling", "normals", "read_zarr", "to_zarr"]

_Border = Literal["wrap", "clamp", "mirror"]

@overload
def normals(
    array: Any,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: _Border | tuple[_Border, _Border] | str = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: Any = ...,
    residual: Literal[False] = False,
    threads: int | None = 1,
    nodata: float | None = None,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
    units: Literal["texels", "map"] = "texels",
    pixel_size: float | tuple[float, float] | Any | None = None,
    _product: dict[str, Any] | None = None,
) -> Any: ...
@overload
def normals(
    array: Any,
    *,
    patch: int = 3,
    fit: Literal["orthogonal", "vertical"] = "orthogonal",
    border: _Border | tuple[_Border, _Border] | str = "wrap",
    convention: Literal["opengl", "gl", "directx", "dx"] = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: Any = ...,
    residual: Literal[True],
    threads: int | None = 1,
    nodata: float | None = None,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
    units: Literal["texels", "map"] = "texels",
    pixel_size: float | tuple[float, float] | Any | None = None,
) -> tuple[Any, Any]: ...
def check_tiling(
    array: Any,
    *,
    threshold: float = 1.5,
    kind: Literal["auto", "height"] = "auto",
    nodata: float | None = None,
) -> TilingReport: ...
def read_zarr(path: str | os.PathLike[str], *, component: str | None = None, chunks: Any = None) -> Any: ...
def to_zarr(array: Any, path: str | os.PathLike[str], *, overwrite: bool = False, **kwargs: Any) -> Path: ...
