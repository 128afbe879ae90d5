"""Tangent-space normal maps from height maps, by least-squares plane fits.

NumPy arrays in, NumPy arrays out, the same bits as the ``normalfit``
command line: the work is done by the Rust library the command line is
built on, with the GIL released.

>>> import numpy as np, normalfit
>>> heights = np.random.default_rng(1).random((64, 64), dtype=np.float32)
>>> n = normalfit.normals(heights, patch=5, scale=4.0)   # (64, 64, 3) float32
>>> rgb = normalfit.normals(heights, patch=5, scale=4.0, dtype=np.uint16)
>>> normalfit.check_tiling(heights).x.seamless   # noise tiles
True
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from . import _normalfit
from ._normalfit import AxisReport, ConversionSummary, HeightInfo, TilingReport

__version__: str = _normalfit.__version__
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


def normals(
    heights: Any,
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
    out: Any = None,
    threads: int | None = None,
    units: str = "texels",
    pixel_size: float | tuple[float, float] | None = None,
    nodata: float | None = None,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: str = "uniform",
    _product: dict[str, Any] | None = None,
) -> Any:
    """The normal map of a height map.

    heights: a 2-D array (rows, columns) of uint8, uint16, float32 or
        float64. Integers are heights v / 255 and v / 65535, floats heights
        as they are (the contract's units, as the command line reads
        files). A C-contiguous, aligned array in native byte order is read
        in place; any other (a slice with steps, a transpose, Fortran
        order) is copied once, in row order, with the GIL released.

    The options are the command line's ``convert`` options, with the same
    names, defaults and values:

    patch: N, the side of the N x N patch fitted around each texel (odd, >= 3).
    detail: several scales in place of patch, a sequence of (N, weight)
        pairs, e.g. [(3, 1.0), (9, 0.5), (33, 0.25)]: the normal of the
        weighted sum of the scales' slopes (docs/detail.md; the command
        line's --detail). patch is then left at 3. No residual.
    fit: "orthogonal" (perpendicular distances) or "vertical".
    weights: "uniform" (every point of the patch alike, the default) or
        "binomial" (point (i, j) weighs w(i) w(j), w Pascal's row for N:
        1 2 1 at N = 3, Horn's gradient as gdaldem's with fit="vertical";
        the command line's --weights). No residual, no detail with binomial.
    border: "wrap", "clamp", "mirror" or "auto" (wrap where the heights
        tile, mirror where not: the library's tiling check, reading the
        heights in place) for both axes, or one per axis as an (x, y) pair or
        the command line's "x,y".
    convention: "opengl" ("gl", green up) or "directx" ("dx", green down).
    scale: the height gain S (default 1); relief: the gain as F x width.
        Give one or neither.
    invert: heights are depths.

    dtype: np.float32 (unit vectors, components in [-1, 1]), or np.uint8 /
        np.uint16 for the encoded RGB round(c_max (n + 1) / 2), bit for bit
        what ``normalfit convert --bits 8/16`` writes.
    residual: also return the fit's residual, a (rows, columns) float32
        array (root-mean-square distance of the patch's points from the
        plane, in texel widths): the result is then (normals, residual).
    out: a C-contiguous (rows, columns, 3) array of dtype to write into
        (returned); it must not share memory with heights.
    threads: run on a pool of this many threads (pools are kept per size);
        default: every core (rayon's global pool).
    units: "texels" (the contract's units, above) or "map": heights as
        they are, whatever the dtype (a DEM's metres, a uint16's stored
        integers), texels pixel_size apart, so that a texel's slope is the
        terrain's times the gain (docs/terrain.md). An array has no
        georeferencing: map units need pixel_size.
    pixel_size: map units with this spacing, x (square) or (x, y): x
        column to column, y row to row, in the heights' unit (the command
        line's --pixel-size; implies units="map"); or a (rows, 2) array of
        one (x, y) per row, a geographic raster's metres at each row's
        latitude (what normalfit.xarray.spacing gives). The residual is
        then in the heights' unit.
    nodata: holes (docs/terrain.md, "Holes"): heights equal to it (as
        stored: an integer array's own values), and NaN or infinite ones,
        are missing; each patch is fitted to its valid points. A missing
        texel (a hole, or one whose patch's valid points are fewer than 3
        or collinear) is NaN in all three components, and NaN in the
        residual. float("nan") marks only the non-finite heights. Needs
        dtype float32. Default None: a NaN height is an error.

    Returns a (rows, columns, 3) array of dtype.

    Raises TypeError for a heights or out that is not an array of the
    right number of dimensions and dtype, ValueError for an option out of
    range, a height that is NaN or infinite, an out of the wrong shape,
    MemoryError when the memory is not there: the fit's work, which grows
    with patch, is checked against the memory the process may take
    (``ulimit -v``) before it starts, as the command line checks it.
    """
    return _normalfit.normals(
        heights, patch, fit, border, convention, scale, relief, invert, dtype, residual, out, threads, units,
        _pixel_size(pixel_size), nodata, detail, weights, **(_product or {}),
    )


def _terrain_options(name: str, options: dict[str, Any]) -> dict[str, Any]:
    """``options`` for ``normals`` (every keyword it takes flows through),
    refusing those that are a normal map's alone; ``transform`` (where
    the raster lies on the map) goes with the product."""
    for key in ("dtype", "residual", "out"):
        if key in options:
            raise TypeError(f"{name}() got an unexpected keyword argument {key!r} (a normal map's option)")
    return {k: v for k, v in options.items() if k != "transform"}


def _placed(product: dict[str, Any], options: dict[str, Any]) -> dict[str, Any]:
    """The product with the raster's ``transform`` (GDAL's geotransform:
    the aspect and the sun are the map's, whichever way its rows run),
    when given."""
    transform = options.get("transform")
    return product if transform is None else {**product, "transform": [float(t) for t in transform]}


def slope(heights: Any, *, slope_units: str = "degrees", **options: Any) -> Any:
    """The slope map of a height map: ``normalfit convert --product slope``
    as a float32 (rows, columns) array (docs/products.md): the angle of
    the plane fitted over each texel's patch, in degrees (0 flat), or
    with slope_units="percent" 100 · rise over run (``gdaldem slope
    -p``). A missing texel (a hole, or one whose patch has fewer than 3
    valid points) is NaN.

    Every other keyword is ``normals``'s, with its default (patch, fit,
    border, convention, scale, relief, invert, threads, units,
    pixel_size, nodata, detail, ...); for a DEM in metres give
    pixel_size (map units) and border="clamp", as the command line's
    terrain examples do. NaN heights are holes here even without nodata.
    dtype, residual and out are refused (TypeError). transform, the
    raster's GDAL geotransform (x0, dx, rx, y0, ry, dy; rasterio's
    ``transform.to_gdal()``), places it on the map for the aspect and
    the sun: a south-up raster (dy > 0) has north at its last row.
    Without it row 0 is north.

    Raises as ``normals``."""
    return normals(
        heights,
        **_terrain_options("slope", options),
        _product=_placed({"product": "slope", "slope_units": slope_units}, options),
    )


def aspect(heights: Any, *, zero_for_flat: bool = False, **options: Any) -> Any:
    """The aspect map of a height map: ``normalfit convert --product
    aspect`` as a float32 (rows, columns) array: the compass direction
    the fitted plane faces (downhill), degrees clockwise from north (up
    the array: row 0 is north, unless ``transform`` places it otherwise), in [0, 360). Flat texels are -9999, as
    gdaldem writes (0 with zero_for_flat, ``-zero_for_flat``); missing
    ones NaN. The keywords as ``slope``'s."""
    return normals(
        heights,
        **_terrain_options("aspect", options),
        _product=_placed({"product": "aspect", "zero_for_flat": zero_for_flat}, options),
    )


def hillshade(heights: Any, *, azimuth: float = 315.0, altitude: float = 45.0, **options: Any) -> Any:
    """The hillshade of a height map: ``normalfit convert --product
    hillshade`` as a uint8 (rows, columns) array, as ``gdaldem
    hillshade`` draws it: 1 + 254 · max(0, n · L) rounded (1 is full
    shadow), 0 at missing texels (gdaldem's nodata). The sun at azimuth
    degrees clockwise from north (up the array), altitude degrees above
    the horizon (0 to 90). The keywords as ``slope``'s."""
    return normals(
        heights,
        **_terrain_options("hillshade", options),
        _product=_placed({"product": "hillshade", "azimuth": azimuth, "altitude": altitude}, options),
    )


def curvature(
    heights: Any,
    *,
    patch: int = 3,
    border: str | tuple[str, str] = "wrap",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    threads: int | None = None,
    units: str = "texels",
    pixel_size: float | tuple[float, float] | None = None,
    nodata: float | None = None,
) -> Any:
    """The curvature map of a height map: ``normalfit convert --product
    curvature`` as a float32 (rows, columns) array (docs/curvature.md).

    Each texel's value is the mean curvature, at the texel, of the
    least-squares quadratic z = a u^2 + b uv + c v^2 + d u + e v + f fitted
    over its patch x patch neighbourhood: convex (a hill top, an edge)
    positive, concave (a pit, a crease) negative, 0 on planes. In 1 / texel
    width (heights as ``normals`` reads them: v / 255, v / 65535, floats as
    they are, times the gain), or with units="map" / pixel_size in 1 / the
    heights' unit (heights as stored).

    patch, border, scale, relief, invert, threads, units, pixel_size: as
    ``normals``. nodata: heights equal to it, and NaN or infinite ones, are
    holes; a texel whose patch holds a hole is NaN. Default None: a NaN
    height is an error.

    Raises TypeError for heights that are not a 2-D array of uint8,
    uint16, float32 or float64, ValueError for an option out of range or a
    NaN height without nodata, MemoryError when the memory is not there.
    """
    return _normalfit.curvature(
        heights, patch, border, scale, relief, invert, threads, units,
        _pixel_size(pixel_size), nodata,
    )


def mips(
    array: Any,
    *,
    way: str = "auto",
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: Any = np.float32,
    roughness: bool = False,
    roughness_base: Any = None,
) -> Any:
    """The mip chain of a height map or a normal map: ``normalfit convert
    --mips`` on an array (docs/mips.md).

    array: a 2-D (rows, columns) height map, as ``normals`` takes it, or a
        3-D (rows, columns, 3) normal map: floats n itself, uint8 / uint16
        the encoded (n + 1) / 2 as ``normals(dtype=...)`` and PNGs store it.
    way: "fit" (each level the plane fit of the heights box-filtered to its
        size, its texels spaced by their footprint, the finest level's gain;
        height maps only), "average" (each level the renormalised mean of
        the finer level's normals; normal maps only), or "auto" (the
        default): fit for a 2-D array, average for a 3-D one.
    patch, fit, border, convention, scale, relief, invert: as ``normals``
        (the fit's options; the average takes none of them).
    dtype: np.float32 (the unit normals), or np.uint8 / np.uint16 for the
        encoded RGB: bit for bit the levels ``normalfit convert --mips``
        writes as 8- or 16-bit PNGs, and (uint8) the RGB of a .dds / .ktx2
        written with ``--compress none``.
    roughness: also return the roughness chain: each level's perceptual
        roughness r = sqrt(alpha), alpha^2 = alpha_base^2 + (1 - |n|) / |n|
        (Toksvig), |n| the length of the mean of the finest normals under
        each texel (level 0: 0 plus the base). The result is then
        (levels, roughness_levels).
    roughness_base: a 2-D array of the input's size, perceptual roughness
        in [0, 1] (uint8 / uint16 over their maximum, floats as they are),
        box-filtered to each level as alpha^2; implies roughness.

    Returns a list of arrays, the finest first, level k (rows_k, columns_k,
    3) with each side max(1, side // 2) of the level before, down to 1 x 1;
    with roughness, a pair (levels, roughness levels of float32 (rows_k,
    columns_k)).

    Raises TypeError for an array that is not one, ValueError for an option
    out of range, a way the array does not take, a base of another size,
    MemoryError when the memory is not there.
    """
    return _normalfit.mips(
        array, way, patch, fit, border, convention, scale, relief, invert, dtype,
        roughness, roughness_base,
    )


def check_tiling(
    image: Any,
    *,
    threshold: float = 1.5,
    kind: str = "auto",
    channel: str | None = None,
    max_texels: int | None = None,
    layer: str | None = None,
) -> TilingReport:
    """Whether an image tiles seamlessly: ``normalfit tiling`` on an array
    or a file.

    image: a file (str or os.PathLike: PNG, EXR, TIFF, ... read by content,
        as the command line reads it; channel, max_texels and layer as its
        --channel, --max-texels and --layer), or an array: a 2-D (rows,
        columns) height map, or a 3-D (rows, columns, channels) array of 1
        to 4 channels (gray, gray + alpha, RGB, RGBA), of uint8, uint16,
        float32 or float64, in the units the command line reads files in
        (integers divided by 255 or 65535). An encoded normal map is judged
        on R, G and B, a height map on its height (the luma of RGB).
    threshold: an axis is seamless when its score is at most this (> 0).
    kind: "auto" (decided from the pixels), "height" or "normal".

    Returns a TilingReport: kind, x and y (score, seamless), seamless,
    width, height, and suggested_borders, the (x, y) borders that add no
    seam (wrap where it tiles, mirror where not).

    Raises OSError naming the file for a file that cannot be read,
    MemoryError naming it for one too large (max_texels, or the memory the
    process may take).
    """
    if isinstance(image, (str, os.PathLike)):
        return _normalfit.check_tiling_file(image, threshold, kind, channel, max_texels, layer)
    if channel is not None or max_texels is not None or layer is not None:
        raise TypeError("channel, max_texels and layer are for files; an array's planes are given as they are")
    return _normalfit.check_tiling(image, threshold, kind)


def convert(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    channel: str | None = None,
    bits: int | None = None,
    format: str | None = None,
    signed: bool = False,
    compression: str = "fast",
    alpha: str = "none",
    channels: str = "rgb",
    residual: bool = False,
    max_texels: int | None = None,
    layer: str | None = None,
    units: str = "texels",
    pixel_size: float | tuple[float, float] | None = None,
    band: int | None = None,
    size: tuple[int, int] | str | None = None,
    byte_order: str | None = None,
    decode: str | None = None,
    nodata: float | None = None,
    nodata_tag: bool = True,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: str = "uniform",
    product: str = "normals",
    slope_units: str = "degrees",
    zero_for_flat: bool = False,
    azimuth: float = 315.0,
    altitude: float = 45.0,
) -> ConversionSummary:
    """``normalfit convert SRC -o DST`` with these options (the command
    line's names and values; see ``normalfit convert --help``): a height
    map file to a normal map file, through the library's conversion. PNG,
    scan-line EXR and GeoTIFF inputs stream (memory grows with the width,
    not the height); the output appears whole or not at all, and never
    replaces the input. The GIL is released while it works.

    The fit options are normals()'s (detail too). channel: luma, r, g, b, a or an
    OpenEXR channel's name; bits: 8 or 16 (PNG), 16 or 32 (EXR), 8, 16 or
    32 (TIFF), default by the input; format: "png", "exr" or "tiff" when
    dst's extension (.png, .exr, .tif) does not say (a TIFF from a GeoTIFF
    keeps its georeferencing tags); signed: a float output (EXR, 32-bit
    TIFF) holds n, not (n + 1)/2; compression: "fast" or "small";
    alpha: "none", "height" or "one"; channels: "rgb" or "rg"; residual:
    also write <dst stem>_residual.<ext>; max_texels, layer: as the
    command line's --max-texels and --layer; units: "texels" or "map"
    (heights as stored, texels as far apart as a GeoTIFF says: slopes in
    real-world units, docs/terrain.md); pixel_size: map units with this
    spacing, x or (x, y) in the heights' unit (--pixel-size); nodata: the
    stored value of holes (--nodata; default a GeoTIFF's GDAL_NODATA tag):
    the map then has an alpha, 0 where a texel is missing; nodata_tag:
    False ignores that tag, every value is a height (--nodata none).

    Terrain files (docs/terrain.md), as the command line reads them:
    band: TIFF band K, 1-based as GDAL counts (--band); size: a RAW
    heightmap's (width, height) or "WxH" (--size; default: a square from
    the file's length); byte_order: "little" or "big", a RAW's 16-bit
    samples (--byte-order); giving size or byte_order also reads files
    whose extension names no format as RAW; decode: "terrain-rgb" or
    "terrarium", heights packed in 8-bit RGB tiles unpacked to metres
    (--decode).

    product: "normals", "slope", "aspect", "hillshade" or "curvature"
    (--product; docs/products.md), with slope_units ("degrees" or
    "percent"), zero_for_flat, and the sun's azimuth and altitude for a
    hillshade: the command line's files, bit for bit.

    Returns a ConversionSummary (width, height, input_format, borders as
    used, streamed, tiling, warnings, nodata, missing). Raises ValueError for a bad option,
    ValueError naming the file for a src whose extension names another
    format than its content (a PNG named .exr, refused as the command line
    refuses it), MemoryError naming the file for one too large (max_texels,
    or the memory the process may take: the command line's line), OSError
    naming the file for a file that cannot be read or written.
    """
    return _normalfit.convert(
        src, dst, patch, fit, border, convention, scale, relief, invert, channel, bits, format, signed,
        compression, alpha, channels, residual, max_texels, layer, units,
        None if pixel_size is None else _pair(pixel_size), band, size, byte_order, decode, nodata, nodata_tag,
        detail, weights, product, slope_units, zero_for_flat, azimuth, altitude,
    )


def _pixel_size(size: Any) -> Any:
    """An array's pixel size as the library takes it: None, an (x, y)
    pair, or one (x, y) per row as a C-contiguous (rows, 2) float64 array."""
    if size is None:
        return None
    if isinstance(size, np.ndarray) and size.ndim == 2:
        return np.ascontiguousarray(size, dtype=np.float64)
    return _pair(size)


def _pair(size: float | tuple[float, float]) -> tuple[float, float]:
    """A pixel size as (x, y): one number is both."""
    if isinstance(size, tuple):
        x, y = size
        return (float(x), float(y))
    return (float(size), float(size))


def decode_normals(
    path: str | os.PathLike[str],
    *,
    signed: bool = False,
    max_texels: int | None = None,
    layer: str | None = None,
) -> Any:
    """A normal map file's colours back to normals: n = 2c - 1 per channel
    (c the stored value in [0, 1]), or n = c for a signed float (EXR) map.
    Returns a (rows, columns, 3) float32 array (not renormalised).
    Raises OSError naming the file, MemoryError naming it for one too
    large, ValueError for signed with an integer image."""
    return _normalfit.decode_normals(path, signed, max_texels, layer)


def lit_view(
    path: str | os.PathLike[str],
    *,
    light: tuple[float, float] | None = None,
    azimuth: float | None = None,
    altitude: float | None = None,
    tile: bool = False,
    kind: str = "auto",
    channel: str | None = None,
    signed: bool = False,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    max_texels: int | None = None,
    layer: str | None = None,
    units: str = "texels",
    pixel_size: float | tuple[float, float] | None = None,
    band: int | None = None,
    size: tuple[int, int] | str | None = None,
    byte_order: str | None = None,
    decode: str | None = None,
    nodata: float | None = None,
    nodata_tag: bool = True,
    detail: Sequence[tuple[int, float]] | None = None,
    weights: str = "uniform",
) -> Any:
    """``normalfit shade``: a normal map file, or a height map file through
    the fit (normals()'s options), lit by a directional light.

    light: (azimuth, elevation) in degrees: azimuth counter-clockwise from
        the image's right (135 = top-left), elevation above the surface
        (0 to 90); the texture view's light, for every input (``shade
        --light``). azimuth, altitude: the GIS sun instead, as ``gdaldem
        hillshade`` (degrees clockwise from north, above the horizon;
        315, 45 by default), for every input (``shade --azimuth
        --altitude``). Neither: the sun for georeferenced inputs (a
        GeoTIFF), the light (135, 35) for the others, as ``normalfit
        shade``. tile: repeat 2 x 2 so wrap seams show. kind: "auto",
        "height" or "normal". signed: a float normal map holds n itself.
        units, pixel_size, band, size, byte_order, decode, nodata,
        nodata_tag, detail: as convert()'s (a height map fitted in map
        units, terrain files, holes: grey 0 where a texel is missing,
        several scales).

    Returns the gray picture as a (rows, columns) uint8 array (twice each
    side when tiled), the pixels ``normalfit shade`` writes.

    Raises ValueError for a bad option, MemoryError naming the file for one
    too large (max_texels, or the memory the process may take: the fit's
    work grows with patch; the command line's line), OSError naming the
    file for a file that cannot be read.
    """
    return _normalfit.lit_view(
        path, light, azimuth, altitude, tile, kind, channel, signed, patch, fit, border, convention, scale, relief, invert,
        max_texels, layer, units, None if pixel_size is None else _pair(pixel_size), band, size, byte_order, decode,
        nodata, nodata_tag, detail, weights,
    )


def height(
    normals: Any,
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    model: str = "exact",
    step: float | None = None,
    threads: int | None = None,
    holes: Any = None,
) -> tuple[Any, HeightInfo]:
    """The heights of a normal map: ``normalfit height`` on an array, the
    inverse of normals().

    normals: a (rows, columns, 3) array: float32 or float64 holding n
        itself (as normals() returns it), or uint8 / uint16 holding the
        encoded (n + 1)/2 (as normals(dtype=np.uint8) returns it, or a PNG
        holds it). Only the direction of n matters.

    The fit options are normals()'s and must be those the map was made with
    for the exact inverse (border: "wrap", "clamp" or "mirror", not auto).
    convention may also be "auto" (the one whose slopes have less curl).
    model: "exact" (the inverse of normalfit's fit) or "generic"
        (Frankot-Chellappa, for maps of other origin or unknown patch).
    step: the step of a stored component, for the quantisation's
        regularisation and error figure; default from the dtype (2/255,
        2/65535, float32's epsilon, 0 for float64).
    threads: as for normals().
    holes: a (rows, columns) bool array, True where a texel is a hole (a
        DEM's nodata): holes come back NaN, the rest solved from the
        patches that hold no hole (the solution whose extension over the
        holes is smoothest: a river's banks join); texels
        no such patch holds are NaN too (info.undetermined).

    Returns (heights, info): a (rows, columns) float64 array, mean 0, in
    units of the gain (``normals(h, scale=S)`` then ``height(n, scale=S)``
    gives h back up to a constant), and a HeightInfo (convention used,
    curl under auto, bad_texels, iterations, converged,
    quantisation_error, range, holes, undetermined).

    Raises TypeError for an array of the wrong dimensions or dtype,
    ValueError for a bad option or shape (holes' included), MemoryError
    when the memory is not there (what the solve holds, which grows with
    patch, is checked against the memory the process may take before it
    starts).
    """
    mask = None if holes is None else np.ascontiguousarray(holes, dtype=bool)
    return _normalfit.height(
        normals, patch, fit, border, convention, scale, relief, invert, model, step, threads, mask
    )


def height_file(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    model: str = "exact",
    signed: bool = False,
    format: str | None = None,
    max_texels: int | None = None,
    layer: str | None = None,
) -> HeightInfo:
    """``normalfit height SRC -o DST`` with these options: a normal map
    file to heights, an EXR of float heights (channel Y), for a .tif dst
    (or format="tiff") a float32 TIFF of them, or, for a .png dst (or
    format="png"), a 16-bit gray PNG normalised to [0, 1] whose
    range is the result's png_range; its png_scale is the gain with which
    ``normalfit convert`` of that PNG makes the normals again (the gain
    times the range's span). signed: a float map holds n itself.
    The output appears whole or not at all and never replaces src.

    Returns a HeightInfo (with warnings, one line each). Raises ValueError
    for a bad option, MemoryError naming the file for one too large,
    OSError naming the file for a file that cannot be read or written.
    """
    return _normalfit.height_file(
        src, dst, patch, fit, border, convention, scale, relief, invert, model, signed, format,
        max_texels, layer,
    )


def blend(
    base: Any,
    detail: Any,
    *,
    method: str = "rnm",
    strength: float = 1.0,
    convention: str = "auto",
    detail_convention: str | None = None,
) -> Any:
    """Blends the normal map ``detail`` onto ``base`` (docs/blend.md).

    Both are (rows, columns, 3) arrays of normals: float32 or float64
    holding n itself (as ``normals`` returns them), or uint8 / uint16
    holding (n + 1)/2 as stored. ``method``: ``"rnm"`` (Reoriented Normal
    Mapping, Barré-Brisebois & Hill 2012), ``"whiteout"``, ``"udn"`` or
    ``"linear"``. ``strength`` scales the detail's slopes (0 leaves the
    base). A detail smaller than the base is tiled; its sides must divide
    the base's. ``convention`` is both maps' green (``"opengl"``,
    ``"directx"`` or ``"auto"``: each guessed from its curl),
    ``detail_convention`` the detail's when it differs; a detail of the
    other convention has its green flipped, and the result is in the
    base's. Returns a float64 array of unit normals of the base's shape.
    Raises ValueError for sizes that do not divide, a bad option or a NaN
    normal, TypeError for arrays of another type."""
    return _normalfit.blend(base, detail, method, float(strength), convention, detail_convention)


def check_map(
    path: str | os.PathLike[str],
    *,
    convention: str = "auto",
    threshold: float | None = None,
    signed: bool = False,
    fix: str | os.PathLike[str] | None = None,
    to: str | None = None,
    max_texels: int | None = None,
    layer: str | None = None,
) -> dict[str, Any]:
    """Checks the normal map file at ``path`` as ``normalfit check`` does
    (docs/check.md) and returns its report as a dict with the keys of
    ``normalfit check --json``: ``length``, ``negative_z``, ``layout``,
    ``convention`` (``"opengl"`` or ``"directx"``, guessed from the map's
    curl) with ``confident`` and ``confidence``, ``banding``, ``tiling``,
    ``findings`` (names) and ``clean``. ``convention`` states the one the
    map should be in (a confident guess of the other is a finding).
    ``fix`` writes the map repaired there (renormalised, z rebuilt for RG,
    green flipped to ``to``). Raises OSError naming the file, ValueError
    for a bad option or a convention that cannot be told when ``to`` asks
    to flip it."""
    return _normalfit.check_map(path, convention, threshold, signed, fix, to, max_texels, layer)
