"""normals() against SPEC's formula in plain NumPy (tests/reference.py)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import normalfit
import reference

RNG = np.random.default_rng(20261125)
SHAPES = [(9, 13), (1, 6), (5, 1), (2, 2)]
"""Rows x columns: odd sizes, a single row, a single column, a patch wider
than the image."""


def stored(dtype: type, shape: tuple[int, int]) -> np.ndarray:
    if dtype is np.uint8:
        return RNG.integers(0, 256, shape, dtype=np.uint8)
    if dtype is np.uint16:
        return RNG.integers(0, 65536, shape, dtype=np.uint16)
    # Floats offset far from zero: the detail must survive the offset.
    return (RNG.random(shape) * 0.5 + 300.0).astype(dtype)


@pytest.mark.parametrize("border", list(itertools.product(reference.BORDERS, repeat=2)), ids="-".join)
@pytest.mark.parametrize("fit", ["orthogonal", "vertical"])
@pytest.mark.parametrize("patch", [3, 5])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64], ids=lambda t: t.__name__)
def test_normals_match_the_formula(border: tuple[str, str], fit: str, patch: int, dtype: type) -> None:
    for shape in SHAPES:
        heights = stored(dtype, shape)
        for convention, scale in [("opengl", 4.0), ("directx", 0.5)]:
            want = reference.normals(heights, patch=patch, fit=fit, border=border, convention=convention, scale=scale)
            got = normalfit.normals(heights, patch=patch, fit=fit, border=border, convention=convention, scale=scale)
            assert got.shape == (*shape, 3) and got.dtype == np.float32
            worst = np.abs(got - want).max()
            assert worst <= 1e-5, f"{shape} {convention}: off by {worst}"
            for bits, dt in [(8, np.uint8), (16, np.uint16)]:
                encoded = normalfit.normals(
                    heights, patch=patch, fit=fit, border=border, convention=convention, scale=scale, dtype=dt
                )
                assert encoded.dtype == dt
                diff = np.abs(encoded.astype(np.int64) - reference.encode(want, bits).astype(np.int64)).max()
                assert diff <= 1, f"{shape} {convention} {bits}-bit: off by {diff} LSB"


def test_relief_and_invert_set_the_gain() -> None:
    heights = stored(np.uint16, (7, 12))
    want = reference.normals(heights, scale=-0.25 * 12)
    got = normalfit.normals(heights, relief=0.25, invert=True)
    assert np.abs(got - want).max() <= 1e-5


def test_defaults_are_the_contracts() -> None:
    heights = stored(np.float32, (8, 8))
    want = reference.normals(heights, patch=3, fit="orthogonal", border=("wrap", "wrap"), convention="opengl", scale=1.0)
    assert np.abs(normalfit.normals(heights) - want).max() <= 1e-5


def test_border_spellings_agree() -> None:
    heights = stored(np.float64, (6, 7))
    pair = normalfit.normals(heights, border=("clamp", "mirror"))
    assert np.array_equal(pair, normalfit.normals(heights, border="clamp,mirror"))
    assert np.array_equal(normalfit.normals(heights, border="mirror"), normalfit.normals(heights, border=("mirror", "mirror")))
    assert not np.array_equal(pair, normalfit.normals(heights, border=("mirror", "clamp")))


def test_convention_aliases() -> None:
    heights = stored(np.uint8, (5, 5))
    assert np.array_equal(normalfit.normals(heights, convention="gl"), normalfit.normals(heights, convention="opengl"))
    assert np.array_equal(normalfit.normals(heights, convention="dx"), normalfit.normals(heights, convention="directx"))


def test_residual_of_a_plane_with_a_checkerboard() -> None:
    """A known answer: a plane plus a checkerboard of amplitude 0.1 lies
    0.1 * sqrt(1 - 1/N^4) from the fitted plane (vertical fit, in the
    units of z = S h; here S = 1)."""
    w = h = 16
    y, x = np.mgrid[0:h, 0:w]
    heights = (0.01 * x + np.where((x + y) % 2 == 0, 0.1, -0.1)).astype(np.float32)
    normals, residual = normalfit.normals(heights, fit="vertical", border="mirror", residual=True)
    assert residual.shape == (h, w) and residual.dtype == np.float32
    assert normals.shape == (h, w, 3)
    expected = 0.1 * np.sqrt(1 - 1 / 81)
    assert abs(residual[5, 7] - expected) < 1e-5
    flat, flat_residual = normalfit.normals(np.full((4, 4), 0.3, np.float32), residual=True)
    assert np.all(flat_residual == 0) and np.all(flat == (0, 0, 1))
