"""The type stubs agree with the module (stubtest) and type user code (mypy)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mypy", reason="mypy is not installed (pip install mypy)")

HERE = Path(__file__).resolve().parent


def run(*args: str) -> subprocess.CompletedProcess[str]:
    # The timeout only stops a hang: mypy --strict took over 600 s on a
    # machine loaded with four builds (issue 37), so the bound is generous.
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, cwd=HERE.parent, timeout=1800)


def test_stubtest_finds_the_stubs_and_the_module_agree() -> None:
    result = run("mypy.stubtest", "normalfit")
    assert result.returncode == 0, result.stdout + result.stderr


def test_typed_usage_checks_strictly() -> None:
    result = run("mypy", "--strict", "--no-incremental", "--cache-dir", "/dev/null", str(HERE / "typed_usage.py"))
    assert result.returncode == 0, result.stdout + result.stderr


def test_a_wrong_call_is_caught(tmp_path: Path) -> None:
    """The stubs do constrain: a misspelt option is a type error."""
    bad = tmp_path / "wrong_usage.py"
    bad.write_text('import numpy as np\nimport normalfit\nnormalfit.normals(np.zeros((2, 2)), fit="cubic")\n')
    result = run("mypy", "--no-incremental", "--cache-dir", str(tmp_path / "cache"), str(bad))
    assert result.returncode == 1 and "fit" in result.stdout, result.stdout
