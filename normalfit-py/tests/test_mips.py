"""normalfit.mips against ``normalfit convert --mips``: the same levels, bit
for bit, as the command line writes them without blocks (a DDS's RGBA8, and
16-bit PNG levels); the roughness chain against Toksvig's formula; errors
as exceptions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import normalfit
from conftest import read_png, run_cli, write_png


def level_sizes(w: int, h: int) -> list[tuple[int, int]]:
    sizes = [(w, h)]
    while w > 1 or h > 1:
        w, h = max(1, w // 2), max(1, h // 2)
        sizes.append((w, h))
    return sizes


def dds_levels(path: Path, w: int, h: int) -> list[np.ndarray]:
    """The RGBA8 levels of a DDS with the DX10 header (148 bytes)."""
    data = path.read_bytes()
    assert data[:4] == b"DDS "
    levels, at = [], 148
    for lw, lh in level_sizes(w, h):
        levels.append(np.frombuffer(data[at : at + lw * lh * 4], dtype=np.uint8).reshape(lh, lw, 4))
        at += lw * lh * 4
    assert at == len(data)
    return levels


@pytest.fixture
def heights() -> np.ndarray:
    y, x = np.mgrid[0:21, 0:45]
    v = 0.5 + 0.2 * np.sin(x * 0.7) * np.cos(y * 0.3) + 0.1 * np.sin(x * 0.05 + y * 0.11)
    return np.round(np.clip(v, 0, 1) * 65535).astype(np.uint16)


@pytest.mark.parametrize("border", ["wrap", "clamp", "mirror"])
def test_fitted_levels_match_the_cli_bit_for_bit(heights: np.ndarray, border: str, cli: Path, tmp_path: Path) -> None:
    src = tmp_path / "h.png"
    write_png(src, heights)
    opts = ["--mips", "fit", "-n", "5", "--border", border, "-s", "3", "--convention", "directx"]
    run_cli(cli, "convert", src, "-o", tmp_path / "n.dds", "--compress", "none", *opts)
    run_cli(cli, "convert", src, "-o", tmp_path / "n.png", "--bits", "16", *opts)
    kw = dict(way="fit", patch=5, border=border, scale=3.0, convention="directx")
    eight = normalfit.mips(heights, dtype=np.uint8, **kw)
    sixteen = normalfit.mips(heights, dtype=np.uint16, **kw)
    floats = normalfit.mips(heights, **kw)
    sizes = level_sizes(45, 21)
    assert [a.shape[:2] for a in floats] == [(lh, lw) for lw, lh in sizes]
    for k, level in enumerate(dds_levels(tmp_path / "n.dds", 45, 21)):
        np.testing.assert_array_equal(eight[k], level[:, :, :3], err_msg=f"level {k}")
        png = read_png(tmp_path / ("n.png" if k == 0 else f"n_mip{k}.png"))
        np.testing.assert_array_equal(sixteen[k], png, err_msg=f"level {k}")
        assert floats[k].dtype == np.float32
    # Level 0 is the plain fit.
    plain = normalfit.normals(heights, patch=5, border=border, scale=3.0, convention="directx")
    np.testing.assert_allclose(floats[0], plain, atol=0)


def test_average_of_a_normal_map_matches_the_cli(tmp_path: Path, cli: Path) -> None:
    y, x = np.mgrid[0:16, 0:40]
    n = np.stack([0.6 * np.sin(x * 0.9), 0.4 * np.cos(y * 1.3 + x * 0.2), np.ones(x.shape)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rgb = np.round((n + 1) / 2 * 65535).astype(np.uint16)
    write_png(tmp_path / "map.png", rgb)
    run_cli(cli, "convert", tmp_path / "map.png", "-o", tmp_path / "avg.png", "--mips", "average", "--bits", "16")
    levels = normalfit.mips(rgb, way="average", dtype=np.uint16)
    for k, level in enumerate(levels):
        png = read_png(tmp_path / ("avg.png" if k == 0 else f"avg_mip{k}.png"))
        np.testing.assert_array_equal(level, png, err_msg=f"level {k}")


def test_roughness_of_alternating_slopes_is_toksvigs() -> None:
    s = 0.5
    n = np.zeros((8, 32, 3))
    n[:, 0::2] = [s, 0, 1]
    n[:, 1::2] = [-s, 0, 1]
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    levels, rough = normalfit.mips(n.astype(np.float32), way="average", roughness=True)
    assert len(levels) == len(rough) == 6
    assert np.all(rough[0] == 0)
    want = (np.sqrt(1 + s * s) - 1) ** 0.25
    for k in range(1, 6):
        np.testing.assert_allclose(rough[k], want, rtol=1e-5, err_msg=f"level {k}")
    base = np.full((8, 32), 0.3, dtype=np.float32)
    _, based = normalfit.mips(n.astype(np.float32), way="average", roughness_base=base)
    np.testing.assert_allclose(based[0], 0.3, rtol=1e-6)
    np.testing.assert_allclose(based[3], (0.3**4 + np.sqrt(1 + s * s) - 1) ** 0.25, rtol=1e-5)


def test_errors_are_exceptions(heights: np.ndarray) -> None:
    with pytest.raises(ValueError, match="normal map"):
        normalfit.mips(np.zeros((4, 4, 3), np.float32), way="fit")
    with pytest.raises(ValueError, match="average"):
        normalfit.mips(heights, way="average")
    with pytest.raises(ValueError, match="size"):
        normalfit.mips(heights, roughness_base=np.zeros((3, 3), np.float32))
    with pytest.raises(ValueError, match="mip chain"):
        normalfit.mips(heights, way="sideways")
    with pytest.raises(ValueError, match="roughness"):
        normalfit.mips(heights, roughness_base=np.full(heights.shape, 2.0, np.float32))
