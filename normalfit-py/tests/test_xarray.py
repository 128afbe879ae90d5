"""normalfit.xarray: GeoTIFFs written by gdal_translate, opened by
rioxarray, fitted here and written back by rioxarray, against the command
line on the same files; Dask-backed against NumPy-backed, bit for bit."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray", reason="xarray is not installed (pip install './normalfit-py[xarray]')")
rioxarray = pytest.importorskip("rioxarray", reason="rioxarray is not installed (pip install './normalfit-py[xarray]')")
dask_array = pytest.importorskip("dask.array", reason="dask is not installed (pip install './normalfit-py[dask]')")

import normalfit  # noqa: E402
import normalfit.xarray as nx  # noqa: E402

from conftest import run_cli  # noqa: E402

# 24 rows of 20 columns: a hill and a ridge, float32 metres near 400 m.
ROWS, COLS = 24, 20
NODATA = -9999.0


def dem() -> np.ndarray:
    y, x = np.mgrid[0:ROWS, 0:COLS].astype(np.float64)
    z = 400 + 30 * np.exp(-((x - 7) ** 2 + (y - 9) ** 2) / 40) + 0.8 * x + 0.3 * y * y / 8 + 5 * np.sin(x * y / 17)
    return z.astype(np.float32)


def gdal(tool: str) -> str:
    path = shutil.which(tool)
    if path is None:
        pytest.skip(f"{tool} is not installed (GDAL's command-line tools, gdal-bin)")
    return path


def write_tif(tmp_path: Path, name: str, srs: str, ullr: tuple[float, float, float, float], holes: bool = False) -> Path:
    """A float32 GeoTIFF written by gdal_translate from an ASCII grid of
    dem() (each value printed with 9 digits: float32 exactly)."""
    z = dem()
    if holes:
        z[3:6, 4] = NODATA
        z[15, 11:14] = NODATA
    asc = tmp_path / f"{name}.asc"
    lines = [f"ncols {COLS}", f"nrows {ROWS}", "xllcorner 0", "yllcorner 0", "cellsize 1"]
    if holes:
        lines.append(f"NODATA_value {NODATA}")
    lines += [" ".join(f"{v:.9g}" for v in row) for row in z.astype(np.float64)]
    asc.write_text("\n".join(lines) + "\n")
    tif = tmp_path / f"{name}.tif"
    subprocess.run(
        [gdal("gdal_translate"), "-q", "-of", "GTiff", "-ot", "Float32", "-a_srs", srs, "-a_ullr", *map(str, ullr),
         str(asc), str(tif)],
        check=True,
    )
    return tif


def projected(tmp_path: Path, holes: bool = False) -> Path:
    # UTM 33N, 30 m columns and 36 m rows.
    return write_tif(tmp_path, "utm", "EPSG:32633", (500000, 5000000, 500000 + 30 * COLS, 5000000 - 36 * ROWS), holes)


def geographic(tmp_path: Path) -> Path:
    # WGS84 degrees, 1/1024° a texel, rows at 46° N.
    step = 1 / 1024
    return write_tif(tmp_path, "wgs84", "EPSG:4326", (10.0, 46.0, 10.0 + step * COLS, 46.0 - step * ROWS))


def opened(tif: Path, **kwargs: object) -> xr.DataArray:
    return rioxarray.open_rasterio(tif, **kwargs).squeeze("band", drop=True)


def cli_normals(cli: Path, tif: Path, tmp_path: Path) -> np.ndarray:
    """``normalfit convert --units map`` of the file, written as a float
    TIFF of the normals themselves (--signed), as (3, rows, columns)."""
    out = tmp_path / f"{tif.stem}_cli.tif"
    run_cli(cli, "convert", tif, "-o", out, "--units", "map", "--border", "clamp", "--format", "tiff", "--bits", "32",
            "--signed")
    written = rioxarray.open_rasterio(out).values
    assert written.dtype == np.float32 and written.shape[1:] == (ROWS, COLS) and written.shape[0] in (3, 4)
    return written


def info(path: Path) -> dict[str, object]:
    return json.loads(subprocess.run([gdal("gdalinfo"), "-json", str(path)], check=True, capture_output=True,
                                     text=True).stdout)


@pytest.mark.parametrize("kind", ["projected", "geographic"])
def test_a_geotiff_round_trip_keeps_its_grid_and_equals_the_cli(cli: Path, tmp_path: Path, kind: str) -> None:
    tif = projected(tmp_path) if kind == "projected" else geographic(tmp_path)
    da = opened(tif)
    n = nx.normals(da, border="clamp")
    assert n.dims == ("band", "y", "x") and list(n.band.values) == ["x", "y", "z"]
    assert n.attrs["units"] == "1" and n.dtype == np.float32
    assert n.rio.crs == da.rio.crs
    np.testing.assert_array_equal(n.x.values, da.x.values)
    np.testing.assert_array_equal(n.y.values, da.y.values)
    # The command line's normals on the same file, bit for bit.
    expected = cli_normals(cli, tif, tmp_path)
    assert np.array_equal(n.values, expected)
    # Written by rioxarray, read by GDAL: the same CRS and transform.
    out = tmp_path / "normals.tif"
    n.rio.to_raster(out)
    (src, dst) = (info(tif), info(out))
    assert dst["geoTransform"] == src["geoTransform"]
    assert dst["coordinateSystem"] == src["coordinateSystem"]
    assert [b["type"] for b in dst["bands"]] == ["Float32"] * 3


def test_the_spacing_is_the_librarys_metres(tmp_path: Path) -> None:
    assert nx.spacing(opened(projected(tmp_path))) == (30.0, 36.0)
    rows = nx.spacing(opened(geographic(tmp_path)))
    assert rows.shape == (ROWS, 2)
    # Degrees east shrink northwards; at 46° N about 77.5 km and 111.1 km
    # a degree (1/1024 of it a texel).
    assert (np.diff(rows[:, 0]) > 0).all()
    assert abs(rows[0, 0] * 1024 - 77_470) < 200 and abs(rows[0, 1] * 1024 - 111_150) < 100


@pytest.mark.parametrize("kind", ["projected", "geographic"])
def test_dask_backed_equals_numpy_backed_bit_for_bit(tmp_path: Path, kind: str) -> None:
    tif = projected(tmp_path) if kind == "projected" else geographic(tmp_path)
    whole = nx.normals(opened(tif), border=("clamp", "mirror"), patch=5)
    chunked = nx.normals(opened(tif, chunks={"y": 7, "x": 6}), border=("clamp", "mirror"), patch=5)
    assert isinstance(chunked.data, dask_array.Array)
    assert chunked.data.chunks == ((3,), (7, 7, 7, 3), (6, 6, 6, 2))
    computed = chunked.compute()
    assert np.array_equal(computed.values, whole.values)
    assert computed.rio.crs == whole.rio.crs and computed.attrs.keys() == whole.attrs.keys()


def test_holes_are_nan_as_the_cli_makes_them(cli: Path, tmp_path: Path) -> None:
    tif = projected(tmp_path, holes=True)
    da = opened(tif)
    assert da.rio.nodata == NODATA
    n = nx.normals(da, border="clamp")
    missing = np.isnan(n.values).all(axis=0)
    assert missing[3:6, 4].all() and missing[15, 11:14].all()
    assert np.isfinite(n.values[:, ~missing]).all()
    # The command line's TIFF has an alpha band, 0 where a texel is
    # missing (its normal there is flat): the same texels, the same bits
    # elsewhere.
    written = cli_normals(cli, tif, tmp_path)
    assert written.shape[0] == 4 and np.array_equal(written[3] == 0, missing)
    assert np.array_equal(n.values[:, ~missing], written[:3, ~missing])
    # Masked on reading (the holes already NaN): the same normals.
    assert np.array_equal(nx.normals(opened(tif, masked=True), border="clamp").values, n.values, equal_nan=True)
    chunked = nx.normals(opened(tif, chunks={"y": 5, "x": 7}), border="clamp").compute()
    assert np.array_equal(chunked.values, n.values, equal_nan=True)


def test_coordinates_without_a_transform_give_the_spacing() -> None:
    z = dem().astype(np.float64)
    da = xr.DataArray(z, dims=("y", "x"), coords={"y": 100.0 - 2.5 * np.arange(ROWS), "x": 10.0 + 4 * np.arange(COLS)},
                      attrs={"units": "m"})
    n = da.normalfit.normals(patch=5, border="mirror")
    assert np.array_equal(n.values, np.moveaxis(normalfit.normals(z, patch=5, border="mirror", pixel_size=(4, 2.5)),
                                                -1, 0))
    n, r = nx.normals(da, residual=True)
    assert r.dims == ("y", "x") and r.attrs["units"] == "m"


@pytest.mark.parametrize("product", ["slope", "aspect", "hillshade"])
def test_a_south_up_grid_is_measured_on_the_map(product: str) -> None:
    """y growing down the rows (row 0 south, as many netCDF grids are):
    the aspect and the sun are the map's, so the products are the
    north-up grid's with the rows flipped, NumPy- and Dask-backed; read
    as north-up, the aspect would be 180° − a."""
    z = dem().astype(np.float64)
    x = 10.0 + 30 * np.arange(COLS)
    north_up = xr.DataArray(z, dims=("y", "x"), coords={"y": 5000.0 - 30 * np.arange(ROWS), "x": x})
    south_up = xr.DataArray(z[::-1], dims=("y", "x"), coords={"y": north_up.y.values[::-1], "x": x})
    options = dict(border="clamp", fit="vertical", weights="binomial")
    want = getattr(nx, product)(north_up, **options).values[::-1]
    for grid in (south_up, south_up.chunk({"y": 7, "x": 6})):
        got = np.asarray(getattr(nx, product)(grid, **options).values, dtype=np.float64)
        if product == "aspect":
            off = np.abs(got - want)
            off = np.minimum(off, 360 - off)
            assert off.max() < 1e-3, off.max()
        elif product == "hillshade":
            assert np.abs(got - want).max() <= 1
        else:
            assert np.abs(got - want).max() < 1e-4
    # The bare call takes the transform: the same values as the DataArray's.
    transform = (x[0] - 15, 30.0, 0.0, south_up.y.values[0] - 15, 0.0, 30.0)
    bare = getattr(normalfit, product)(z[::-1].copy(), pixel_size=30.0, transform=transform, **options)
    assert np.array_equal(bare, getattr(nx, product)(south_up, **options).values, equal_nan=True)


def test_irregular_coordinates_are_refused() -> None:
    x = 10.0 + 4 * np.arange(COLS)
    x[7:] += 0.5
    da = xr.DataArray(dem(), dims=("y", "x"), coords={"y": np.arange(ROWS) * 2.0, "x": x})
    with pytest.raises(ValueError, match=r"x coordinates are not equally spaced: from index 0 to 1 the step is 4, "):
        nx.normals(da)


def test_a_rotated_transform_is_refused() -> None:
    from affine import Affine

    da = xr.DataArray(dem(), dims=("y", "x"))
    da = da.rio.write_crs("EPSG:32633").rio.write_transform(Affine.rotation(30) * Affine.scale(30, -30))
    with pytest.raises(ValueError, match=r"rotated 30\.000° counter-clockwise from north-up"):
        nx.normals(da)


def test_curvature_in_metres(tmp_path: Path) -> None:
    da = opened(projected(tmp_path))
    c = nx.curvature(da, border="clamp")
    assert c.dims == ("y", "x") and c.attrs["units"] == "1/m" and c.rio.crs == da.rio.crs
    assert np.array_equal(c.values, normalfit.curvature(da.values, border="clamp", pixel_size=(30, 36)))


def test_bad_arrays_are_refused_in_one_line(tmp_path: Path) -> None:
    da = opened(projected(tmp_path))
    with pytest.raises(TypeError, match=r"2-D DataArray of heights is needed"):
        nx.normals(rioxarray.open_rasterio(projected(tmp_path)).expand_dims("t"))
    with pytest.raises(ValueError, match=r"dims must be rows then columns"):
        nx.normals(da.transpose("x", "y"))
    with pytest.raises(TypeError, match=r"NumPy-backed"):
        nx.curvature(da.chunk({"y": 8}))


def cli_product(cli: Path, tif: Path, tmp_path: Path, product: str, *extra: str) -> np.ndarray:
    """``normalfit convert --units map --product PRODUCT --fit vertical
    --border clamp`` of the file, as (rows, columns)."""
    out = tmp_path / f"{tif.stem}_{product}.tif"
    run_cli(cli, "convert", tif, "-o", out, "--units", "map", "--product", product, "--fit", "vertical", "--border",
            "clamp", *extra)
    written: np.ndarray = rioxarray.open_rasterio(out).values
    assert written.shape == (1, ROWS, COLS)
    return written[0]


PRODUCTS = [
    ("slope", {}, ["--slope-units", "degrees"], "degrees", np.float32),
    ("slope", {"slope_units": "percent"}, ["--slope-units", "percent"], "percent", np.float32),
    ("aspect", {}, [], "degrees", np.float32),
    ("aspect", {"zero_for_flat": True}, ["--zero-for-flat"], "degrees", np.float32),
    ("hillshade", {"azimuth": 200.0, "altitude": 30.0}, ["--azimuth", "200", "--altitude", "30"], None, np.uint8),
]


@pytest.mark.parametrize("kind", ["projected", "geographic"])
@pytest.mark.parametrize(("product", "keywords", "flags", "units", "dtype"), PRODUCTS)
def test_products_round_trip_keep_the_grid_and_equal_the_cli(
    cli: Path, tmp_path: Path, kind: str, product: str, keywords: dict[str, object], flags: list[str],
    units: str | None, dtype: type,
) -> None:
    tif = projected(tmp_path) if kind == "projected" else geographic(tmp_path)
    da = opened(tif)
    p = getattr(nx, product)(da, fit="vertical", border="clamp", **keywords)
    assert p.dims == ("y", "x") and p.dtype == dtype and p.attrs.get("units") == units
    assert p.rio.crs == da.rio.crs and p.name == product
    np.testing.assert_array_equal(p.x.values, da.x.values)
    np.testing.assert_array_equal(p.y.values, da.y.values)
    # The command line's product of the same file, bit for bit (no holes
    # here: aspect's −9999 is a flat texel's, as the command line's).
    expected = cli_product(cli, tif, tmp_path, product, *flags)
    assert expected.dtype == dtype and np.array_equal(p.values, expected)
    assert np.ptp(p.values) > 0
    # The accessor is the function.
    assert np.array_equal(getattr(da.normalfit, product)(fit="vertical", border="clamp", **keywords).values, p.values)
    # Written by rioxarray, read by GDAL: the same CRS and transform.
    out = tmp_path / f"{product}.tif"
    p.rio.to_raster(out)
    (src, dst) = (info(tif), info(out))
    assert dst["geoTransform"] == src["geoTransform"]
    assert dst["coordinateSystem"] == src["coordinateSystem"]
    assert [b["type"] for b in dst["bands"]] == ["Byte" if dtype == np.uint8 else "Float32"]


@pytest.mark.parametrize(("product", "keywords", "flags", "units", "dtype"), PRODUCTS)
def test_convert_writes_the_clis_product_files(
    cli: Path, tmp_path: Path, product: str, keywords: dict[str, object], flags: list[str], units: str | None,
    dtype: type,
) -> None:
    tif = projected(tmp_path, holes=True)
    out = tmp_path / "python.tif"
    summary = normalfit.convert(tif, out, units="map", product=product, fit="vertical", border="clamp", **keywords)
    assert summary.missing > 0
    written = rioxarray.open_rasterio(out)
    assert written.dtype == dtype
    assert np.array_equal(written.values[0], cli_product(cli, tif, tmp_path, product, *flags), equal_nan=True)
    with pytest.raises(ValueError, match="product"):
        normalfit.convert(tif, tmp_path / "bad.tif", units="map", product="relief")


@pytest.mark.parametrize("kind", ["projected", "geographic"])
@pytest.mark.parametrize("product", ["slope", "aspect", "hillshade"])
def test_products_dask_backed_equal_numpy_backed_bit_for_bit(tmp_path: Path, kind: str, product: str) -> None:
    tif = projected(tmp_path, holes=True) if kind == "projected" else geographic(tmp_path)
    options = dict(border=("clamp", "mirror"), patch=5, fit="vertical")
    whole = getattr(nx, product)(opened(tif), **options)
    chunked = getattr(nx, product)(opened(tif, chunks={"y": 7, "x": 6}), **options)
    assert isinstance(chunked.data, dask_array.Array)
    assert chunked.data.chunks == ((7, 7, 7, 3), (6, 6, 6, 2))
    computed = chunked.compute()
    assert computed.dtype == whole.dtype
    assert np.array_equal(computed.values, whole.values, equal_nan=product != "hillshade")
    assert computed.rio.crs == whole.rio.crs and computed.attrs.keys() == whole.attrs.keys()
    assert computed.attrs.get("units") == whole.attrs.get("units")
    # Chunks smaller than the halo are joined for the fit and cut back.
    tiny = getattr(nx, product)(opened(tif, chunks={"y": 1, "x": 3}), **options)
    assert tiny.data.chunks == ((1,) * ROWS, (3,) * 6 + (2,))
    assert np.array_equal(tiny.compute().values, whole.values, equal_nan=product != "hillshade")


def test_products_holes_are_nan_or_0_where_the_cli_writes_its_nodata(cli: Path, tmp_path: Path) -> None:
    tif = projected(tmp_path, holes=True)
    da = opened(tif)
    s = nx.slope(da, fit="vertical", border="clamp")
    missing = np.isnan(s.values)
    assert missing[3:6, 4].all() and missing[15, 11:14].all() and missing.sum() == 6
    expected = cli_product(cli, tif, tmp_path, "slope")
    assert np.array_equal(expected == -9999, missing)
    assert np.array_equal(s.values[~missing], expected[~missing])
    # NaN holes (masked on reading) are the same holes.
    assert np.array_equal(nx.slope(opened(tif, masked=True), fit="vertical", border="clamp").values, s.values,
                          equal_nan=True)
    shade = nx.hillshade(da, fit="vertical", border="clamp")
    assert shade.rio.nodata == 0 and np.array_equal(shade.values == 0, missing)
    assert np.array_equal(shade.values, cli_product(cli, tif, tmp_path, "hillshade"))
    out = tmp_path / "shade.tif"
    shade.rio.to_raster(out)
    assert info(out)["bands"][0]["noDataValue"] == 0


def test_products_of_bare_arrays_are_the_references_fit() -> None:
    import reference

    z = dem().astype(np.float64)
    s = normalfit.slope(z, fit="vertical", border="clamp", scale=0.2)
    a = normalfit.aspect(z, fit="vertical", border="clamp", scale=0.2)
    n = reference.normals(z, fit="vertical", border=("clamp", "clamp"), scale=0.2)
    horizontal = np.hypot(n[..., 0], n[..., 1])
    want_slope = np.degrees(np.arctan2(horizontal, n[..., 2]))
    want_aspect = np.degrees(np.arctan2(n[..., 0], n[..., 1])) % 360
    assert s.dtype == np.float32 and np.abs(s - want_slope).max() < 1e-4 and want_slope.max() > 20
    turn = np.abs(a - want_aspect) % 360
    assert np.minimum(turn, 360 - turn).max() < 1e-3
    # The xarray function on a DataArray of it, in texel units.
    da = xr.DataArray(z, dims=("y", "x"))
    assert np.array_equal(nx.slope(da, units="texels", fit="vertical", border="clamp", scale=0.2).values, s)


def test_products_refuse_a_normal_maps_options_and_unknown_keywords(tmp_path: Path) -> None:
    da = opened(projected(tmp_path))
    with pytest.raises(TypeError, match=r"slope\(\) got an unexpected keyword argument 'dtype'"):
        nx.slope(da, dtype=np.uint8)
    with pytest.raises(TypeError, match=r"residual"):
        normalfit.aspect(da.values, residual=True)
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'colour'"):
        nx.hillshade(da, colour=3)
    with pytest.raises(ValueError, match=r"slope units"):
        nx.slope(da, slope_units="radians")
    with pytest.raises(ValueError, match=r"altitude must be from 0 to 90"):
        da.normalfit.hillshade(altitude=95)
