#!/usr/bin/env python3
"""Python's normals call against the NumPy recipe and the Rust core, turn about, in one run.

usage: python bench/python_call.py [--size N] [--rounds K] [--core PATH]
       python bench/python_call.py --calls {new,out} [--size N] [--rounds K]

Issue 36, points 3 and 1: `normalfit.normals(h)` (a new float32 array)
against the NumPy recipe below, both from the same 4096² uint16 heights;
the same call into a caller's `out=`; and the core, the Rust library's
`FitRequest::normals_into` into a kept buffer without Python (the
`core_timing` example: `cargo build --profile ci -p normalfit-py --example
core_timing`, the wheel's profile; pass its path with --core). Point 1:
`normalfit.normals(f32 heights, dtype=np.uint8, out=buf)` against the same
recipe. Besides: the allocating call on one thread (as the recipe runs),
the same call with NumPy's huge pages off, and what a new output's pages
cost alone (numpy.empty written once, against the same write into pages
already there).

Each of K rounds runs every contender once, in turn (the core in a
process of its own), each round starting one contender later, so that a
change in the shared machine's load falls on all of them; the figures
are the best of the K rounds (medians beside them).
A call is timed until it returns: its result is dropped after the clock
stops (freeing is not the call's work, for either side). Prints; asserts
nothing.

--calls runs one call K times and nothing else, for a profiler: `perf stat
-e task-clock,page-faults python bench/python_call.py --calls new` against
`--calls out` shows the kernel time a new output adds (`sys`), `perf record
-g` where it goes.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numpy._core.multiarray import _set_madvise_hugepage  # type: ignore[attr-defined]

import normalfit

HERE = Path(__file__).resolve().parent


def heights(size: int) -> np.ndarray:
    """Smooth relief plus grain, 16-bit (bench.py's input)."""
    out = np.empty((size, size), np.uint16)
    rng = np.random.default_rng(1)
    x = np.arange(size, dtype=np.float64) / size
    for top in range(0, size, 256):
        y = np.arange(top, min(top + 256, size), dtype=np.float64)[:, None] / size
        surface = 0.5 + 0.2 * np.sin(12 * x) * np.cos(9 * y) + 0.05 * rng.random((len(y), size))
        out[top : top + len(y)] = np.round(surface * 65535)
    return out


def numpy_recipe(h: np.ndarray) -> np.ndarray:
    """The recipe as a user writes it: heights in [0, 1] (NumPy's default
    float64), central differences by np.gradient, (−dx, dy, 1) stacked and
    normalised (green up), float32 out like normalfit's."""
    z = h / 65535.0
    dy, dx = np.gradient(z)
    n = np.stack([-dx, dy, np.ones_like(z)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n.astype(np.float32)


def without_huge_pages(work: Callable[[], Any]) -> Callable[[], Any]:
    """`work` with NumPy's madvise(MADV_HUGEPAGE) of new large arrays off:
    their pages are then 4 KiB ones (where transparent huge pages are
    `madvise`, as on the machine measured)."""

    def call() -> Any:
        was = _set_madvise_hugepage(False)
        try:
            return work()
        finally:
            _set_madvise_hugepage(was)

    return call


def written_once(shape: tuple[int, ...]) -> np.ndarray:
    """A new float32 array written once: the kernel clears each page at
    its first touch."""
    a = np.empty(shape, np.float32)
    a.fill(0)
    return a


def timed(work: Callable[[], Any]) -> float:
    """Seconds until `work` returns; its result is dropped after."""
    start = time.perf_counter()
    result = work()
    seconds = time.perf_counter() - start
    del result
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=4096)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--core", type=Path, default=HERE.parents[1] / "target" / "ci" / "examples" / "core_timing")
    parser.add_argument("--calls", choices=["new", "out"], help="only this call, K times (for perf)")
    args = parser.parse_args()
    if args.calls is not None:
        h = heights(args.size)
        out = np.empty((args.size, args.size, 3), np.float32)
        normalfit.normals(h, out=out)
        for _ in range(args.rounds):
            timed((lambda: normalfit.normals(h)) if args.calls == "new" else (lambda: normalfit.normals(h, out=out)))
        return
    if not args.core.exists():
        sys.exit(f"no {args.core}: cargo build --profile ci -p normalfit-py --example core_timing (or --core PATH)")
    size = args.size
    h = heights(size)
    h32 = (h / np.float32(65535)).astype(np.float32)
    out32 = np.empty((size, size, 3), np.float32)
    out8 = np.empty((size, size, 3), np.uint8)
    # The kept outputs' pages are touched once before any round.
    normalfit.normals(h, out=out32)
    normalfit.normals(h32, dtype=np.uint8, out=out8)

    contenders: dict[str, Callable[[], Any]] = {
        "NumPy recipe (float64 gradient, normalised, float32 out)": lambda: numpy_recipe(h),
        "normalfit.normals(h) (new float32 array)": lambda: normalfit.normals(h),
        "normalfit.normals(h, out=buf)": lambda: normalfit.normals(h, out=out32),
        "normalfit.normals(h32, dtype=np.uint8, out=buf)": lambda: normalfit.normals(h32, dtype=np.uint8, out=out8),
        # One thread, as the recipe runs: a core against a core.
        "normalfit.normals(h, threads=1) (new float32 array)": lambda: normalfit.normals(h, threads=1),
        "normalfit.normals(h), NumPy's huge pages off": without_huge_pages(lambda: normalfit.normals(h)),
        # What a new array's pages cost alone: numpy.empty written once,
        # against the same write into pages already there (neither freed
        # while the clock runs).
        "np.empty((H, W, 3), float32).fill(0)": lambda: written_once((size, size, 3)),
        "buf.fill(0) (pages already there)": lambda: out32.fill(0),
    }
    times: dict[str, list[float]] = {name: [] for name in contenders}
    core_times: list[float] = []
    items = list(contenders.items())
    with tempfile.NamedTemporaryFile(suffix=".u16") as raw:
        raw.write(h.tobytes())
        raw.flush()
        for k in range(args.rounds):
            # Each round starts one contender later: what a call follows
            # matters (memory just freed is cheaper to take again than
            # pages the system took back), so no call always follows
            # the recipe's frees.
            for name, work in items[k % len(items) :] + items[: k % len(items)]:
                times[name].append(timed(work))
            # One repetition a round, as every other contender has (its
            # buffer written once before, as out= is).
            line = subprocess.run(
                [str(args.core), raw.name, str(size), str(size), "1"], capture_output=True, text=True, check=True
            ).stdout.split()
            core_times.append(float(line[3]))
    core_name = "core: FitRequest::normals_into, kept buffer (Rust, no Python)"
    times[core_name] = core_times
    best = {name: min(t) for name, t in times.items()}
    median = {name: statistics.median(t) for name, t in times.items()}
    core = best[core_name]

    names = list(contenders)
    recipe, fresh, into, u8, one = (best[n] for n in names[:5])
    print(f"{size}² uint16 heights → float32 normals (patch 3, defaults); best of {args.rounds} rounds, turn about; "
          f"normalfit {normalfit.__version__}, NumPy {np.__version__}")

    def row(name: str, seconds: float, note: str = "") -> None:
        mid = f"(median {median[name] * 1000:6.1f})" if name in median else " " * 15
        print(f"  {name:<58} {seconds * 1000:8.1f} ms {mid}  {note}")

    row(names[0], recipe)
    row(names[1], fresh, f"recipe ÷ this: {recipe / fresh:.1f}× (asked ≥ 10×; of the medians "
        f"{median[names[0]] / median[names[1]]:.1f}×); this ÷ core: {fresh / core:.2f}×")
    row(names[2], into, f"recipe ÷ this: {recipe / into:.1f}×; this ÷ core: {into / core:.3f}× (asked ≤ 1.1×; "
        f"of the medians {median[names[2]] / median[core_name]:.3f}×)")
    row(core_name, core)
    row(names[3], u8, f"recipe ÷ this: {recipe / u8:.1f}× (asked ≥ 20×)")
    row(names[4], one, f"recipe ÷ this: {recipe / one:.1f}× (one thread each)")
    row(names[5], best[names[5]], f"this ÷ the same call with them: {best[names[5]] / fresh:.2f}×")
    row(names[6], best[names[6]], f"a new output's first touch: {(best[names[6]] - best[names[7]]) * 1000:.1f} ms")
    row(names[7], best[names[7]])


if __name__ == "__main__":
    main()
