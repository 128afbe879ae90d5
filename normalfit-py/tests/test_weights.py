"""weights="binomial": the weighted plane fit (SPEC section 2, "Weights")
against reference.py's weighted sums, in every front end that takes a
patch (normals, normalfit.dask, normalfit.xarray, lit_view); chunked
equals whole; its refusals."""

from __future__ import annotations

import numpy as np
import pytest

import normalfit
import reference


def dem(h: int, w: int) -> np.ndarray:
    """Heights near 400 with hills and roughness: known non-zero slopes."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    rng = np.random.default_rng(5)
    v = 400.0 + 3.0 * np.sin(0.21 * x) * np.cos(0.17 * y) + 0.4 * x - 0.25 * y
    return v + 0.3 * rng.random((h, w))


@pytest.mark.parametrize("border", ["wrap", "clamp", ("mirror", "wrap")])
@pytest.mark.parametrize("fit", ["orthogonal", "vertical"])
@pytest.mark.parametrize("patch", [3, 5, 9])
def test_binomial_normals_are_the_weighted_reference(patch: int, fit: str, border: object) -> None:
    heights = dem(21, 26)
    pair = (border, border) if isinstance(border, str) else border
    got = normalfit.normals(heights, patch=patch, fit=fit, border=border, weights="binomial", scale=0.7)
    want = reference.normals(heights, patch=patch, fit=fit, border=pair, scale=0.7, weights="binomial")
    np.testing.assert_allclose(got, want, atol=1e-6)
    uniform = reference.normals(heights, patch=patch, fit=fit, border=pair, scale=0.7)
    assert np.abs(got - uniform).max() > 1e-4, "the weights made no difference"


def test_dask_chunks_give_the_whole_bits() -> None:
    da = pytest.importorskip("dask.array", reason="dask is not installed (pip install 'normalfit[dask]')")
    import normalfit.dask as nd

    heights = dem(60, 70)
    whole = normalfit.normals(heights, patch=9, border="clamp", weights="binomial")
    chunked = nd.normals(da.from_array(heights, chunks=(17, 23)), patch=9, border="clamp", weights="binomial")
    assert np.array_equal(np.asarray(chunked.compute()), whole)


def test_refusals_name_the_reason() -> None:
    heights = dem(8, 8)
    with pytest.raises(ValueError, match="unknown weights 'pascal'"):
        normalfit.normals(heights, weights="pascal")
    with pytest.raises(ValueError, match="residual"):
        normalfit.normals(heights, weights="binomial", residual=True)
    with pytest.raises(ValueError, match="one patch size"):
        normalfit.normals(heights, weights="binomial", detail=[(3, 1.0), (9, 0.5)])
