#!/usr/bin/env python3
"""4096² uint16 heights to float32 normals: normalfit from Python, the Rust
core on the same input, and the usual NumPy recipe, in one run.

usage: python bench/bench.py [--size N] [--reps R] [--core PATH]

--core is the `core_timing` example (cargo build --release -p normalfit-py
--example core_timing); by default target/release/examples/core_timing.
Prints medians of R repetitions (the machine may be shared and noisy) and
the ratios; asserts nothing. Peak memory is measured in a fresh process
that makes the input and calls normalfit once: its ru_maxrss against the
input's and output's size (VmHWM on Linux: see high_water_bytes).
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

import normalfit

ROOT = Path(__file__).resolve().parents[2]


def heights(size: int) -> np.ndarray:
    """Smooth relief plus grain, 16-bit: the same array in every process,
    made 256 rows at a time so that making it leaves no large peak in the
    memory figure."""
    out = np.empty((size, size), np.uint16)
    rng = np.random.default_rng(1)
    x = np.arange(size, dtype=np.float64) / size
    for top in range(0, size, 256):
        y = np.arange(top, min(top + 256, size), dtype=np.float64)[:, None] / size
        surface = 0.5 + 0.2 * np.sin(12 * x) * np.cos(9 * y) + 0.05 * rng.random((len(y), size))
        out[top : top + len(y)] = np.round(surface * 65535)
    return out


def numpy_recipe(h: np.ndarray, dtype: type = np.float64) -> np.ndarray:
    """The usual recipe: heights as floats (float64 is NumPy's default;
    float32 gives NumPy its best), central differences by np.gradient,
    (−dx, dy, 1) normalised (green up)."""
    z = h.astype(dtype) / dtype(65535)
    dy, dx = np.gradient(z)
    n = np.stack([-dx, dy, np.ones_like(z)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n


def median_seconds(work, reps: int) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(reps):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def status_bytes(field: str) -> int | None:
    """A memory figure of /proc/self/status (Linux), in bytes."""
    status = Path("/proc/self/status")
    if status.exists():
        for line in status.read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return None


def high_water_bytes() -> int:
    """The process's peak resident memory: VmHWM on Linux, which starts
    anew at exec; ru_maxrss elsewhere (Linux keeps the parent's peak in a
    child's ru_maxrss across fork and exec, so it would show the parent's)."""
    peak = status_bytes("VmHWM")
    return peak if peak is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def peak_memory(size: int) -> None:
    """Run in a child: resident memory before one call (VmRSS, the input
    held; the peak so far includes making it) and the peak after."""
    h = heights(size)
    before = status_bytes("VmRSS") or high_water_bytes()
    n = normalfit.normals(h)
    after = high_water_bytes()
    print(before, after, h.nbytes, n.nbytes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=4096)
    parser.add_argument("--reps", type=int, default=7)
    parser.add_argument("--core", type=Path, default=ROOT / "target" / "release" / "examples" / "core_timing")
    parser.add_argument("--peak-memory-child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.peak_memory_child:
        peak_memory(args.size)
        return

    size, reps = args.size, args.reps
    h = heights(size)
    print(f"{size}² uint16 → float32 normals (patch 3, defaults), medians of {reps}; normalfit {normalfit.__version__}")

    out = np.empty((size, size, 3), np.float32)
    if not args.core.exists():
        sys.exit(f"no {args.core}: cargo build --release -p normalfit-py --example core_timing")
    # Python and the core take turns, three rounds of `reps`, so that a
    # change in the machine's load falls on both; medians over all rounds.
    times: dict[str, list[float]] = {"fresh": [], "out": [], "core fresh": [], "core kept": []}
    with tempfile.NamedTemporaryFile(suffix=".u16") as raw:
        raw.write(h.tobytes())
        raw.flush()
        for _ in range(3):
            times["fresh"].append(median_seconds(lambda: normalfit.normals(h), reps))
            times["out"].append(median_seconds(lambda: normalfit.normals(h, out=out), reps))
            line = subprocess.run(
                [str(args.core), raw.name, str(size), str(size), str(reps)], capture_output=True, text=True, check=True
            ).stdout.split()
            times["core fresh"].append(float(line[0]))
            times["core kept"].append(float(line[1]))
    python_fresh, python_out, core_fresh, core_kept = (statistics.median(times[k]) for k in times)
    one_thread = median_seconds(lambda: normalfit.normals(h, threads=1), max(3, reps // 2))
    def two_at_once() -> None:
        # Two Python threads, one call each: the GIL is released in a call,
        # so with two cores free they take about one call's time.
        pair = [threading.Thread(target=lambda: normalfit.normals(h, threads=1)) for _ in range(2)]
        for t in pair:
            t.start()
        for t in pair:
            t.join()

    two_threads = median_seconds(two_at_once, max(3, reps // 2))
    recipe64 = median_seconds(lambda: numpy_recipe(h, np.float64), max(3, reps // 2))
    recipe32 = median_seconds(lambda: numpy_recipe(h, np.float32), max(3, reps // 2))

    def row(name: str, seconds: float, note: str = "") -> None:
        print(f"  {name:<44} {seconds * 1000:9.1f} ms  {size * size / seconds / 1e6:7.1f} Mtexel/s  {note}")

    row("normalfit.normals(h, out=out) (Python)", python_out, f"{python_out / core_kept:.3f}× the core's time")
    row("Rust core FitRequest::normals_into() (kept output)", core_kept)
    row("normalfit.normals(h) (Python, new output)", python_fresh, f"{python_fresh / core_fresh:.3f}× the core's time")
    row("Rust core normals() (new, zeroed output)", core_fresh)
    row("normalfit.normals(h, threads=1)", one_thread, "(NumPy runs on one thread)")
    row("two threads=1 calls at once (two Python threads)", two_threads / 2,
        f"per call; {two_threads / one_thread:.2f}× one call's wall time")
    row("NumPy recipe, float64 (np.gradient + norm)", recipe64,
        f"normalfit is {recipe64 / python_fresh:.1f}× faster ({recipe64 / one_thread:.1f}× on one thread)")
    row("NumPy recipe, float32", recipe32,
        f"normalfit is {recipe32 / python_fresh:.1f}× faster ({recipe32 / one_thread:.1f}× on one thread)")

    child = subprocess.run(
        [sys.executable, __file__, "--peak-memory-child", "--size", str(size)], capture_output=True, text=True, check=True
    )
    before, after, in_bytes, out_bytes = map(int, child.stdout.split())
    mib = 1 << 20
    print(
        f"  memory of one call: resident {before / mib:.0f} MiB before (Python, NumPy, the input), peak {after / mib:.0f} MiB "
        f"(+{(after - before) / mib:.0f} MiB); "
        f"input {in_bytes / mib:.0f} MiB, output {out_bytes / mib:.0f} MiB, "
        f"so {(after - before - out_bytes) / mib:.1f} MiB beyond the output"
    )


if __name__ == "__main__":
    main()
