"""The file APIs (convert, decode_normals, lit_view, check_tiling of a
file) against the command line, which drives the same library calls; and
border="auto" on arrays against `convert --border auto`."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import normalfit
from conftest import ROOT, read_png, run_cli, write_png

ROCK = ROOT / "samples" / "rock.png"
TERRAIN = ROOT / "samples" / "terrain.png"


@pytest.mark.parametrize(
    ("name", "kwargs", "args"),
    [
        ("rock.png", {"scale": 16.0}, ["-s", "16"]),
        ("terrain.png", {"scale": 40.0, "patch": 5, "border": "clamp"}, ["-s", "40", "-n", "5", "--border", "clamp"]),
        ("terrain.png", {"border": "auto", "bits": 16}, ["--border", "auto", "--bits", "16"]),
        ("bricks.png", {"border": ("auto", "mirror"), "convention": "dx", "alpha": "height"},
         ["--border", "auto,mirror", "--convention", "dx", "--alpha", "height"]),
        ("rock.png", {"channels": "rg", "compression": "small", "fit": "vertical"},
         ["--channels", "rg", "--compression", "small", "--fit", "vertical"]),
        ("rock.png", {"bits": 32, "signed": True}, ["--bits", "32", "--signed"]),
    ],
)
def test_convert_writes_the_clis_bytes(name: str, kwargs: dict[str, object], args: list[str], cli: Path, tmp_path: Path) -> None:
    ext = "exr" if kwargs.get("bits") == 32 else "png"
    ours, theirs = tmp_path / f"ours.{ext}", tmp_path / f"theirs.{ext}"
    summary = normalfit.convert(ROOT / "samples" / name, ours, **kwargs)  # type: ignore[arg-type]
    run_cli(cli, "convert", ROOT / "samples" / name, "-o", theirs, *args)
    assert ours.read_bytes() == theirs.read_bytes()
    assert (summary.width, summary.height) == (512, 512) and summary.input_format == "png"
    assert summary.streamed


def test_convert_settles_auto_and_warns_about_seams(tmp_path: Path) -> None:
    auto = normalfit.convert(TERRAIN, tmp_path / "a.png", border="auto")
    assert auto.borders == ("mirror", "mirror") and auto.tiling is not None and not auto.tiling.seamless
    assert auto.warnings == []
    wrap = normalfit.convert(TERRAIN, tmp_path / "w.png")
    assert wrap.borders == ("wrap", "wrap")
    assert len(wrap.warnings) == 1 and "does not tile" in wrap.warnings[0]


def test_convert_with_residual(tmp_path: Path, cli: Path) -> None:
    summary = normalfit.convert(ROCK, tmp_path / "n.png", residual=True, scale=16.0)
    assert not summary.streamed, "a residual is made from the whole image"
    run_cli(cli, "convert", ROCK, "-o", tmp_path / "c.png", "-s", "16", "--residual", tmp_path / "c_residual.png")
    assert (tmp_path / "n_residual.png").read_bytes() == (tmp_path / "c_residual.png").read_bytes()
    assert (tmp_path / "n.png").read_bytes() == (tmp_path / "c.png").read_bytes()


def test_convert_in_map_units(tmp_path: Path, cli: Path) -> None:
    """units= and pixel_size= give the command line's --units and
    --pixel-size bytes, streamed; map units of a file without
    georeferencing are refused, naming it."""
    dem = ROOT / "samples" / "dem" / "jacksboro_fault_dem.tif"
    for src, kwargs, args in [
        (dem, {"units": "map", "border": "clamp"}, ["--units", "map", "--border", "clamp"]),
        (ROCK, {"pixel_size": (2.0, 3.0), "fit": "vertical"}, ["--pixel-size", "2,3", "--fit", "vertical"]),
        (ROCK, {"pixel_size": 0.5}, ["--pixel-size", "0.5"]),
    ]:
        ours, theirs = tmp_path / "ours.exr", tmp_path / "theirs.exr"
        summary = normalfit.convert(src, ours, **kwargs)  # type: ignore[arg-type]
        run_cli(cli, "convert", src, "-o", theirs, *args)
        assert ours.read_bytes() == theirs.read_bytes(), kwargs
        assert summary.streamed, "map units and texel spacings stream, as -s does"
    with pytest.raises(OSError, match=r"rock\.png: unsupported: map units need the texel spacing"):
        normalfit.convert(ROCK, tmp_path / "o.png", units="map")
    with pytest.raises(ValueError, match="texel spacing must be finite and positive"):
        normalfit.convert(ROCK, tmp_path / "o.png", pixel_size=(1.0, -2.0))
    with pytest.raises(ValueError, match="unknown units 'metres'"):
        normalfit.convert(ROCK, tmp_path / "o.png", units="metres")


def test_convert_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError) as missing:
        normalfit.convert(tmp_path / "missing.png", tmp_path / "o.png")
    assert missing.value.filename == str(tmp_path / "missing.png")
    text = tmp_path / "notes.png"
    text.write_text("this is not an image\n")
    with pytest.raises(OSError, match=r"notes\.png: cannot decode: not a recognised image format"):
        normalfit.convert(text, tmp_path / "o.png")
    with pytest.raises(OSError, match="does not exist"):
        normalfit.convert(ROCK, tmp_path / "no" / "folder" / "o.png")
    with pytest.raises(ValueError, match="12 bits need EXR output"):
        normalfit.convert(ROCK, tmp_path / "o.png", bits=12)
    with pytest.raises(ValueError, match="8 bits need PNG output"):
        normalfit.convert(ROCK, tmp_path / "o.exr", bits=8)
    copy = tmp_path / "rock.png"
    copy.write_bytes(ROCK.read_bytes())
    with pytest.raises(ValueError, match="never writes over an input"):
        normalfit.convert(copy, copy)
    for kwargs, message in [
        ({"patch": 4}, "patch size must be odd"),
        ({"format": "jpeg"}, "unknown format 'jpeg': use png, exr, tiff, dds or ktx2"),
        ({"compression": "zip"}, "unknown compression 'zip'"),
        ({"alpha": "height", "channels": "rg"}, "has no alpha"),
        ({"alpha": "half"}, "unknown alpha 'half'"),
        ({"channels": "rgba"}, "unknown channels 'rgba'"),
        ({"channel": ""}, "got an empty name"),
        ({"max_texels": 0}, "max_texels must be at least 1"),
        # A ValueError as for 0, not the OverflowError of a conversion.
        ({"max_texels": -1}, "^invalid option: max_texels is out of range, got -1$"),
        ({"max_texels": 2**64}, "^invalid option: max_texels is out of range, got 18446744073709551616$"),
    ]:
        with pytest.raises(ValueError, match=message):
            normalfit.convert(ROCK, tmp_path / "o.png", **kwargs)  # type: ignore[arg-type]
    with pytest.raises(MemoryError, match="too large"):
        normalfit.convert(ROCK, tmp_path / "o.png", max_texels=1000)
    assert not (tmp_path / "o.png").exists(), "a failed conversion leaves no output"


def test_convert_refuses_an_extension_naming_another_format(tmp_path: Path, cli: Path) -> None:
    """A file whose extension names another format than its content is
    refused as the command line refuses it (the library's rule, one
    message), naming it; with no image extension it is read by content."""
    misnamed = tmp_path / "rock.exr"
    misnamed.write_bytes(ROCK.read_bytes())
    message = "is named .exr but its content is png: rename it"
    with pytest.raises(ValueError, match=rf"rock\.exr: {message}"):
        normalfit.convert(misnamed, tmp_path / "o.png")
    assert not (tmp_path / "o.png").exists()
    theirs = subprocess.run(
        [str(cli), "convert", str(misnamed), "-o", str(tmp_path / "c.png")], capture_output=True, text=True, timeout=300
    )
    assert theirs.returncode == 2 and f"normalfit: {misnamed}: {message}" in theirs.stderr, theirs.stderr
    unnamed = tmp_path / "rock"
    unnamed.write_bytes(ROCK.read_bytes())
    normalfit.convert(unnamed, tmp_path / "u.png")
    normalfit.convert(ROCK, tmp_path / "r.png")
    assert (tmp_path / "u.png").read_bytes() == (tmp_path / "r.png").read_bytes()


def test_decode_normals_reads_the_colours_back(tmp_path: Path) -> None:
    out = tmp_path / "n.png"
    normalfit.convert(ROCK, out, bits=16, scale=16.0)
    stored = read_png(out).astype(np.float64) / 65535
    decoded = normalfit.decode_normals(out)
    assert decoded.dtype == np.float32 and decoded.shape == (512, 512, 3)
    assert np.abs(decoded - (2 * stored - 1)).max() < 1e-6
    fitted = normalfit.normals(read_png(ROCK), scale=16.0)
    assert np.abs(decoded - fitted).max() < 2 / 65535
    with pytest.raises(OSError, match="needs R, G and B"):
        normalfit.decode_normals(ROCK)
    with pytest.raises(ValueError, match="signed normal maps are float"):
        normalfit.decode_normals(out, signed=True)


@pytest.mark.parametrize(
    ("kwargs", "args"),
    [
        ({"scale": 16.0, "tile": True}, ["-s", "16", "--tile"]),
        ({"light": (45.0, 60.0), "border": "auto", "scale": 4.0}, ["--light", "45,60", "--border", "auto", "-s", "4"]),
    ],
)
def test_lit_view_is_the_clis_picture(kwargs: dict[str, object], args: list[str], cli: Path, tmp_path: Path) -> None:
    ours = normalfit.lit_view(ROCK, **kwargs)  # type: ignore[arg-type]
    run_cli(cli, "shade", ROCK, "-o", tmp_path / "lit.png", *args)
    assert ours.dtype == np.uint8
    assert np.array_equal(ours, read_png(tmp_path / "lit.png"))


def test_lit_view_of_a_normal_map_and_refusals(tmp_path: Path) -> None:
    out = tmp_path / "n.png"
    normalfit.convert(ROCK, out, scale=16.0)
    of_normals = normalfit.lit_view(out)
    of_heights = normalfit.lit_view(ROCK, scale=16.0)
    assert of_normals.shape == (512, 512)
    assert np.abs(of_normals.astype(int) - of_heights.astype(int)).max() <= 2
    with pytest.raises(ValueError, match="elevation must be from 0 to 90"):
        normalfit.lit_view(ROCK, light=(0.0, 95.0))
    with pytest.raises(FileNotFoundError):
        normalfit.lit_view(tmp_path / "missing.png")


@pytest.mark.parametrize("name", ["rock.png", "terrain.png"])
def test_check_tiling_of_a_file_is_the_clis(name: str, cli: Path) -> None:
    line = json.loads(
        subprocess.run([str(cli), "tiling", "--json", str(ROOT / "samples" / name)], capture_output=True, text=True).stdout
    )
    report = normalfit.check_tiling(ROOT / "samples" / name)
    assert report.seamless == line["seamless"] and report.kind == line["kind"]
    assert (report.width, report.height) == (line["width"], line["height"])
    for axis in ("x", "y"):
        assert getattr(report, axis).score == pytest.approx(line[axis]["score"], abs=1e-4)
    assert normalfit.check_tiling(str(ROOT / "samples" / name)).x.score == report.x.score
    array = normalfit.check_tiling(read_png(ROOT / "samples" / name))
    assert array.x.score == report.x.score and array.y.score == report.y.score
    with pytest.raises(TypeError, match="for files"):
        normalfit.check_tiling(read_png(ROOT / "samples" / name), channel="r")


@pytest.mark.parametrize("border", ["auto", "auto,clamp", "wrap,auto"])
def test_auto_borders_on_arrays_are_the_clis(border: str, cli: Path, tmp_path: Path) -> None:
    for name in ("rock", "terrain"):
        source = ROOT / "samples" / f"{name}.png"
        run_cli(cli, "convert", source, "-o", tmp_path / "o.png", "--bits", "16", "--border", border)
        got = normalfit.normals(read_png(source), border=border, dtype=np.uint16)
        assert np.array_equal(got, read_png(tmp_path / "o.png")), name


def test_auto_picks_wrap_where_an_array_tiles(tmp_path: Path) -> None:
    n = 64
    y, x = np.mgrid[0:n, 0:n]
    tiles = (0.5 + 0.25 * np.sin(2 * np.pi * x / n) + y / 400).astype(np.float32)  # tiles in x only
    got = normalfit.normals(tiles, border="auto")
    assert np.array_equal(got, normalfit.normals(tiles, border=("wrap", "mirror")))
    write_png(tmp_path / "t.png", np.round(tiles * 65535).astype(np.uint16))
    assert normalfit.check_tiling(tmp_path / "t.png").suggested_borders == ("wrap", "mirror")


def forged_png(width: int, height: int) -> bytes:
    """A PNG header claiming width x height 16-bit gray texels, then one
    tiny IDAT: the pixels are not there."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\x00" * 7)) + chunk(b"IEND", b"")


@pytest.mark.parametrize(
    ("make", "error"),
    [
        (lambda p: p.write_bytes(b""), OSError),
        (lambda p: p.write_bytes(ROCK.read_bytes()[:3000]), OSError),
        # Headers claiming more texels than max_texels are too large, as
        # the command line's line says: MemoryError, before any pixel.
        (lambda p: p.write_bytes(forged_png(100_000, 100_000)), MemoryError),
        (lambda p: p.write_bytes(forged_png(2**31 - 1, 1)), MemoryError),
        (lambda p: p.write_bytes(forged_png(300, 200)), OSError),
        (lambda p: p.write_bytes(np.random.default_rng(9).integers(0, 256, 5000, dtype=np.uint8).tobytes()), OSError),
        (lambda p: p.mkdir(), OSError),
    ],
    ids=["empty", "truncated", "huge-header", "wide-header", "short-data", "noise", "a-folder"],
)
def test_hostile_files_are_os_or_memory_errors(make, error: type[Exception], tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    bad = tmp_path / "bad.png"
    make(bad)
    for call in (
        lambda: normalfit.convert(bad, tmp_path / "o.png"),
        lambda: normalfit.convert(bad, tmp_path / "o.png", residual=True, border="auto"),
        lambda: normalfit.decode_normals(bad),
        lambda: normalfit.lit_view(bad),
        lambda: normalfit.check_tiling(bad),
    ):
        with pytest.raises(error) as caught:
            call()
        assert "bad.png" in str(caught.value) and "\n" not in str(caught.value)
        if error is MemoryError:
            assert "too large: " in str(caught.value), caught.value
    assert not (tmp_path / "o.png").exists()
