"""Terrain from Python (docs/terrain.md): the command line's --band, --size,
--byte-order, --decode, --units and --pixel-size reach convert() and
lit_view(), and normals() fits arrays in map units; each is compared with
the command line's output of the same file (the same bytes, or the same
texels)."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

import normalfit
from conftest import ROOT, read_png, run_cli, write_float_tiff, write_png

DEM = ROOT / "samples" / "dem" / "jacksboro_fault_dem.tif"


def hills(height: int, width: int) -> np.ndarray:
    """Heights in metres, a few hundred metres of relief."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    return 500.0 + 120.0 * np.sin(x * 0.31) * np.cos(y * 0.23) + 40.0 * np.sin(x * 0.9 + y * 0.7) + 3.0 * x


def write_rgb16_tiff(path: Path, image: np.ndarray) -> None:
    """A 16-bit, three-band (RGB, chunky) TIFF of an (H, W, 3) uint16
    image, uncompressed, one strip, written with struct alone."""
    height, width, _ = image.shape
    data = np.ascontiguousarray(image, dtype="<u2").tobytes()
    entries = [
        (256, 4, 1, width),
        (257, 4, 1, height),
        (258, 3, 3, None),  # BitsPerSample 16,16,16: at an offset
        (259, 3, 1, 1),
        (262, 3, 1, 2),  # RGB
        (273, 4, 1, None),  # StripOffsets
        (277, 3, 1, 3),
        (278, 4, 1, height),
        (279, 4, 1, len(data)),
    ]
    ifd_size = 2 + 12 * len(entries) + 4
    bits_offset = 8 + ifd_size
    data_offset = bits_offset + 6
    out = bytearray(b"II*\x00" + struct.pack("<I", 8) + struct.pack("<H", len(entries)))
    for tag, kind, count, value in entries:
        value = {258: bits_offset, 273: data_offset}.get(tag, value)
        packed = struct.pack("<H", value) + b"\x00\x00" if kind == 3 and count == 1 else struct.pack("<I", value)
        out += struct.pack("<HHI", tag, kind, count) + packed
    out += struct.pack("<I", 0) + struct.pack("<3H", 16, 16, 16) + data
    path.write_bytes(bytes(out))


def same_output(src: Path, kwargs: dict[str, object], args: list[str], cli: Path, tmp_path: Path, ext: str) -> None:
    ours, theirs = tmp_path / f"ours.{ext}", tmp_path / f"theirs.{ext}"
    normalfit.convert(src, ours, **kwargs)  # type: ignore[arg-type]
    run_cli(cli, "convert", src, "-o", theirs, *args)
    assert ours.read_bytes() == theirs.read_bytes(), kwargs


def test_convert_reads_a_tiff_band_as_the_cli(cli: Path, tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    image = rng.integers(0, 65536, size=(40, 56, 3), dtype=np.uint16)
    src = tmp_path / "bands.tif"
    write_rgb16_tiff(src, image)
    for band in (1, 2, 3):
        same_output(src, {"band": band, "scale": 8.0}, ["--band", str(band), "-s", "8"], cli, tmp_path, "png")
    # The band is that band alone, as gray: the same normals as the plane.
    green = tmp_path / "green.png"
    write_png(green, image[:, :, 1])
    normalfit.convert(src, tmp_path / "b2.png", band=2, scale=8.0)
    normalfit.convert(green, tmp_path / "g.png", scale=8.0)
    assert np.array_equal(read_png(tmp_path / "b2.png"), read_png(tmp_path / "g.png"))
    with pytest.raises(OSError, match="band 4 asked for, but the file has 3 bands"):
        normalfit.convert(src, tmp_path / "o.png", band=4)
    with pytest.raises(ValueError, match="bands count from 1"):
        normalfit.convert(src, tmp_path / "o.png", band=0)
    with pytest.raises(ValueError, match="bands count from 1"):
        normalfit.convert(src, tmp_path / "o.png", band=-1)
    with pytest.raises(TypeError, match="band must be an int"):
        normalfit.convert(src, tmp_path / "o.png", band="2")  # type: ignore[arg-type]


def test_convert_reads_raw_heightmaps_as_the_cli(cli: Path, tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    heights = rng.integers(0, 65536, size=(32, 64), dtype=np.uint16)
    little = tmp_path / "terrain.r16"
    little.write_bytes(heights.astype("<u2").tobytes())
    big = tmp_path / "terrain.bin"
    big.write_bytes(heights.astype(">u2").tobytes())
    same_output(little, {"size": (64, 32)}, ["--size", "64x32"], cli, tmp_path, "png")
    same_output(little, {"size": "64x32", "byte_order": "little"}, ["--size", "64x32", "--byte-order", "little"],
                cli, tmp_path, "png")
    same_output(big, {"size": (64, 32), "byte_order": "big"}, ["--size", "64x32", "--byte-order", "big"],
                cli, tmp_path, "png")
    # Both orders are the same heights, so the same normal map.
    normalfit.convert(little, tmp_path / "le.png", size=(64, 32))
    normalfit.convert(big, tmp_path / "be.png", size=(64, 32), byte_order="big")
    assert (tmp_path / "le.png").read_bytes() == (tmp_path / "be.png").read_bytes()
    # A square is found from the length without a size.
    square = tmp_path / "square.raw"
    square.write_bytes(heights[:, :32].astype("<u2").tobytes())
    same_output(square, {}, [], cli, tmp_path, "png")
    with pytest.raises(OSError, match="does not hold 60×32 16-bit samples"):
        normalfit.convert(little, tmp_path / "o.png", size=(60, 32))
    with pytest.raises(ValueError, match="unknown byte order 'middle'"):
        normalfit.convert(little, tmp_path / "o.png", byte_order="middle")
    with pytest.raises(ValueError):
        normalfit.convert(little, tmp_path / "o.png", size=(0, 4))
    with pytest.raises(ValueError):
        normalfit.convert(little, tmp_path / "o.png", size="64by32")
    with pytest.raises(TypeError, match="size must be a"):
        normalfit.convert(little, tmp_path / "o.png", size=64)  # type: ignore[arg-type]


@pytest.mark.parametrize("packing", ["terrain-rgb", "terrarium"])
def test_convert_unpacks_elevation_tiles_as_the_cli(packing: str, cli: Path, tmp_path: Path) -> None:
    rng = np.random.default_rng(11)
    tile = rng.integers(0, 256, size=(48, 48, 3), dtype=np.uint8)
    # Smooth-ish high bytes so the heights are terrain, not noise.
    tile[:, :, 0] = 1 + (np.arange(48)[None, :] // 12).astype(np.uint8)
    src = tmp_path / "tile.png"
    write_png(src, tile)
    same_output(src, {"decode": packing, "scale": 0.01}, ["--decode", packing, "-s", "0.01"], cli, tmp_path, "png")
    same_output(src, {"decode": packing, "pixel_size": 30.0, "signed": True},
                ["--decode", packing, "--pixel-size", "30", "--signed"], cli, tmp_path, "exr")
    gray = tmp_path / "gray.png"
    write_png(gray, tile[:, :, 0])
    with pytest.raises(OSError, match="tiles hold 8-bit RGB"):
        normalfit.convert(gray, tmp_path / "o.png", decode=packing)
    with pytest.raises(ValueError, match="unknown elevation packing 'lerc'"):
        normalfit.convert(src, tmp_path / "o.png", decode="lerc")


def test_normals_of_arrays_in_map_units_are_the_clis_texels(cli: Path, tmp_path: Path) -> None:
    # Stored integers on 10 × 4 m pixels: the 16-bit PNG the CLI converts.
    stored = np.round(hills(31, 45)).astype(np.uint16)
    src = tmp_path / "dem.png"
    write_png(src, stored)
    run_cli(cli, "convert", src, "-o", tmp_path / "c.png", "--pixel-size", "10,4", "--border", "clamp", "--bits", "16")
    ours = normalfit.normals(stored, pixel_size=(10.0, 4.0), border="clamp", dtype=np.uint16)
    assert np.array_equal(ours, read_png(tmp_path / "c.png"))
    assert np.array_equal(ours, normalfit.normals(stored, units="map", pixel_size=(10, 4), border="clamp",
                                                  dtype=np.uint16))
    # Float metres, square pixels, both fits: the float TIFF's texels.
    metres = hills(29, 37).astype(np.float32)
    tif = tmp_path / "dem.tif"
    write_float_tiff(tif, metres)
    for fit in ("orthogonal", "vertical"):
        run_cli(cli, "convert", tif, "-o", tmp_path / "f.png", "--pixel-size", "30", "--fit", fit, "--bits", "16")
        ours = normalfit.normals(metres, pixel_size=30.0, fit=fit, dtype=np.uint16)
        assert np.array_equal(ours, read_png(tmp_path / "f.png")), fit
    # Map units are not texel units: a 45 m rise over 30 m is steep.
    texels = normalfit.normals(metres)
    mapped = normalfit.normals(metres, pixel_size=30.0)
    assert np.abs(texels - mapped).max() > 0.1
    plane = (np.arange(5)[None, :] * 3.0 + np.zeros((5, 1))).astype(np.float64)  # 3 m per 10 m texel east
    n = normalfit.normals(plane, pixel_size=10.0, border="clamp", fit="vertical")
    slope = np.degrees(np.arctan2(np.hypot(n[2, 2, 0], n[2, 2, 1]), n[2, 2, 2]))
    assert abs(slope - np.degrees(np.arctan(0.3))) < 1e-4
    with pytest.raises(ValueError, match="give the pixel size"):
        normalfit.normals(metres, units="map")
    with pytest.raises(ValueError, match="texel spacing must be finite and positive"):
        normalfit.normals(metres, pixel_size=(1.0, 0.0))
    with pytest.raises(ValueError, match="unknown units 'feet'"):
        normalfit.normals(metres, units="feet")


def test_lit_view_in_map_units_and_of_terrain_files_is_the_clis(cli: Path, tmp_path: Path) -> None:
    # The shipped DEM in map units: by default lit by the GIS sun, as the
    # command lights a GeoTIFF; or by a light; or by a sun given.
    for kwargs, args in (
        ({}, []),
        ({"light": (135.0, 35.0)}, ["--light", "135,35"]),
        ({"azimuth": 200.0}, ["--azimuth", "200"]),
        ({"azimuth": 90.0, "altitude": 30.0}, ["--azimuth", "90", "--altitude", "30"]),
    ):
        ours = normalfit.lit_view(DEM, units="map", border="clamp", **kwargs)  # type: ignore[arg-type]
        run_cli(cli, "shade", DEM, "--units", "map", "--border", "clamp", *args, "-o", tmp_path / "d.png")
        assert np.array_equal(ours, read_png(tmp_path / "d.png")), kwargs
    sun = normalfit.lit_view(DEM, units="map", border="clamp")
    assert not np.array_equal(sun, normalfit.lit_view(DEM, units="map", border="clamp", light=(135.0, 35.0)))
    assert not np.array_equal(sun, normalfit.lit_view(DEM, border="clamp"))
    with pytest.raises(ValueError, match="not both"):
        normalfit.lit_view(DEM, light=(135.0, 35.0), altitude=30.0)
    with pytest.raises(ValueError, match="altitude must be from 0 to 90"):
        normalfit.lit_view(DEM, altitude=95.0)
    # A RAW heightmap with a pixel size.
    heights = np.round(hills(32, 64) * 20).astype(np.uint16)
    raw = tmp_path / "terrain.r16"
    raw.write_bytes(heights.astype("<u2").tobytes())
    ours = normalfit.lit_view(raw, size=(64, 32), pixel_size=(20.0, 20.0), border="clamp")
    run_cli(cli, "shade", raw, "--size", "64x32", "--pixel-size", "20", "--border", "clamp", "-o", tmp_path / "r.png")
    assert np.array_equal(ours, read_png(tmp_path / "r.png"))
    with pytest.raises(OSError, match="map units need the texel spacing"):
        normalfit.lit_view(raw, size=(64, 32), units="map")


def test_a_geotiffs_nodata_tag_makes_holes_unless_nodata_tag_is_false(cli: Path, tmp_path: Path) -> None:
    heights = hills(20, 24).astype(np.float32)
    heights[5, 7] = heights[12, 3] = -9999.0
    src = tmp_path / "dem.tif"
    write_float_tiff(src, heights, nodata="-9999")
    # convert(): the tag's holes (an alpha), or every value a height, as
    # the command line's default and --nodata none.
    for kwargs, args in (({}, []), ({"nodata_tag": False}, ["--nodata", "none"])):
        same_output(src, {"border": "clamp", "scale": 0.01, **kwargs}, ["--border", "clamp", "-s", "0.01", *args], cli, tmp_path, "png")
    held = normalfit.convert(src, tmp_path / "a.png", border="clamp", scale=0.01)
    assert held.nodata == -9999.0 and held.missing >= 2
    plain = normalfit.convert(src, tmp_path / "b.png", border="clamp", scale=0.01, nodata_tag=False)
    assert plain.nodata is None and plain.missing == 0
    assert read_png(tmp_path / "b.png").shape == (20, 24, 3)
    # lit_view(): grey 0 at the holes, none without the tag, and nodata=
    # as shade --nodata.
    lit = normalfit.lit_view(src, border="clamp", scale=0.01)
    assert lit[5, 7] == 0 and lit[12, 3] == 0
    assert (normalfit.lit_view(src, border="clamp", scale=0.01, nodata_tag=False) > 0).all()
    for kwargs, args in (({}, []), ({"nodata_tag": False}, ["--nodata", "none"]), ({"nodata": 500.0}, ["--nodata", "500"])):
        ours = normalfit.lit_view(src, border="clamp", scale=0.01, **kwargs)  # type: ignore[arg-type]
        run_cli(cli, "shade", src, "--border", "clamp", "-s", "0.01", *args, "-o", tmp_path / "l.png")
        assert np.array_equal(ours, read_png(tmp_path / "l.png")), kwargs


def test_convert_and_height_write_tiff_as_the_cli(cli: Path, tmp_path: Path) -> None:
    src = tmp_path / "dem.tif"
    write_float_tiff(src, hills(30, 44) * 100.0)
    for kwargs, args in (
        ({"scale": 0.1}, ["-s", "0.1"]),
        ({"scale": 0.1, "bits": 32, "signed": True}, ["-s", "0.1", "--bits", "32", "--signed"]),
    ):
        same_output(src, kwargs, args, cli, tmp_path, "tif")
    assert (tmp_path / "ours.tif").read_bytes()[:4] == b"II*\0"
    # format= names it when the name has no extension.
    normalfit.convert(src, tmp_path / "normals", format="tiff", scale=0.1)
    normalfit.convert(src, tmp_path / "named.tif", scale=0.1)
    assert (tmp_path / "normals").read_bytes() == (tmp_path / "named.tif").read_bytes()
    with pytest.raises(ValueError, match="TIFF output holds 8, 16 or 32"):
        normalfit.convert(src, tmp_path / "bad.tif", bits=12)
    # The heights of a normal map, as float32 TIFF.
    normals = tmp_path / "n.exr"
    normalfit.convert(src, normals, scale=0.1)
    normalfit.height_file(normals, tmp_path / "h.tif", scale=0.1)
    run_cli(cli, "height", normals, "-o", tmp_path / "h_cli.tif", "-s", "0.1")
    assert (tmp_path / "h.tif").read_bytes() == (tmp_path / "h_cli.tif").read_bytes()
