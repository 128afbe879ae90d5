"""normalfit.blend: the formulas of "Blending in Detail" (Barré-Brisebois &
Hill, 2012) written out here in NumPy float64 on random unit normals, the
identities, tiling and refusals, and the command line's bytes."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import normalfit

from conftest import cli_binary, read_png, write_png


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_normals(shape: tuple[int, int], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = np.stack([rng.uniform(-1, 1, shape), rng.uniform(-1, 1, shape), rng.uniform(0.3, 1, shape)], axis=-1)
    return unit(v)


def reference(n1: np.ndarray, n2: np.ndarray, method: str) -> np.ndarray:
    if method == "linear":
        return unit(n1 + n2)
    if method == "udn":
        return unit(np.stack([n1[..., 0] + n2[..., 0], n1[..., 1] + n2[..., 1], n1[..., 2]], axis=-1))
    if method == "whiteout":
        return unit(np.stack([n1[..., 0] + n2[..., 0], n1[..., 1] + n2[..., 1], n1[..., 2] * n2[..., 2]], axis=-1))
    t = n1 + np.array([0.0, 0.0, 1.0])
    u = n2 * np.array([-1.0, -1.0, 1.0])
    return t * (np.sum(t * u, axis=-1, keepdims=True) / t[..., 2:3]) - u


@pytest.mark.parametrize("method", ["rnm", "whiteout", "udn", "linear"])
def test_blend_matches_the_formulas(method: str) -> None:
    a, b = random_normals((40, 56), 1), random_normals((40, 56), 2)
    got = normalfit.blend(a, b, method=method, convention="opengl")
    assert got.dtype == np.float64 and got.shape == a.shape
    np.testing.assert_allclose(got, reference(a, b, method), atol=1e-12)


def test_blend_flat_is_the_identity_and_rnm_adds_tilts() -> None:
    n = random_normals((16, 16), 3)
    flat = np.zeros_like(n)
    flat[..., 2] = 1.0
    for method in ["rnm", "whiteout", "udn"]:  # linear halves the base's tilt
        np.testing.assert_allclose(normalfit.blend(n, flat, method=method), n, atol=1e-12)
    for method in ["rnm", "whiteout"]:
        np.testing.assert_allclose(normalfit.blend(flat, n, method=method), n, atol=1e-12)
    a, b = 0.4, 0.3
    base = np.broadcast_to(np.array([np.sin(a), 0.0, np.cos(a)]), (4, 4, 3)).copy()
    det = np.broadcast_to(np.array([np.sin(b), 0.0, np.cos(b)]), (4, 4, 3)).copy()
    got = normalfit.blend(base, det, method="rnm")
    np.testing.assert_allclose(got[0, 0], [np.sin(a + b), 0.0, np.cos(a + b)], atol=1e-12)


def test_blend_tiles_the_detail_and_refuses_other_sizes() -> None:
    a, d = random_normals((12, 8), 4), random_normals((4, 2), 5)
    got = normalfit.blend(a, d, method="whiteout", convention="opengl")
    np.testing.assert_allclose(got, reference(a, np.tile(d, (3, 4, 1)), "whiteout"), atol=1e-12)
    with pytest.raises(ValueError, match="must divide"):
        normalfit.blend(a, random_normals((5, 2), 6))
    with pytest.raises(ValueError, match="strength"):
        normalfit.blend(a, d, strength=-1.0)
    with pytest.raises(ValueError, match="method"):
        normalfit.blend(a, d, method="overlay")
    with pytest.raises(TypeError):
        normalfit.blend(a.astype(np.int32), d)


def test_blend_reads_encoded_arrays() -> None:
    a, d = random_normals((8, 8), 7), random_normals((8, 8), 8)
    enc = np.round((a + 1) / 2 * 65535).astype(np.uint16)
    got = normalfit.blend(enc, d, convention="opengl")
    np.testing.assert_allclose(got, reference(unit(enc / 65535 * 2 - 1), d, "rnm"), atol=1e-9)


def enc(n: np.ndarray) -> np.ndarray:
    return np.round((n + 1) / 2 * 65535).astype(np.uint16)


def test_blend_file_matches_the_array_call(tmp_path: Path) -> None:
    binary = cli_binary()
    if binary is None:
        pytest.skip("no normalfit binary: cargo build --release first (or set NORMALFIT_BIN)")
    a, d = random_normals((32, 32), 9), random_normals((16, 16), 10)
    write_png(tmp_path / "a.png", enc(a))
    write_png(tmp_path / "d.png", enc(d))
    out = tmp_path / "out.png"
    subprocess.run(
        [str(binary), "blend", str(tmp_path / "a.png"), str(tmp_path / "d.png"), "-o", str(out), "--method", "udn", "--convention", "opengl"],
        check=True,
        capture_output=True,
    )
    got = read_png(out)
    want = normalfit.blend(enc(a), enc(d), method="udn", convention="opengl")
    assert np.abs(got.astype(np.float64) - (want + 1) / 2 * 65535).max() <= 0.5 + 1e-3
