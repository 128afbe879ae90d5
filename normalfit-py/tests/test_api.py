"""Layouts, dtypes, out=, and every exception; hostile inputs never abort."""

from __future__ import annotations

import numpy as np
import pytest

import normalfit

RNG = np.random.default_rng(7)


def heights(shape: tuple[int, int] = (12, 17), dtype: type = np.uint16) -> np.ndarray:
    return RNG.integers(0, 65536, shape).astype(dtype) if dtype in (np.uint8, np.uint16) else RNG.random(shape).astype(dtype)


# --- layouts: any strides give the same result as the C-contiguous copy ---


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64], ids=lambda t: t.__name__)
def test_every_layout_gives_the_same_normals(dtype: type) -> None:
    base = heights((40, 50), dtype)
    layouts = {
        "fortran": np.asfortranarray(base[:12, :17]),
        "steps": base[::3, ::2][:12, :17],
        "reversed": base[::-1, ::-1][:12, :17],
        "transposed": base[:17, :12].T,
        "readonly": base[:12, :17].copy(),
    }
    layouts["readonly"].flags.writeable = False
    for name, view in layouts.items():
        want = normalfit.normals(np.ascontiguousarray(view), patch=5, scale=3.0)
        got = normalfit.normals(view, patch=5, scale=3.0)
        assert np.array_equal(got, want), name


def test_unaligned_array_is_copied_not_misread() -> None:
    want = heights((6, 7), np.uint16)
    raw = bytearray(1 + want.nbytes)
    raw[1:] = want.tobytes()
    unaligned = np.frombuffer(raw, dtype=np.uint16, offset=1).reshape(6, 7)
    assert not unaligned.flags.aligned
    assert np.array_equal(normalfit.normals(unaligned), normalfit.normals(want))


def test_input_is_not_changed() -> None:
    h = heights()
    before = h.copy()
    normalfit.normals(h, dtype=np.uint8)
    assert np.array_equal(h, before)


@pytest.mark.parametrize("dt", [np.float32, np.uint8, np.uint16, "float32", "u2", np.dtype("uint8")])
def test_dtype_spellings(dt: object) -> None:
    got = normalfit.normals(heights(), dtype=dt)
    assert got.dtype == np.dtype(dt) and got.shape == (12, 17, 3)


# --- out= ---


@pytest.mark.parametrize("dt", [np.float32, np.uint8, np.uint16])
def test_out_is_written_and_returned(dt: type) -> None:
    h = heights()
    out = np.zeros((12, 17, 3), dt)
    got = normalfit.normals(h, dtype=dt, out=out)
    assert got is out
    assert np.array_equal(out, normalfit.normals(h, dtype=dt))


def test_out_with_residual() -> None:
    h = heights()
    out = np.zeros((12, 17, 3), np.float32)
    normals, residual = normalfit.normals(h, out=out, residual=True)
    assert normals is out and residual.shape == (12, 17)


def test_out_refusals() -> None:
    h = heights()
    with pytest.raises(TypeError, match="out must have dtype"):
        normalfit.normals(h, out=np.zeros((12, 17, 3), np.float64))
    with pytest.raises(TypeError, match="out must have dtype"):
        normalfit.normals(h, dtype=np.uint8, out=np.zeros((12, 17, 3), np.uint16))
    with pytest.raises(ValueError, match=r"out must have shape \(12, 17, 3\)"):
        normalfit.normals(h, out=np.zeros((17, 12, 3), np.float32))
    with pytest.raises(ValueError, match="C-contiguous"):
        normalfit.normals(h, out=np.zeros((12, 17, 6), np.float32)[:, :, ::2])
    with pytest.raises(TypeError, match="3-D"):
        normalfit.normals(h, out=np.zeros((12, 51), np.float32))
    with pytest.raises(TypeError, match="NumPy array"):
        normalfit.normals(h, out=[[0.0]])
    readonly = np.zeros((12, 17, 3), np.float32)
    readonly.flags.writeable = False
    # Said as it is, not as memory shared with the heights (issue 32).
    with pytest.raises(ValueError, match=r"^out= is read-only: give a writeable array, or none for a new one$"):
        normalfit.normals(h, out=readonly)
    with pytest.raises(ValueError, match="out= is read-only"):
        normalfit.normals(h, out=np.frombuffer(bytes(12 * 17 * 3 * 4), np.float32).reshape(12, 17, 3))
    # out as a view of the heights' own memory.
    shared = np.zeros((12, 17, 3), np.float32)
    with pytest.raises(ValueError, match="share memory"):
        normalfit.normals(shared[:, :, 0], out=shared)


# --- exceptions: options are ValueError with the library's line ---


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"patch": 4}, "invalid option: patch size must be odd and at least 3, got 4"),
        ({"patch": 1}, "invalid option: patch size must be odd and at least 3, got 1"),
        ({"patch": -3}, "invalid option: patch size must be odd and at least 3, got -3"),
        ({"patch": 1025}, "invalid option: patch size must be at most 1023, got 1025"),
        ({"patch": 10**40}, "invalid option: patch is out of range"),
        ({"fit": "cubic"}, "invalid option: unknown fit 'cubic': use orthogonal or vertical"),
        ({"border": "tile"}, "invalid option: unknown border mode 'tile'"),
        ({"border": ("wrap", "tile")}, "invalid option: unknown border mode 'tile'"),
        ({"convention": "up"}, "invalid option: unknown convention 'up'"),
        ({"scale": float("nan")}, "invalid option: scale must be a finite number"),
        ({"scale": 1e31}, "invalid option: scale must be a finite number of magnitude at most 1e30"),
        ({"relief": float("inf")}, "invalid option: relief must be a finite number"),
        ({"scale": 2.0, "relief": 0.1}, "invalid option: give scale or relief, not both"),
        ({"dtype": np.int32}, "invalid option: dtype must be float32, uint8 or uint16"),
        ({"dtype": "no such type"}, "invalid option: dtype must be float32, uint8 or uint16"),
        ({"threads": 0}, "invalid option: threads must be from 1 to 1024, got 0"),
        ({"threads": -2}, "invalid option: threads must be from 1 to 1024, got -2"),
        ({"threads": 100000}, "invalid option: threads must be from 1 to 1024, got 100000"),
    ],
)
def test_bad_option_is_a_value_error(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError) as caught:
        normalfit.normals(heights(), **kwargs)  # type: ignore[arg-type]
    assert str(caught.value).startswith(message), str(caught.value)
    assert "\n" not in str(caught.value)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"patch": 3.0}, "patch must be an int"),
        ({"patch": "3"}, "patch must be an int"),
        ({"threads": 2.5}, "threads must be an int"),
        ({"border": ("wrap",)}, "border must be a mode name or an (x, y) pair"),
        ({"border": 3}, "border must be a mode name or an (x, y) pair"),
    ],
)
def test_option_of_the_wrong_type_is_a_type_error(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(TypeError) as caught:
        normalfit.normals(heights(), **kwargs)  # type: ignore[arg-type]
    assert message in str(caught.value)


@pytest.mark.parametrize(
    ("array", "message"),
    [
        ([[0.1, 0.2], [0.3, 0.4]], "heights must be a NumPy array, got list"),
        (np.zeros(5, np.float32), "heights must be a 2-D array, got 1-D"),
        (np.zeros((2, 2, 1), np.float32), "heights must be a 2-D array, got 3-D"),
        (np.zeros((3, 3), np.int32), "heights must be uint8, uint16, float32 or float64"),
        (np.zeros((3, 3), np.complex64), "heights must be uint8, uint16, float32 or float64"),
        (np.zeros((3, 3), ">u2"), "(native byte order)"),
        (np.zeros((3, 3), bool), "heights must be uint8"),
    ],
)
def test_wrong_array_is_a_type_error(array: object, message: str) -> None:
    with pytest.raises(TypeError) as caught:
        normalfit.normals(array)
    assert message in str(caught.value)


@pytest.mark.parametrize("shape", [(0, 0), (0, 5), (5, 0)])
def test_empty_images_are_refused(shape: tuple[int, int]) -> None:
    """Every call that takes an array refuses one without texels, as the
    command line refuses an image of zero size: a ValueError, never a
    result (check_tiling called it seamless)."""
    message = rf"^invalid option: image is {shape[1]}×{shape[0]}: both sides must be at least 1$"
    for border in ("wrap", "auto"):
        with pytest.raises(ValueError, match=message):
            normalfit.normals(np.zeros(shape, np.float32), border=border)
    with pytest.raises(ValueError, match=message):
        normalfit.height(np.zeros((*shape, 3), np.float32))
    for image in (np.zeros(shape, np.uint16), np.zeros((*shape, 3), np.float32)):
        with pytest.raises(ValueError, match=message):
            normalfit.check_tiling(image)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_non_finite_height_names_the_texel(bad: float, dtype: type) -> None:
    h = np.zeros((4, 6), dtype)
    h[2, 5] = bad
    h[3, 0] = bad
    with pytest.raises(ValueError, match=r"^height at texel \(x 5, y 2\) is NaN or infinite$"):
        normalfit.normals(h)
    with pytest.raises(ValueError, match=r"\(x 5, y 2\)"):
        normalfit.normals(np.asfortranarray(h), residual=True)


def test_huge_sizes_raise_instead_of_aborting() -> None:
    # 10^6 x 10^6 texels that take one byte (stride 0): the output cannot be made.
    huge = np.lib.stride_tricks.as_strided(np.zeros(1, np.uint8), shape=(10**6, 10**6), strides=(0, 0))
    with pytest.raises(MemoryError):
        normalfit.normals(huge, dtype=np.uint8)
    # Every output dtype.
    for dt in (np.float32, np.uint16):
        with pytest.raises(MemoryError):
            normalfit.normals(huge, dtype=dt, residual=True)


def test_results_are_the_same_whatever_the_threads() -> None:
    h = heights((300, 257), np.float32)
    want = normalfit.normals(h, patch=7)
    for threads in (1, 2, 3, 2):
        assert np.array_equal(normalfit.normals(h, patch=7, threads=threads), want)


def test_help_shows_the_docstrings() -> None:
    assert "convention" in (normalfit.normals.__doc__ or "")
    assert "threshold" in (normalfit.check_tiling.__doc__ or "")
    assert normalfit.AxisReport.__doc__ and normalfit.TilingReport.__doc__


def test_version_is_the_crates() -> None:
    """The package's version is its crate's (maturin's dynamic version),
    which follows the library's."""
    import re

    from conftest import ROOT

    def version(manifest: str) -> str:
        found = re.search(r'^version = "([^"]+)"', (ROOT / manifest).read_text(), re.M)
        assert found, manifest
        return found.group(1)

    assert normalfit.__version__ == version("normalfit-py/Cargo.toml") == version("Cargo.toml")
