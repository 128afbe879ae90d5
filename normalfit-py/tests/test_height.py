"""normalfit.height and height_file: the inverse of normals(), checked by
round trips (float, 16-bit, 8-bit), against a closed-form Fourier mode
computed here, against the command line's bytes, and for its errors."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import png  # pypng
import pytest

import normalfit

from conftest import cli_binary


def periodic(rows: int, cols: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:rows, 0:cols]
    h = np.full((rows, cols), 0.5)
    for _ in range(8):
        kx, ky = rng.integers(-5, 6, size=2)
        h += 0.05 * rng.random() * np.sin(2 * np.pi * (kx * x / cols + ky * y / rows) + rng.random() * 3)
    return h


def relative(original: np.ndarray, back: np.ndarray) -> float:
    want = original - original.mean()
    return float(np.abs(want - back).max() / np.ptp(want))


@pytest.mark.parametrize("fit", ["vertical", "orthogonal"])
@pytest.mark.parametrize("border", ["wrap", "mirror"])
@pytest.mark.parametrize("patch", [3, 5])
def test_float_round_trip_within_1e_4(fit: str, border: str, patch: int) -> None:
    h = periodic(48, 64)
    n = normalfit.normals(h, patch=patch, fit=fit, border=border, scale=6.0)
    back, info = normalfit.height(n, patch=patch, fit=fit, border=border, scale=6.0)
    assert back.shape == h.shape and back.dtype == np.float64
    assert info.converged and info.bad_texels == 0
    assert relative(h, back) < 1e-4


def test_encoded_round_trips_state_their_precision() -> None:
    h = periodic(64, 64, seed=3)
    for dtype, bound in [(np.uint16, 1e-3), (np.uint8, 3e-2)]:
        rgb = normalfit.normals(h, fit="vertical", scale=8.0, dtype=dtype)
        back, info = normalfit.height(rgb, fit="vertical", scale=8.0)
        want = h - h.mean()
        rms = float(np.sqrt(np.mean((want - back) ** 2)) / np.ptp(want))
        assert rms < bound, (dtype, rms)
        assert info.quantisation_error is not None and info.quantisation_error > 0


def test_a_fourier_mode_matches_its_closed_form() -> None:
    """z = sin(wx x + wy y); N = 3: the vertical fit's slopes are
    (1/6) 2 sin(wx) (1 + 2 cos(wy)) cos(theta) and the same with x, y
    swapped (A = 6)."""
    rows, cols, kx, ky = 24, 32, 3, 2
    wx, wy = 2 * np.pi * kx / cols, 2 * np.pi * ky / rows
    y, x = np.mgrid[0:rows, 0:cols].astype(np.float64)
    theta = wx * x + wy * y
    gx = 2 * np.sin(wx) * (1 + 2 * np.cos(wy)) * np.cos(theta) / 6
    gy = 2 * np.sin(wy) * (1 + 2 * np.cos(wx)) * np.cos(theta) / 6
    n = np.stack([-gx, gy, np.ones_like(gx)], axis=-1)  # OpenGL: n ∝ (−gx, gy, 1)
    back, _ = normalfit.height(n, fit="vertical")
    assert np.abs(back - np.sin(theta)).max() < 1e-9


def test_auto_convention_and_generic_model() -> None:
    h = periodic(40, 40, seed=5)
    n = normalfit.normals(h, convention="directx", scale=5.0)
    back, info = normalfit.height(n, convention="auto", scale=5.0)
    assert info.convention == "directx" and info.curl is not None and info.curl[1] < info.curl[0]
    assert relative(h, back) < 1e-4
    generic, _ = normalfit.height(n, convention="directx", scale=5.0, model="generic")
    assert relative(h, generic) > 10 * relative(h, back)


def test_threads_give_the_same_bits() -> None:
    n = normalfit.normals(periodic(50, 30), scale=3.0)
    one, _ = normalfit.height(n, scale=3.0, threads=1)
    three, _ = normalfit.height(n, scale=3.0, threads=3)
    assert np.array_equal(one, three)


def test_bad_calls_raise() -> None:
    n = np.zeros((4, 4, 3), np.float32)
    n[..., 2] = 1
    with pytest.raises(ValueError, match="patch"):
        normalfit.height(n, patch=4)
    with pytest.raises(ValueError, match="auto"):
        normalfit.height(n, border="auto")
    with pytest.raises(ValueError, match="model"):
        normalfit.height(n, model="poisson")
    with pytest.raises(TypeError):
        normalfit.height(np.zeros((4, 4), np.float32))
    with pytest.raises(ValueError, match="shape"):
        normalfit.height(np.zeros((4, 4, 2), np.float32))
    flat, info = normalfit.height(n)
    assert not flat.any() and info.range == (0.0, 0.0)


def test_clamp_past_the_limit_of_time_raises_as_the_command_line_refuses() -> None:
    """Clamp at N = 255 on a 4 × 2048 map: no path solves it within the
    limit of time (a band of 254, conjugate gradients past it), so it
    raises before any solve, naming the limit; mirror at the same N runs."""
    n = normalfit.normals(periodic(4, 2048), patch=255, border="clamp")
    with pytest.raises(ValueError, match="past the limit of 2.1e9"):
        normalfit.height(n, patch=255, border="clamp")
    back, _ = normalfit.height(n, patch=255, border="mirror")
    assert np.isfinite(back).all()


def test_heights_past_the_float_range_raise() -> None:
    """A gain so small that the heights leave f64's range raises, as the
    command line refuses: never infinite heights."""
    n = normalfit.normals(periodic(24, 32), scale=4.0)
    with pytest.raises(ValueError, match="overflow"):
        normalfit.height(n, scale=1e-320)
    back, info = normalfit.height(n, scale=1e-40)
    assert np.isfinite(back).all() and np.isfinite(info.range).all()


def test_height_file_matches_the_command_line(tmp_path: Path) -> None:
    binary = cli_binary()
    if binary is None:
        pytest.skip("the normalfit binary is not built (cargo build --release)")
    h = periodic(32, 48, seed=7)
    hpng, nmap = tmp_path / "h.png", tmp_path / "n.exr"
    png.from_array((h / h.max() * 65535).round().astype(np.uint16).tolist(), "L;16").save(str(hpng))
    subprocess.run([str(binary), "convert", str(hpng), "-o", str(nmap), "-s", "4"], check=True)
    ours, theirs = tmp_path / "ours.exr", tmp_path / "theirs.exr"
    info = normalfit.height_file(nmap, ours, scale=4.0)
    subprocess.run([str(binary), "height", str(nmap), "-o", str(theirs), "-s", "4"], check=True)
    assert ours.read_bytes() == theirs.read_bytes()
    assert info.warnings == [] and info.png_range is None and info.png_scale is None
    as_png = normalfit.height_file(nmap, tmp_path / "h2.png", scale=4.0)
    assert as_png.png_range is not None and as_png.png_range[0] < as_png.png_range[1]
    # The gain that re-creates the normals from the PNG: S times the span,
    # and the command line prints the same figure.
    lo, hi = as_png.png_range
    assert as_png.png_scale == pytest.approx(4.0 * (hi - lo), rel=1e-12)
    printed = subprocess.run(
        [str(binary), "height", str(nmap), "-o", str(tmp_path / "h3.png"), "-s", "4"],
        check=True, capture_output=True, text=True,
    )
    assert f"convert -s {as_png.png_scale:.6f}" in printed.stdout + printed.stderr
    # The same gain given relative to the width (48 columns) gives the same figure.
    by_relief = normalfit.height_file(nmap, tmp_path / "h4.png", relief=4.0 / 48)
    assert by_relief.png_scale == pytest.approx(as_png.png_scale, rel=1e-9)
    with pytest.raises(OSError, match="missing.exr"):
        normalfit.height_file(tmp_path / "missing.exr", tmp_path / "x.exr")


def test_holes_come_back_as_holes_and_the_rest_up_to_a_constant() -> None:
    # Odd sides, not multiples of 3: under wrap at N = 3 only the constant
    # is then unseen (no alternating heights, no zeros of the box).
    h = periodic(35, 41)
    holes = np.zeros(h.shape, dtype=bool)
    holes[10:16, 20:24] = True
    n = normalfit.normals(np.where(holes, np.nan, h), fit="vertical", scale=6.0, nodata=float("nan"))
    back, info = normalfit.height(n, fit="vertical", scale=6.0, holes=holes)
    assert np.array_equal(np.isnan(back), holes)
    assert (info.holes, info.undetermined, info.converged) == (24, 0, True)
    diff = (back - h)[~holes]
    assert np.ptp(diff) < 1e-6
    # No hole: the inverse without holes, to the bit.
    plain, _ = normalfit.height(n, fit="vertical", scale=6.0)
    none, _ = normalfit.height(n, fit="vertical", scale=6.0, holes=np.zeros(h.shape, dtype=bool))
    assert np.array_equal(plain, none)


def test_a_mask_of_the_wrong_shape_raises() -> None:
    n = normalfit.normals(periodic(16, 24))
    with pytest.raises(ValueError, match="holes must have the normals' shape"):
        normalfit.height(n, holes=np.zeros((24, 16), dtype=bool))
    with pytest.raises((TypeError, ValueError)):
        normalfit.height(n, holes=np.zeros(16 * 24, dtype=bool))
