"""normals(..., dtype=uint16/uint8) equals, bit for bit, what the command
line writes: on every case of the contract check, every sample, and every
border pair for 8-bit, 16-bit and float inputs."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

import normalfit
from conftest import CONFORMANCE, ROOT, read_png, run_cli, write_float_tiff, write_png

LUMA = (0.2126, 0.7152, 0.0722)


def heights_from(image: np.ndarray, channel: str | None) -> np.ndarray:
    """The heights the command line takes from a PNG's pixels (SPEC section
    1): gray as stored; a colour channel as stored (a strided view: the
    copy path); luma of the contract's units in f64, in the CLI's order."""
    if image.ndim == 2:
        return image
    if channel in ("r", "g", "b"):
        return image[:, :, "rgb".index(channel)]
    unit = 1.0 / (255.0 if image.dtype == np.uint8 else 65535.0)
    r, g, b = (image[:, :, k].astype(np.float64) * unit for k in range(3))
    return LUMA[0] * r + LUMA[1] * g + LUMA[2] * b


def kwargs_from(args: list[str]) -> tuple[dict[str, object], str | None]:
    """The keyword arguments for the command line's options."""
    kw: dict[str, object] = {}
    channel = None
    it = iter(args)
    for arg in it:
        name = arg.lstrip("-")
        if name == "invert":
            kw["invert"] = True
        elif name == "channel":
            channel = next(it)
        elif name == "patch":
            kw["patch"] = int(next(it))
        elif name in ("scale", "relief"):
            kw[name] = float(next(it))
        else:
            kw[name] = next(it)
    return kw, channel


def cases() -> list[dict[str, object]]:
    path = CONFORMANCE / "cases.json"
    if not path.exists():
        return []
    return list(json.loads(path.read_text()))


@pytest.mark.skipif(not CONFORMANCE.is_dir(), reason=f"{CONFORMANCE} is absent (the contract's cases live beside the clone)")
@pytest.mark.parametrize("case", cases(), ids=lambda c: str(c["id"]))
def test_conformance_case_matches_the_cli(case: dict[str, object], cli: Path, tmp_path: Path) -> None:
    args = list(case["args"])  # type: ignore[call-overload]
    source = CONFORMANCE / str(case["input"])
    out = tmp_path / "out.png"
    run_cli(cli, "convert", source, "-o", out, "--bits", "16", *args)
    kw, channel = kwargs_from(args)
    heights = heights_from(read_png(source), channel)
    got = normalfit.normals(heights, dtype=np.uint16, **kw)  # type: ignore[arg-type]
    assert np.array_equal(got, read_png(out)), f"case {case['id']} ({case['what']})"


@pytest.mark.parametrize("name", ["bricks", "rock", "terrain"])
def test_sample_matches_the_cli(name: str, cli: Path, tmp_path: Path) -> None:
    source = ROOT / "samples" / f"{name}.png"
    heights = read_png(source)
    assert heights.dtype == np.uint16 and heights.ndim == 2
    for bits, dt, extra in [(16, np.uint16, []), (8, np.uint8, ["--patch", "7", "--scale", "6"])]:
        out = tmp_path / f"{bits}.png"
        run_cli(cli, "convert", source, "-o", out, "--bits", bits, *extra)
        kw, _ = kwargs_from(extra)
        got = normalfit.normals(heights, dtype=dt, **kw)  # type: ignore[arg-type]
        assert np.array_equal(got, read_png(out)), f"{name}, {bits}-bit"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, np.ndarray]]:
    """One 23 x 37 surface as an 8-bit PNG, a 16-bit PNG and a float TIFF."""
    folder = tmp_path_factory.mktemp("inputs")
    y, x = np.mgrid[0:23, 0:37]
    surface = 0.5 + 0.3 * np.sin(x / 3.0) * np.cos(y / 5.0) + 0.05 * np.random.default_rng(3).random((23, 37))
    made = {}
    for name, array in [
        ("u8", np.round(surface * 255).astype(np.uint8)),
        ("u16", np.round(surface * 65535).astype(np.uint16)),
    ]:
        write_png(folder / f"{name}.png", array)
        made[name] = (folder / f"{name}.png", array)
    floats = (surface * 7.0 - 2.0).astype(np.float32)  # outside [0, 1]: stored as is
    write_float_tiff(folder / "f32.tif", floats)
    made["f32"] = (folder / "f32.tif", floats)
    return made


@pytest.mark.parametrize("border", list(itertools.product(["wrap", "clamp", "mirror"], repeat=2)), ids="-".join)
@pytest.mark.parametrize("kind", ["u8", "u16", "f32"])
def test_every_border_pair_matches_the_cli(
    border: tuple[str, str], kind: str, inputs: dict[str, tuple[Path, np.ndarray]], cli: Path, tmp_path: Path
) -> None:
    source, heights = inputs[kind]
    out = tmp_path / "out.png"
    run_cli(cli, "convert", source, "-o", out, "--bits", "16", "--border", ",".join(border), "--patch", "5", "--scale", "3")
    got = normalfit.normals(heights, border=border, patch=5, scale=3.0, dtype=np.uint16)
    assert np.array_equal(got, read_png(out))
