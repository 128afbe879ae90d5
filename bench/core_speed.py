#!/usr/bin/env python3
"""Runs builds of `examples/core_speed.rs` turn about and prints, per case,
each build's least wall and processor time over all its runs, and their
ratios: the compute core's figures of docs/speed.md, compared on one
machine in one run.

    bench/core_speed.py [--runs R] [--args "SIZE REPS N,N,..."] NAME=BINARY ...

Build a binary with `cargo build --release --example core_speed` (an older
build from a `git worktree`, the example copied in if it lacks it). The
first NAME is the reference of the ratio columns.
"""

import argparse
import os
import subprocess


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--args", default="4096 5 3,5,7,9,15,33,63")
    parser.add_argument("builds", nargs="+", metavar="NAME=BINARY")
    opts = parser.parse_args()
    builds = [b.split("=", 1) for b in opts.builds]
    best = {}  # (case, name) -> [wall, cpu]
    cases = []
    digests = {}  # case -> {name: digest}
    for run in range(opts.runs):
        # Each run starts one build later, so neither always goes first.
        order = builds[run % len(builds):] + builds[:run % len(builds)]
        for name, binary in order:
            out = subprocess.run([binary, *opts.args.split()], check=True, capture_output=True, text=True).stdout
            for line in out.splitlines()[1:]:
                fields = line.split()
                case = " ".join(fields[:4])
                if case not in cases:
                    cases.append(case)
                wall, cpu = float(fields[4]), float(fields[5])
                digests.setdefault(case, {})[name] = fields[9]
                old = best.get((case, name), [wall, cpu])
                best[(case, name)] = [min(old[0], wall), min(old[1], cpu)]
    load = os.getloadavg()[0]
    names = [name for name, _ in builds]
    print(f"load average {load:.2f}; least of {opts.runs} runs × the example's repetitions; ms")
    header = "| input output fit N | " + " | ".join(f"{n} wall | {n} cpu" for n in names)
    header += "".join(f" | {n} ÷ {names[0]} (wall, cpu)" for n in names[1:])
    print(header + " |")
    print("|---" * (1 + 2 * len(names) + len(names) - 1) + "|")
    for case in cases:
        cells = [f"{best[(case, n)][0]:.1f} | {best[(case, n)][1]:.1f}" for n in names]
        ratios = [
            f"{best[(case, n)][0] / best[(case, names[0])][0]:.3f}, {best[(case, n)][1] / best[(case, names[0])][1]:.3f}"
            for n in names[1:]
        ]
        print(f"| {case} | " + " | ".join(cells + ratios) + " |")
    differ = [case for case in cases if len(set(digests[case].values())) > 1]
    print("outputs: " + ("the same bits in every build" if not differ else "DIFFER in " + ", ".join(differ)))
    # Each build's N ≥ 5 against its own N = 3 (issue 36, point 2).
    for name in names:
        for case in cases:
            input_, output, fit, n = case.split()
            three = best.get((f"{input_} {output} {fit} 3", name))
            if n != "3" and three:
                wall, cpu = best[(case, name)]
                print(f"{name}: {case} ÷ N = 3: wall {wall / three[0]:.3f}, cpu {cpu / three[1]:.3f}")


if __name__ == "__main__":
    main()
