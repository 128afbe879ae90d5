"""Holes: nodata= in normals() and convert(); missing texels are NaN."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import png
import pytest

import normalfit

RNG = np.random.default_rng(17)


def ramp(shape: tuple[int, int] = (20, 30)) -> np.ndarray:
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (0.03 * cols - 0.02 * rows + 0.05 * RNG.random(shape)).astype(np.float32)


def test_nan_heights_are_missing_with_nodata_nan() -> None:
    h = ramp()
    h[5, 7] = np.nan
    h[10:13, 20:24] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite"):
        normalfit.normals(h)
    n = normalfit.normals(h, nodata=float("nan"), border="clamp")
    missing = np.isnan(n).any(axis=2)
    assert missing[5, 7] and missing[11, 21]
    assert np.isnan(n[missing]).all(), "a missing texel is NaN in every component"
    assert not missing[0, 0] and not missing[5, 6]
    assert missing.sum() == 1 + 12
    # Valid texels are unit normals facing up.
    valid = n[~missing]
    assert np.allclose(np.linalg.norm(valid, axis=1), 1.0, atol=1e-6)
    assert (valid[:, 2] > 0).all()


def test_full_patches_keep_the_plain_fits_values() -> None:
    h = ramp((16, 16))
    plain = normalfit.normals(h, patch=5, border="mirror")
    h[8, 8] = -9999.0
    holed = normalfit.normals(h, patch=5, border="mirror", nodata=-9999.0)
    far = np.ones((16, 16), bool)
    far[6:11, 6:11] = False
    assert np.array_equal(plain[far], holed[far])
    assert np.isnan(holed[8, 8]).all() and not np.isnan(holed[7, 8]).any()


def test_integer_heights_with_a_nodata_value_and_the_residual() -> None:
    h = RNG.integers(1000, 2000, (12, 14)).astype(np.uint16)
    h[3, 4] = 0
    n, r = normalfit.normals(h, nodata=0, residual=True, scale=20.0)
    assert np.isnan(n[3, 4]).all() and np.isnan(r[3, 4])
    assert np.isfinite(r[0, 0]) and np.isfinite(n[3, 5]).all()


def test_nodata_needs_float_output() -> None:
    with pytest.raises(ValueError, match="float32"):
        normalfit.normals(ramp(), nodata=0.0, dtype=np.uint8)


def test_all_missing() -> None:
    n = normalfit.normals(np.full((5, 6), np.nan, np.float32), nodata=float("nan"))
    assert np.isnan(n).all()


def test_convert_with_nodata_writes_an_alpha(tmp_path: Path) -> None:
    values = RNG.integers(100, 60000, (9, 11)).astype(np.uint16)
    values[2, 3] = 0
    src = tmp_path / "h.png"
    png.Writer(11, 9, greyscale=True, bitdepth=16).write(src.open("wb"), values.tolist())
    dst = tmp_path / "n.png"
    summary = normalfit.convert(src, dst, nodata=0, border="clamp")
    assert summary.nodata == 0.0 and summary.missing == 1
    width, height, rows, info = png.Reader(filename=str(dst)).read()
    assert info["planes"] == 4 and info["bitdepth"] == 16
    pixels = np.array([list(r) for r in rows]).reshape(height, width, 4)
    assert pixels[2, 3, 3] == 0 and (pixels[..., 3] == 0).sum() == 1
    assert pixels[0, 0, 3] == 65535
    plain = normalfit.convert(src, tmp_path / "p.png")
    assert plain.nodata is None and plain.missing == 0
