"""normalfit on xarray DataArrays: a DEM as rioxarray opens it in, its
normals (and curvature) out as DataArrays on the same grid, with its
coordinates, CRS and attributes, NumPy- or Dask-backed.

>>> import rioxarray, normalfit.xarray
>>> dem = rioxarray.open_rasterio("dem.tif").squeeze("band", drop=True)
>>> n = dem.normalfit.normals(patch=5)           # (band: 3, y, x), band x, y, z
>>> n.rio.to_raster("normals.tif")                # the DEM's CRS and transform

A DataArray carries its spacing, so the fit is in map units by default
(``units="map"``): heights as stored (metres), texels as far apart as the
ground says. The spacing is the library's rule, the command line's on the
same GeoTIFF (``normalfit::units::geotransform_spacing``): the transform
rioxarray holds (``da.rio.transform()``), else the regular step of the 1-D
x and y coordinates (``normalfit::units::centres_geotransform``; irregular
ones are refused); a projected CRS's step in its linear unit turned into
metres, a geographic CRS's degrees into metres at each row's latitude (one
spacing per row), a rotated or sheared transform refused naming its angle.
Holes: the DataArray's nodata (``rio.nodata``, the ``_FillValue`` or
``nodatavals`` attribute) and NaN. docs/xarray.md has the rest.

Importing this module registers the accessor ``da.normalfit``. Requires
xarray; rioxarray (the ``xarray`` extra) for the CRS, the transform and
``to_raster``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import xarray as xr

from . import _normalfit
from . import curvature as _curvature
from . import normals as _normals

__all__ = ["NormalfitAccessor", "aspect", "curvature", "hillshade", "normals", "slope", "spacing"]

# Attributes that describe the heights' values and no longer hold for a
# product made from them (its units are set anew).
_VALUE_ATTRS = (
    "_FillValue", "missing_value", "fill_value", "nodata", "nodatavals", "scale_factor", "add_offset",
    "valid_min", "valid_max", "valid_range", "units", "long_name", "standard_name",
)


def _rio(da: xr.DataArray) -> Any:
    """rioxarray's accessor, or None when rioxarray is not installed."""
    try:
        import rioxarray  # noqa: F401  (registers da.rio)
    except ImportError:
        return None
    return da.rio


def _axes(da: xr.DataArray) -> tuple[str, str]:
    """The (y, x) dims of a 2-D DataArray, rows first."""
    if not isinstance(da, xr.DataArray):
        raise TypeError(f"expected an xarray.DataArray, got {type(da).__name__}")
    if da.ndim != 2:
        raise TypeError(
            f"a 2-D DataArray of heights is needed, got dims {da.dims}: select one band first (da.sel(band=1))"
        )
    rio = _rio(da)
    if rio is not None:
        try:
            (y, x) = (rio.y_dim, rio.x_dim)
        except Exception:  # rioxarray finds no spatial dims: take the order
            (y, x) = (str(da.dims[0]), str(da.dims[1]))
        if (str(da.dims[0]), str(da.dims[1])) != (y, x):
            raise ValueError(f"dims must be rows then columns ({y!r}, {x!r}), got {da.dims}: transpose it first")
        return (y, x)
    return (str(da.dims[0]), str(da.dims[1]))


def _crs(da: xr.DataArray) -> tuple[str | None, int | None]:
    """The CRS kind ("projected", "geographic" or None) and the EPSG code
    of its horizontal unit, which the library turns into metres."""
    rio = _rio(da)
    crs = rio.crs if rio is not None else None
    if crs is None:
        return (None, None)
    import pyproj

    proj = pyproj.CRS.from_user_input(crs.to_wkt())
    kind = "geographic" if proj.is_geographic else "projected" if proj.is_projected else None
    if kind is None:
        raise ValueError(f"map units take projected or geographic coordinates, the CRS is {proj.name!r}")
    axis = proj.axis_info[0]
    try:
        code = int(axis.unit_code)
    except (TypeError, ValueError):
        raise ValueError(
            f"the CRS's unit {axis.unit_name!r} has no EPSG code, which the spacing needs: give pixel_size"
        ) from None
    return (kind, code)


def _geotransform(da: xr.DataArray, dims: tuple[str, str]) -> list[float]:
    """GDAL's geotransform of the DataArray: rioxarray's transform when it
    holds one, else the one its 1-D coordinates imply (the library checks
    that their steps are regular)."""
    (y, x) = dims
    xs = da.coords[x].values if x in da.coords and da.coords[x].ndim == 1 else None
    ys = da.coords[y].values if y in da.coords and da.coords[y].ndim == 1 else None
    rio = _rio(da)
    stored = None
    if rio is not None:
        try:
            stored = da.coords[rio.grid_mapping].attrs.get("GeoTransform")
        except KeyError:
            stored = None
    coords = None
    if xs is not None and ys is not None and len(xs) > 1 and len(ys) > 1:
        coords = _normalfit.centres_geotransform(
            np.asarray(xs, np.float64).tolist(), np.asarray(ys, np.float64).tolist()
        )
    if stored is None:
        if coords is None:
            raise ValueError(
                "the DataArray holds no spacing: neither a transform (rioxarray's GeoTransform) nor 1-D x and y "
                "coordinates of 2 or more texels; give pixel_size, or units='texels'"
            )
        return list(coords)
    t = rio.transform()
    gt = [t.c, t.a, t.b, t.f, t.d, t.e]
    # rioxarray takes the origin from the coordinates, half a step before
    # the first centre, which can differ from the stored one in the last
    # bit: the stored one, when it is the same place, is the file's.
    file = [float(v) for v in str(stored).split()]
    if len(file) == 6 and all(abs(a - b) <= 1e-9 * (abs(gt[1]) + abs(gt[5])) for a, b in zip(gt, file)):
        gt = file
    return gt


def spacing(da: xr.DataArray) -> Any:
    """The texel spacing normalfit fits ``da`` with in map units, in
    metres (in the coordinates' unit without a CRS): an (x, y) pair, or
    for a geographic CRS a (rows, 2) float64 array, one (x, y) per row.
    The library's rule (``normalfit::units::geotransform_spacing``), the
    command line's on the same GeoTIFF.

    Raises ValueError for a rotated or sheared transform, irregular
    coordinates, a unit the library does not know, a DataArray without
    a transform or coordinates; TypeError for one that is not 2-D."""
    dims = _axes(da)
    (kind, unit) = _crs(da)
    return _normalfit.geotransform_spacing(_geotransform(da, dims), kind, unit, int(da.shape[0]))


def _nodata(da: xr.DataArray, nodata: Any, float_output: bool) -> float | None:
    """The holes' value: the one given, else ("auto") the DataArray's
    nodata, else NaN for float heights into float normals."""
    if nodata is None:
        return None
    if not (isinstance(nodata, str) and nodata == "auto"):
        return float(nodata)
    rio = _rio(da)
    value = rio.nodata if rio is not None else None
    if value is None:
        value = da.attrs.get("_FillValue")
    if value is None and "nodatavals" in da.attrs:
        values = np.atleast_1d(da.attrs["nodatavals"])
        value = values[0] if values.size else None
    if value is not None:
        return float(value)
    if np.issubdtype(da.dtype, np.floating) and float_output:
        return float("nan")
    return None


def _units(da: xr.DataArray, units: str, pixel_size: Any) -> tuple[str, Any]:
    """``units`` and ``pixel_size`` for the array fit: the DataArray's
    spacing in map units unless a pixel size is given."""
    if pixel_size is not None or units != "map":
        return (units, pixel_size)
    return ("map", spacing(da))


def _product(
    da: xr.DataArray,
    values: Any,
    name: str,
    units: str | None,
    band: bool,
    dims: tuple[str, str],
    hole: Any = None,
) -> xr.DataArray:
    """``values`` on ``da``'s grid: its coords (the CRS's ``spatial_ref``
    among them), its attributes but those of the heights' values, and
    ``band`` (x, y, z) first for normals, as rioxarray writes bands."""
    coords = {k: v for k, v in da.coords.items() if k != "band"}
    attrs = {k: v for k, v in da.attrs.items() if k not in _VALUE_ATTRS}
    if units is not None:
        attrs["units"] = units
    attrs["long_name"] = name
    if band:
        data = values.transpose(2, 0, 1)
        out = xr.DataArray(data, dims=("band", *dims), coords={**coords, "band": ["x", "y", "z"]}, attrs=attrs)
    else:
        out = xr.DataArray(values, dims=dims, coords=coords, attrs=attrs)
    out.name = name.replace(" ", "_")
    grid = da.encoding.get("grid_mapping", da.attrs.get("grid_mapping"))
    if grid is not None:
        out.encoding["grid_mapping"] = grid
    rio = _rio(da)
    if rio is not None and np.issubdtype(out.dtype, np.floating):
        # Holes are NaN: a GeoTIFF written from it says so.
        out = out.rio.write_nodata(np.nan, encoded=False)
    elif rio is not None and hole is not None:
        # An integer product's holes (the hillshade's 0).
        out = out.rio.write_nodata(hole, encoded=False)
    return out


def _is_dask(data: Any) -> bool:
    try:
        import dask.array
    except ImportError:
        return False
    return isinstance(data, dask.array.Array)


def normals(
    da: xr.DataArray,
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: Any = np.float32,
    residual: bool = False,
    threads: int | None = None,
    units: str = "map",
    pixel_size: Any = None,
    nodata: Any = "auto",
    detail: Sequence[tuple[int, float]] | None = None,
    weights: str = "uniform",
) -> Any:
    """The normals of a 2-D DataArray of heights, as a DataArray (band: 3,
    y, x) on its grid: band "x" east, "y" north (OpenGL's convention;
    south with convention="directx"), "z" up; float32 unit vectors
    (``units`` "1"), NaN at holes. Its coords (``spatial_ref``, the CRS,
    among them) and attributes are the input's (those of the heights'
    values dropped; ``units`` and ``long_name`` set). NumPy-backed in,
    NumPy out; Dask-backed in, Dask out, chunked like the input, equal to
    the NumPy result bit for bit (``normalfit.dask.normals``).

    The options are ``normalfit.normals``'s, with their defaults but one:
    ``units="map"`` (the DataArray carries its spacing; ``"texels"`` fits
    in the contract's units). border: the contract's default is "wrap"; a
    DEM does not tile, pass border="clamp" (as the command line's terrain
    examples do). pixel_size: replaces the DataArray's spacing (a pair, or a
    (rows, 2) array). nodata: "auto" (default): the DataArray's nodata
    (rioxarray's ``rio.nodata``, else its ``_FillValue`` or
    ``nodatavals`` attribute), else NaN for float heights (float32
    normals); a number; or None (no holes: a NaN height is an error).
    residual: also return the residual, a (y, x) DataArray in the
    heights' unit. threads: as ``normalfit.normals`` (NumPy) or
    ``normalfit.dask.normals`` (Dask; default 1 per task there).

    Raises TypeError for a DataArray that is not 2-D or of a dtype the fit
    does not take, ValueError for an option out of range, a spacing the
    library refuses (rotated, irregular, an unknown unit), a NaN height
    with nodata=None.
    """
    dims = _axes(da)
    (units, pixel_size) = _units(da, units, pixel_size)
    holes = _nodata(da, nodata, np.dtype(dtype) == np.float32)
    options: dict[str, Any] = dict(
        patch=patch, fit=fit, border=border, convention=convention, scale=scale, relief=relief, invert=invert,
        dtype=dtype, residual=residual, units=units, pixel_size=pixel_size, nodata=holes, detail=detail,
        weights=weights,
    )
    if _is_dask(da.data):
        from . import dask as ndask

        result = ndask.normals(da.data, threads=1 if threads is None else threads, **options)
    else:
        result = _normals(np.asarray(da.data), threads=threads, **options)
    encoded = np.dtype(dtype) != np.float32
    name = "encoded normal" if encoded else "unit normal"
    if residual:
        n, r = result
        res = _product(da, r, "residual", da.attrs.get("units") if units == "map" else None, False, dims)
        return _product(da, n, name, None if encoded else "1", True, dims), res
    return _product(da, result, name, None if encoded else "1", True, dims)


def curvature(
    da: xr.DataArray,
    *,
    patch: int = 3,
    border: str | tuple[str, str] = "wrap",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    threads: int | None = None,
    units: str = "map",
    pixel_size: Any = None,
    nodata: Any = "auto",
) -> xr.DataArray:
    """The mean curvature of a 2-D NumPy-backed DataArray of heights
    (``normalfit.curvature``), a float32 (y, x) DataArray on its grid: in
    1 / metre in map units (``units`` "1/m"; 1 / the coordinates' unit
    without a CRS), NaN where a patch holds a hole. The keywords and their
    defaults are ``normals``'s. A Dask-backed DataArray is refused
    (TypeError): the library's window fit makes normals only."""
    dims = _axes(da)
    if _is_dask(da.data):
        raise TypeError("curvature takes a NumPy-backed DataArray (the window fit makes normals only): da.compute()")
    (units, pixel_size) = _units(da, units, pixel_size)
    holes = _nodata(da, nodata, True)
    values = _curvature(
        np.asarray(da.data), patch=patch, border=border, scale=scale, relief=relief, invert=invert,
        threads=threads, units=units, pixel_size=pixel_size, nodata=holes,
    )
    unit = "1/m" if units == "map" and _crs(da)[0] is not None else None
    return _product(da, values, "mean curvature", unit, False, dims)


def _terrain(
    da: xr.DataArray, product: dict[str, Any], name: str, unit: str | None, options: dict[str, Any]
) -> xr.DataArray:
    """A terrain product of ``da`` (``normalfit.slope``, ``aspect`` or
    ``hillshade``, or their Dask twins), on its grid: every keyword of
    ``normals`` flows through, with this module's defaults for units,
    pixel_size, nodata and threads."""
    for key in ("dtype", "residual", "out"):
        if key in options:
            raise TypeError(f"{name}() got an unexpected keyword argument {key!r} (a normal map's option)")
    dims = _axes(da)
    rest = dict(options)
    (units, pixel_size) = _units(da, rest.pop("units", "map"), rest.pop("pixel_size", None))
    holes = _nodata(da, rest.pop("nodata", "auto"), True)
    threads = rest.pop("threads", None)
    if "transform" in rest:
        raise TypeError(f"{name}() got an unexpected keyword argument 'transform' (the DataArray's own is used)")
    # The aspect and the sun are the map's whichever way the rows run (a
    # south-up grid's y grows down the rows); a grid with neither a
    # transform nor coordinates is north-up.
    try:
        product = {**product, "transform": _geotransform(da, dims)}
    except ValueError:
        pass
    if _is_dask(da.data):
        from . import dask as ndask

        values = ndask.normals(
            da.data, threads=1 if threads is None else threads, units=units, pixel_size=pixel_size, nodata=holes,
            _product=product, **rest,
        )
    else:
        values = _normals(
            np.asarray(da.data), threads=threads, units=units, pixel_size=pixel_size, nodata=holes,
            _product=product, **rest,
        )
    hole = 0 if product["product"] == "hillshade" else None
    return _product(da, values, name, unit, False, dims, hole)


def slope(da: xr.DataArray, *, slope_units: str = "degrees", **options: Any) -> xr.DataArray:
    """The slope of a 2-D DataArray of heights, a float32 (y, x) DataArray
    on its grid: ``normalfit convert --product slope``'s values, in
    degrees (``units`` "degrees") or percent (slope_units="percent",
    ``units`` "percent"), NaN at holes. Coords (``spatial_ref``), dims and
    attributes as ``normals``; NumPy in, NumPy out; Dask in, Dask out,
    chunked equal to whole bit for bit. Every keyword of ``normals`` but
    dtype, residual and out, with its defaults (units="map": the spacing
    from the DataArray; nodata="auto"); for a DEM pass border="clamp",
    and fit="vertical" for gdaldem's gradient."""
    product = {"product": "slope", "slope_units": slope_units}
    return _terrain(da, product, "slope", "percent" if slope_units == "percent" else "degrees", options)


def aspect(da: xr.DataArray, *, zero_for_flat: bool = False, **options: Any) -> xr.DataArray:
    """The aspect of a 2-D DataArray of heights (``--product aspect``): a
    float32 (y, x) DataArray, degrees clockwise from north in [0, 360)
    (``units`` "degrees"), the raster north-up (row 0 north, as
    rioxarray opens a GeoTIFF); flat texels -9999 as gdaldem writes (0
    with zero_for_flat), holes NaN. The keywords as ``slope``'s."""
    return _terrain(da, {"product": "aspect", "zero_for_flat": zero_for_flat}, "aspect", "degrees", options)


def hillshade(da: xr.DataArray, *, azimuth: float = 315.0, altitude: float = 45.0, **options: Any) -> xr.DataArray:
    """The hillshade of a 2-D DataArray of heights (``--product
    hillshade``): a uint8 (y, x) DataArray as ``gdaldem hillshade`` draws
    it, 1 (full shadow) to 255, 0 at holes (its rioxarray nodata); the sun
    at azimuth degrees clockwise from north, altitude above the horizon;
    the raster north-up. The keywords as ``slope``'s."""
    return _terrain(da, {"product": "hillshade", "azimuth": azimuth, "altitude": altitude}, "hillshade", None, options)


@xr.register_dataarray_accessor("normalfit")
class NormalfitAccessor:
    """``da.normalfit``: this module's functions on ``da``."""

    def __init__(self, da: xr.DataArray) -> None:
        self._da = da

    def normals(self, **options: Any) -> Any:
        """``normalfit.xarray.normals(da, **options)``."""
        return normals(self._da, **options)

    def curvature(self, **options: Any) -> xr.DataArray:
        """``normalfit.xarray.curvature(da, **options)``."""
        return curvature(self._da, **options)

    def slope(self, **options: Any) -> xr.DataArray:
        """``normalfit.xarray.slope(da, **options)``."""
        return slope(self._da, **options)

    def aspect(self, **options: Any) -> xr.DataArray:
        """``normalfit.xarray.aspect(da, **options)``."""
        return aspect(self._da, **options)

    def hillshade(self, **options: Any) -> xr.DataArray:
        """``normalfit.xarray.hillshade(da, **options)``."""
        return hillshade(self._da, **options)

    def spacing(self) -> Any:
        """``normalfit.xarray.spacing(da)``."""
        return spacing(self._da)
