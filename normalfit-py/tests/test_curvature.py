"""normalfit.curvature: against the NumPy reference (reference.py), the
command line's float map bit for bit, a dome's known value, refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import normalfit
import reference
from conftest import ROOT, read_png, run_cli


@pytest.mark.parametrize("border", reference.BORDERS)
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_matches_the_reference(border: str, dtype: type) -> None:
    rng = np.random.default_rng(5)
    if dtype == np.float32:
        stored = rng.random((13, 17)).astype(np.float32)
    else:
        stored = rng.integers(0, np.iinfo(dtype).max, (13, 17), endpoint=True).astype(dtype)
    got = normalfit.curvature(stored, patch=5, scale=3.0, border=border)
    assert got.dtype == np.float32 and got.shape == stored.shape
    want = reference.curvature(stored, 5, 3.0, border)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
    assert np.abs(want).max() > 0.01


def test_a_dome_is_convex_with_its_known_curvature() -> None:
    y, x = np.mgrid[-7:8, -7:8].astype(np.float64)
    dome = -(x * x + y * y) / 20.0
    k = normalfit.curvature(dome, patch=5, border="clamp")
    assert k[7, 7] == pytest.approx(0.1, rel=1e-6)
    assert normalfit.curvature(-dome, patch=5, border="clamp")[7, 7] == pytest.approx(-0.1, rel=1e-6)


def test_the_command_lines_16_bit_map_by_the_stated_mapping(cli: Path, tmp_path: Path) -> None:
    source = ROOT / "samples" / "rock.png"
    out = tmp_path / "k.png"
    run_cli(
        cli, "convert", source, "-o", out, "--product", "curvature", "-n", "7", "-s", "4",
        "--bits", "16", "--curvature-range", "0.02", "--quiet",
    )
    stored = read_png(source)
    assert stored.ndim == 2, "a gray sample"
    k = normalfit.curvature(stored, patch=7, scale=4.0, threads=2)
    # Flat at 32768, 0.02 white: round(32768 + 32767 clamp(k / 0.02, -1, 1)).
    want = np.floor(32768.0 + 32767.0 * np.clip(k.astype(np.float64) / 0.02, -1.0, 1.0) + 0.5).astype(np.uint16)
    got = read_png(out)
    assert got.dtype == np.uint16 and got.shape == stored.shape
    assert np.array_equal(got, want)
    assert got.min() < 32768 < got.max()


def test_refusals() -> None:
    heights = np.zeros((8, 8), dtype=np.float32)
    with pytest.raises(ValueError, match="patch"):
        normalfit.curvature(heights, patch=4)
    with pytest.raises(TypeError):
        normalfit.curvature(heights[0])
    heights[3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        normalfit.curvature(heights)
    k = normalfit.curvature(heights, nodata=float("nan"))
    assert np.isnan(k[3, 3]) and np.isnan(k[2, 4]) and k[0, 0] == 0.0
