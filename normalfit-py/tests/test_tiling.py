"""check_tiling(): known answers, the command line's --json, refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import normalfit
import subprocess

from conftest import write_png

N = 96


def sine() -> np.ndarray:
    """Periodic on both axes: tiles."""
    y, x = np.mgrid[0:N, 0:N]
    return (32767.5 + 30000 * np.sin(2 * np.pi * (2 * x / N + y / N))).astype(np.uint16)


def ramp() -> np.ndarray:
    """A ramp along x: a jump at the x wrap; every row the same, so y tiles."""
    return np.tile((65535 * np.arange(N) / (N - 1)).astype(np.uint16), (N, 1))


def test_known_answers() -> None:
    tiles = normalfit.check_tiling(sine())
    assert tiles.seamless and tiles.x.seamless and tiles.y.seamless and tiles.kind == "height"
    assert tiles.suggested_borders == ("wrap", "wrap")
    seam = normalfit.check_tiling(ramp())
    assert not seam.seamless and not seam.x.seamless and seam.y.seamless
    assert seam.x.score > 10 and seam.y.score == 1.0
    assert seam.suggested_borders == ("mirror", "wrap")
    assert (seam.width, seam.height) == (N, N)
    assert "seamless=False" in repr(seam)


def test_threshold_and_kind() -> None:
    seam = normalfit.check_tiling(ramp())
    assert normalfit.check_tiling(ramp(), threshold=seam.x.score * 2).x.seamless
    normal_map = normalfit.normals(sine(), scale=4.0, dtype=np.uint8)
    assert normalfit.check_tiling(normal_map).kind == "normal"
    assert normalfit.check_tiling(normal_map, kind="height").kind == "height"
    assert normalfit.check_tiling(sine(), kind="normal").kind == "normal"


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_every_dtype_and_layout(dtype: type) -> None:
    heights = ramp().astype(np.float64) / 65535
    stored = (heights * (255 if dtype is np.uint8 else 65535)).astype(dtype) if dtype in (np.uint8, np.uint16) else heights.astype(dtype)
    report = normalfit.check_tiling(stored)
    assert not report.x.seamless and report.y.seamless
    assert normalfit.check_tiling(np.asfortranarray(stored)).x.score == report.x.score
    rgb = np.stack([stored] * 3, axis=-1)
    assert not normalfit.check_tiling(rgb).x.seamless


@pytest.mark.parametrize("name", ["sine", "ramp"])
def test_same_as_the_cli_json(name: str, cli: Path, tmp_path: Path) -> None:
    image = sine() if name == "sine" else ramp()
    path = tmp_path / f"{name}.png"
    write_png(path, image)
    result = subprocess.run([str(cli), "tiling", "--json", str(path)], capture_output=True, text=True)
    line = json.loads(result.stdout.splitlines()[0])
    report = normalfit.check_tiling(image)
    assert report.kind == line["kind"] and report.seamless == line["seamless"]
    assert (report.width, report.height) == (line["width"], line["height"])
    for axis in ("x", "y"):
        # The JSON line rounds scores to 4 decimals.
        assert getattr(report, axis).score == pytest.approx(line[axis]["score"], abs=1e-4)
        assert getattr(report, axis).seamless == line[axis]["seamless"]


def test_refusals() -> None:
    with pytest.raises(ValueError, match="threshold must be positive"):
        normalfit.check_tiling(sine(), threshold=0)
    with pytest.raises(ValueError, match="threshold must be positive"):
        normalfit.check_tiling(sine(), threshold=float("nan"))
    with pytest.raises(ValueError, match="unknown kind 'bump'"):
        normalfit.check_tiling(sine(), kind="bump")
    with pytest.raises(TypeError, match="1 to 4 channels"):
        normalfit.check_tiling(np.zeros((4, 4, 5), np.uint8))
    with pytest.raises(TypeError, match="2-D or 3-D"):
        normalfit.check_tiling(np.zeros(4, np.uint8))
    with pytest.raises(TypeError, match="uint8, uint16"):
        normalfit.check_tiling(np.zeros((4, 4), np.int64))
    # No texels: no verdict, as the command line refuses an empty image.
    with pytest.raises(ValueError, match="both sides must be at least 1"):
        normalfit.check_tiling(np.zeros((0, 4), np.float32))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_non_finite_heights_are_refused_as_the_cli_refuses_them(bad: float, dtype: type, cli: Path, tmp_path: Path) -> None:
    """A height map with a NaN or infinite height has no seam score: the
    library's tiling check refuses it, from an array as from a file (it was
    "seamless" from an array, issue 32). The CLI's line for the same
    heights in a float TIFF names the same texel."""
    heights = np.tile(np.sin(np.linspace(0, 2 * np.pi, 16, endpoint=False)), (12, 1)).astype(dtype)
    heights[5, 7] = bad
    heights[9, 2] = bad
    for image, kind in [(heights, "auto"), (heights, "height"), (np.stack([heights] * 3, axis=-1), "auto")]:
        with pytest.raises(ValueError, match=r"^height at texel \(x 7, y 5\) is NaN or infinite$"):
            normalfit.check_tiling(image, kind=kind)
    path = tmp_path / "nan.tif"
    write_float_tiff(path, heights.astype(np.float32))
    result = subprocess.run([str(cli), "tiling", str(path)], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr == f"normalfit: {path}: height at texel (x 7, y 5) is NaN or infinite\n"
    with pytest.raises(OSError, match=r"height at texel \(x 7, y 5\) is NaN or infinite"):
        normalfit.check_tiling(path)


def write_float_tiff(path: Path, heights: np.ndarray) -> None:
    """A one-strip little-endian float32 TIFF of `heights`."""
    import struct

    h, w = heights.shape
    data = heights.astype("<f4").tobytes()
    entries = [(256, 4, w), (257, 4, h), (258, 3, 32), (259, 3, 1), (262, 3, 1), (273, 4, 0), (277, 3, 1), (278, 4, h), (279, 4, len(data)), (339, 3, 3)]
    data_at = 8 + 2 + 12 * len(entries) + 4
    out = b"II*\0" + struct.pack("<IH", 8, len(entries))
    for tag, kind, value in entries:
        value = data_at if tag == 273 else value
        out += struct.pack("<HHI", tag, kind, 1) + (struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value))
    path.write_bytes(out + struct.pack("<I", 0) + data)
