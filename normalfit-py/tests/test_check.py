"""normalfit.check_map and `normalfit check`: the report's keys, the
convention guessed from the curl of maps made by normals() in both
conventions, the findings, the repair, and the command line's exit codes."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import normalfit

from conftest import cli_binary, read_png, write_png


def waves(rows: int = 96, cols: int = 128) -> np.ndarray:
    y, x = np.mgrid[0:rows, 0:cols]
    return 0.5 + 0.3 * np.sin(2 * np.pi * (2 * x / cols + y / rows)) + 0.2 * np.cos(2 * np.pi * 3 * y / rows)


def encoded(heights: np.ndarray, convention: str) -> np.ndarray:
    return normalfit.normals(heights, scale=8.0, convention=convention, dtype=np.uint16)  # type: ignore[no-any-return]


@pytest.mark.parametrize("convention", ["opengl", "directx"])
def test_check_map_guesses_the_convention(tmp_path: Path, convention: str) -> None:
    path = tmp_path / "map.png"
    write_png(path, encoded(waves(), convention))
    report = normalfit.check_map(path)
    assert report["convention"] == convention and report["confident"] is True
    assert report["clean"] is True and report["findings"] == []
    assert report["layout"] == "rgb" and report["storage"] == "16-bit"
    assert report["length"]["off"] == 0 and report["negative_z"]["count"] == 0
    assert report["banding"] is None and report["tiling"]["seamless"] is True
    other = "directx" if convention == "opengl" else "opengl"
    assert normalfit.check_map(path, convention=other)["findings"] == ["convention"]


def test_check_map_fix_flips_and_renormalises(tmp_path: Path) -> None:
    gl, dx = encoded(waves(), "opengl"), encoded(waves(), "directx")
    write_png(tmp_path / "dx.png", dx)
    report = normalfit.check_map(tmp_path / "dx.png", fix=tmp_path / "gl.png", to="opengl")
    assert report["convention"] == "directx"
    assert np.abs(read_png(tmp_path / "gl.png").astype(np.int64) - gl.astype(np.int64)).max() <= 1
    rg = gl.copy()
    rg[..., 2] = 0
    write_png(tmp_path / "rg.png", rg)
    report = normalfit.check_map(tmp_path / "rg.png", fix=tmp_path / "rgb.png")
    assert report["layout"] == "rg" and report["findings"] == ["rg"]
    assert np.abs(read_png(tmp_path / "rgb.png").astype(np.int64) - gl.astype(np.int64)).max() <= 2
    assert normalfit.check_map(tmp_path / "rgb.png")["clean"] is True
    with pytest.raises(ValueError, match="needs fix"):
        normalfit.check_map(tmp_path / "rg.png", to="opengl")
    with pytest.raises(OSError, match="missing.png"):
        normalfit.check_map(tmp_path / "missing.png")


def test_check_command_exit_codes_and_json(tmp_path: Path) -> None:
    binary = cli_binary()
    if binary is None:
        pytest.skip("no normalfit binary: cargo build --release first (or set NORMALFIT_BIN)")
    write_png(tmp_path / "good.png", encoded(waves(), "directx"))
    bad = encoded(waves(), "opengl").astype(np.float64)
    bad[::7, :, :2] = 32768  # flattened x, y with z kept: not unit
    write_png(tmp_path / "bad.png", bad.astype(np.uint16))
    good = subprocess.run([str(binary), "check", str(tmp_path / "good.png"), "--json"], capture_output=True, text=True)
    assert good.returncode == 0, good.stderr
    line = json.loads(good.stdout)
    assert line["convention"] == "directx" and line["confident"] is True and line["clean"] is True
    found = subprocess.run([str(binary), "check", str(tmp_path / "bad.png"), "--json"], capture_output=True, text=True)
    assert found.returncode == 1, found.stderr
    assert "length" in json.loads(found.stdout)["findings"]
    (tmp_path / "broken.png").write_bytes(b"not a png")
    broken = subprocess.run([str(binary), "check", str(tmp_path / "broken.png")], capture_output=True, text=True)
    assert broken.returncode == 2 and broken.stderr.count("\n") == 1 and "broken.png" in broken.stderr
