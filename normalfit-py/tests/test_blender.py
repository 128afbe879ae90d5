"""A real host: Blender makes normal maps through the package
(examples/blender/normal_map.py, headless) and saves them with its own PNG
writer; the pixels must be the command line's, bit for bit.

Runs where Blender is installed (Debian: ``apt-get install blender
python3-numpy``; CI installs both) and is skipped, with that reason,
where it is not.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import normalfit
from conftest import ROOT, read_png, run_cli

SCRIPT = ROOT / "examples" / "blender" / "normal_map.py"
BLENDER = shutil.which("blender")

pytestmark = pytest.mark.skipif(BLENDER is None, reason="Blender is not installed (apt-get install blender python3-numpy)")


@pytest.fixture(scope="module")
def package_only(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding only the installed normalfit package, for Blender's
    own Python (its NumPy stays Blender's)."""
    folder = tmp_path_factory.mktemp("blender-path")
    (folder / "normalfit").symlink_to(Path(normalfit.__file__).parent, target_is_directory=True)
    return folder


def blender(package_only: Path, *args: object) -> subprocess.CompletedProcess[str]:
    assert BLENDER is not None
    env = {**os.environ, "PYTHONPATH": str(package_only)}
    command = [BLENDER, "-b", "--factory-startup", "--python-use-system-env", "--python", str(SCRIPT), "--"]
    return subprocess.run([*command, *map(str, args)], capture_output=True, text=True, timeout=600, env=env)


CASES = [
    # sample, bits, options as the script and the CLI spell them
    ("rock.png", 8, ["--patch", "5", "--scale", "4"]),
    ("terrain.png", 16, ["--scale", "8", "--border", "clamp"]),
    ("bricks.png", 16, ["--patch", "7", "--border", "auto", "--convention", "directx", "--fit", "vertical"]),
]


@pytest.mark.parametrize(("sample", "bits", "options"), CASES, ids=[c[0] for c in CASES])
def test_blender_saves_the_clis_pixels(
    sample: str, bits: int, options: list[str], package_only: Path, cli: Path, tmp_path: Path
) -> None:
    source = ROOT / "samples" / sample
    made = tmp_path / "blender.png"
    result = blender(package_only, source, made, "--bits", bits, *options)
    assert result.returncode == 0, f"blender exit {result.returncode}:\n{result.stdout[-2000:]}\n{result.stderr[-2000:]}"
    expected = tmp_path / "cli.png"
    cli_options = [("-s" if o == "--scale" else o) for o in options]
    run_cli(cli, "convert", source, "-o", expected, "--bits", bits, "--quiet", *cli_options)
    got, want = read_png(made), read_png(expected)
    assert got.dtype == want.dtype == (np.uint16 if bits == 16 else np.uint8)
    assert got.shape == want.shape
    differ = np.count_nonzero(np.any(got != want, axis=-1))
    assert differ == 0, f"{differ} of {got.shape[0] * got.shape[1]} texels differ from the CLI's"


def test_a_missing_file_is_one_line_and_exit_2(package_only: Path, tmp_path: Path) -> None:
    result = blender(package_only, tmp_path / "absent.png", tmp_path / "out.png")
    assert result.returncode == 2, result.stdout[-2000:]
    assert "absent.png" in result.stderr
    assert not (tmp_path / "out.png").exists()
