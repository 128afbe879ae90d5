"""One memory rule for every path (issue 32): under a 1 GiB address-space
limit, normals(), lit_view() and height() with a patch whose work does not
fit raise MemoryError with the library's one line, before they allocate,
and the interpreter lives on; a patch that fits runs. Each call is made in
a child interpreter under the limit (resource.setrlimit), on 2 threads."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import write_png

pytestmark = pytest.mark.skipif(
    sys.platform != "linux", reason="the memory rule reads the process's use in /proc (Linux)"
)

CHILD = """
import resource, sys
limit = 1 << 30
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
import numpy as np
import normalfit

call, path, patch = sys.argv[1], sys.argv[2], int(sys.argv[3])
try:
    if call == "normals":
        normalfit.normals(np.load(path), patch=patch)
    elif call == "normals_nodata":
        normalfit.normals(np.load(path), patch=patch, nodata=0.0, residual=True)
    elif call == "lit_view":
        normalfit.lit_view(path, patch=patch)
    elif call == "height":
        normalfit.height(np.load(path), patch=patch)
    elif call == "height_large":
        # A 6000 x 6000 map (432 MB of float32 normals), made here.
        normalfit.height(np.zeros((6000, 6000, 3), np.float32), patch=patch)
    print("ran")
except MemoryError as e:
    print("MemoryError:", e)
"""


def call_limited(call: str, path: Path, patch: int) -> str:
    """The child's one line of output: "ran", or the MemoryError's."""
    env = dict(os.environ, RAYON_NUM_THREADS="2")
    child = subprocess.run(
        [sys.executable, "-c", CHILD, call, str(path), str(patch)],
        capture_output=True, text=True, env=env, timeout=600,
    )
    # An abort would be a negative return code (SIGABRT) and
    # "memory allocation of ... failed" on standard error.
    assert child.returncode == 0, f"{call}, patch {patch}: {child.returncode}: {child.stderr}"
    assert "memory allocation" not in child.stderr, child.stderr
    lines = child.stdout.splitlines()
    assert len(lines) == 1, child.stdout
    return lines[0]


@pytest.fixture(scope="module")
def wide(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A 3 × 20000 height map (as float32 and as a 16-bit PNG), and its
    normals fitted at N = 31 and 1023 for the inverse at those N: its
    memory does not depend on the map, and on a map made at another N the
    orthogonal inverse chases what no heights give (hundreds of solves)."""
    folder = tmp_path_factory.mktemp("memory")
    x = np.arange(20000, dtype=np.float64)
    heights = (0.4 * x / 20000 + 0.1 * np.sin(0.05 * x))[None, :] + np.array([[0.0], [0.01], [0.02]])
    paths = {"heights": folder / "h.npy", "png": folder / "h.png"}
    np.save(paths["heights"], heights.astype(np.float32))
    write_png(paths["png"], np.round(heights * 65535).astype(np.uint16))
    import normalfit

    for patch in (31, 1023):
        paths[f"normals_{patch}"] = folder / f"n{patch}.npy"
        np.save(paths[f"normals_{patch}"], normalfit.normals(heights.astype(np.float32), patch=patch))
    return paths


@pytest.mark.parametrize(
    ("call", "data"),
    [("normals", "heights"), ("normals_nodata", "heights"), ("lit_view", "png")],
)
def test_a_patch_too_large_for_the_limit_is_a_memory_error(call: str, data: str, wide: dict[str, Path]) -> None:
    """Patch 1023 on 3 × 20000: the fit's sums alone (a strip of 8·N
    columns holds 2N rows of them, on each thread) are some 2 GiB."""
    line = call_limited(call, wide[data], 1023)
    assert line.startswith("MemoryError:"), line
    assert "too large: " in line and "needs about" in line, line
    assert line.endswith("(its memory limit is 1024 MiB)"), line
    if call == "lit_view":
        assert f"{wide[data]}: too large: lighting the view needs about" in line, line


@pytest.mark.parametrize(
    ("call", "data"),
    [("normals", "heights"), ("normals_nodata", "heights"), ("lit_view", "png"), ("height", "normals_31")],
)
def test_a_patch_that_fits_runs_under_the_limit(call: str, data: str, wide: dict[str, Path]) -> None:
    assert call_limited(call, wide[data], 31) == "ran"


def test_the_inverse_of_a_wide_patch_runs_under_the_limit(wide: dict[str, Path]) -> None:
    """The inverse's memory does not grow with N (its patch sums are line
    sums, and on a map this small for N its re-fit is by line sums too):
    patch 1023 on 3 × 20000 runs under the limit."""
    assert call_limited("height", wide["normals_1023"], 1023) == "ran"


def test_a_normal_map_too_large_for_the_limit_is_a_memory_error(tmp_path: Path) -> None:
    """The inverse's own planes (the slopes, the heights, the spectra, the
    orthogonal fit's ratios: some 50 bytes a texel) of a 6000 × 6000 map
    do not fit beside the map itself (432 MB): refused before they are
    allocated."""
    line = call_limited("height_large", tmp_path / "unused", 3)
    assert line.startswith("MemoryError:"), line
    assert "too large: finding the heights needs about" in line, line
    assert line.endswith("(its memory limit is 1024 MiB)"), line
