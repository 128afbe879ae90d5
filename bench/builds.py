#!/usr/bin/env python3
"""Builds of normalfit against each other: the same conversion by each
binary, turn about, in one run, so that a change is judged against the
build before it under the same load (these machines are shared and noisy;
figures of different days do not compare).

usage: bench/builds.py INPUT REPS NAME=BINARY [NAME=BINARY ...] [-- OPTIONS]

Each repetition runs every binary once, in the order given, as
`BINARY convert INPUT OPTIONS -o builds_NAME.png` (OPTIONS default to
`--relief 0.03 --bits 8`, the comparison's settings in bench/compare.sh),
with the output removed first. Prints per build the median and least wall
time and the median processor time (user + system, from the children's
rusage), and whether the last build wrote the same bytes as each other. Asserts nothing.

Older builds come from a worktree, e.g.
  git worktree add /tmp/old 09f110c && (cd /tmp/old && cargo build --release)
  bench/builds.py h4096.png 20 old=/tmp/old/target/release/normalfit new=target/release/normalfit
"""

from __future__ import annotations

import filecmp
import os
import resource
import statistics
import subprocess
import sys
import time


def main() -> None:
    args = sys.argv[1:]
    options = ["--relief", "0.03", "--bits", "8"]
    if "--" in args:
        split = args.index("--")
        args, options = args[:split], args[split + 1 :]
    if len(args) < 3 or not all("=" in a for a in args[2:]):
        sys.exit(__doc__.split("\n\n")[1])
    source, reps = args[0], int(args[1])
    builds = dict(a.split("=", 1) for a in args[2:])
    wall: dict[str, list[float]] = {name: [] for name in builds}
    cpu: dict[str, list[float]] = {name: [] for name in builds}
    for _ in range(reps):
        for name, binary in builds.items():
            out = f"builds_{name}.png"
            if os.path.exists(out):
                os.remove(out)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            subprocess.run([binary, "convert", source, *options, "-o", out], check=True)
            wall[name].append(time.perf_counter() - start)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu[name].append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    print(f"{source}, {reps} turns, options {' '.join(options)}")
    for name in builds:
        print(
            f"  {name:10s} wall median {statistics.median(wall[name]):.4f} s, least {min(wall[name]):.4f} s; "
            f"processor median {statistics.median(cpu[name]):.3f} s"
        )
    names = list(builds)
    last = names[-1]
    for name in names[:-1]:
        same = filecmp.cmp(f"builds_{name}.png", f"builds_{last}.png", shallow=False)
        print(f"  {last} wrote {'the same bytes as' if same else 'other bytes than'} {name}")
    for name in names:
        os.remove(f"builds_{name}.png")


if __name__ == "__main__":
    main()
