"""detail=: the normal of the weighted sum of several scales' slopes
(docs/detail.md), against that sum made here in NumPy (float64) from each
scale's own float output; one scale of weight 1 is patch=N; convert and
normalfit.dask take it too; its refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import normalfit

SCALES = [(3, 1.0), (9, 0.5), (5, -0.25)]


def field(h: int, w: int, seed: int = 3) -> np.ndarray:
    """Heights with detail at several scales, no symmetry."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    rng = np.random.default_rng(seed)
    v = 0.5 + 0.25 * np.sin(0.11 * x + 0.05 * y) + 0.1 * np.cos(0.7 * x) * np.sin(0.45 * y)
    return (v + 0.1 * rng.random((h, w))).astype(np.float32)


def combined(heights: np.ndarray, scales: list[tuple[int, float]], **options: object) -> np.ndarray:
    """Each scale fitted alone (float32 normals), slopes p = -nx/nz,
    q = -ny/nz summed with the weights, n ~ (-sum w p, -sum w q, 1)."""
    a = np.zeros(heights.shape)
    b = np.zeros(heights.shape)
    for n, weight in scales:
        normals = normalfit.normals(heights, patch=n, **options).astype(np.float64)  # type: ignore[arg-type]
        a += weight * normals[..., 0] / normals[..., 2]
        b += weight * normals[..., 1] / normals[..., 2]
    length = np.sqrt(a * a + b * b + 1.0)
    return np.stack([a / length, b / length, 1.0 / length], axis=-1)


@pytest.mark.parametrize("border", ["wrap", "clamp", ("mirror", "wrap")])
@pytest.mark.parametrize("fit", ["orthogonal", "vertical"])
def test_normals_are_those_of_the_summed_slopes(border: object, fit: str) -> None:
    heights = field(31, 27)
    options = dict(border=border, fit=fit, scale=6.0)
    got = normalfit.normals(heights, detail=SCALES, **options)  # type: ignore[arg-type]
    want = combined(heights, SCALES, **options)
    assert got.dtype == np.float32
    # The single scales come as float32 here; the detail fit sums float64.
    assert np.abs(got - want).max() < 1e-5
    coarse = normalfit.normals(heights, patch=9, **options)  # type: ignore[arg-type]
    assert np.abs(got - coarse).max() > 0.05


def test_one_scale_of_weight_one_is_patch_n_and_threads_change_no_bit() -> None:
    heights = field(40, 33)
    for dtype in (np.float32, np.uint16):
        single = normalfit.normals(heights, patch=7, dtype=dtype)
        assert np.array_equal(normalfit.normals(heights, detail=[(7, 1.0)], dtype=dtype), single)
    one = normalfit.normals(heights, detail=SCALES, dtype=np.uint16, threads=1)
    assert np.array_equal(normalfit.normals(heights, detail=SCALES, dtype=np.uint16, threads=3), one)


def test_convert_takes_detail(tmp_path: Path) -> None:
    heights = (field(30, 26) * 65535).round().clip(0, 65535).astype(np.uint16)
    import png  # pypng: 16-bit PNG exactly

    src = tmp_path / "h.png"
    png.from_array(heights, "L;16").save(str(src))
    dst = tmp_path / "n.png"
    normalfit.convert(src, dst, detail=SCALES, bits=16, border="clamp")
    rows = png.Reader(filename=str(dst)).asDirect()[2]
    got = np.vstack([np.asarray(r, np.uint16) for r in rows]).reshape(30, 26, 3)
    assert np.array_equal(got, normalfit.normals(heights, detail=SCALES, dtype=np.uint16, border="clamp"))


def test_dask_plans_the_largest_size_s_halo() -> None:
    da = pytest.importorskip("dask.array", reason="dask is not installed (pip install 'normalfit[dask]')")
    import dask

    import normalfit.dask as nd

    heights = field(70, 52)
    lazy = nd.normals(da.from_array(heights, chunks=(20, 15)), detail=SCALES, border=("wrap", "mirror"))
    with dask.config.set(scheduler="synchronous"):
        got = lazy.compute()
    assert np.array_equal(got, normalfit.normals(heights, detail=SCALES, border=("wrap", "mirror")))


@pytest.mark.parametrize(
    ("detail", "says"),
    [
        ([(4, 1.0)], "detail patch size must be odd"),
        ([(3, 1.0), (3, 2.0)], "detail gives patch size 3 twice"),
        ([(3, float("nan"))], "detail weight must be finite"),
        ([], "at least one scale"),
        ([(-3, 1.0)], "detail patch size must be odd"),
    ],
)
def test_bad_detail_is_a_value_error(detail: list[tuple[int, float]], says: str) -> None:
    with pytest.raises(ValueError, match=says):
        normalfit.normals(field(8, 8), detail=detail)


def test_what_detail_cannot_do_raises() -> None:
    heights = field(8, 8)
    with pytest.raises(ValueError, match="not both"):
        normalfit.normals(heights, patch=5, detail=SCALES)
    with pytest.raises(ValueError, match="no residual"):
        normalfit.normals(heights, detail=SCALES, residual=True)
    with pytest.raises(TypeError, match="pairs"):
        normalfit.normals(heights, detail=[3, 5])  # type: ignore[list-item]
