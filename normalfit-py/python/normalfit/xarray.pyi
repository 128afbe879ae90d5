"""Type stubs of normalfit.xarray (the functions are in xarray.py)."""

from collections.abc import Sequence
from typing import Any, Literal, overload

import xarray as xr

__all__ = ["NormalfitAccessor", "aspect", "curvature", "hillshade", "normals", "slope", "spacing"]

_Border = Literal["wrap", "clamp", "mirror", "auto"]

def spacing(da: xr.DataArray) -> Any: ...
def slope(
    da: xr.DataArray, *, slope_units: Literal["degrees", "percent"] = "degrees", **options: Any
) -> xr.DataArray: ...
def aspect(da: xr.DataArray, *, zero_for_flat: bool = False, **options: Any) -> xr.DataArray: ...
def hillshade(da: xr.DataArray, *, azimuth: float = 315.0, altitude: float = 45.0, **options: Any) -> xr.DataArray: ...
@overload
def normals(
    da: xr.DataArray,
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
    threads: int | None = None,
    units: Literal["texels", "map"] = "map",
    pixel_size: Any = None,
    nodata: float | Literal["auto"] | None = "auto",
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
) -> xr.DataArray: ...
@overload
def normals(
    da: xr.DataArray,
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
    threads: int | None = None,
    units: Literal["texels", "map"] = "map",
    pixel_size: Any = None,
    nodata: float | Literal["auto"] | None = "auto",
    detail: Sequence[tuple[int, float]] | None = None,
    weights: Literal["uniform", "binomial"] = "uniform",
) -> tuple[xr.DataArray, xr.DataArray]: ...
def curvature(
    da: xr.DataArray,
    *,
    patch: int = 3,
    border: _Border | tuple[_Border, _Border] | str = "wrap",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    threads: int | None = None,
    units: Literal["texels", "map"] = "map",
    pixel_size: Any = None,
    nodata: float | Literal["auto"] | None = "auto",
) -> xr.DataArray: ...

class NormalfitAccessor:
    def __init__(self, da: xr.DataArray) -> None: ...
    def normals(self, **options: Any) -> Any: ...
    def curvature(self, **options: Any) -> xr.DataArray: ...
    def slope(self, **options: Any) -> xr.DataArray: ...
    def aspect(self, **options: Any) -> xr.DataArray: ...
    def hillshade(self, **options: Any) -> xr.DataArray: ...
    def spacing(self) -> Any: ...
