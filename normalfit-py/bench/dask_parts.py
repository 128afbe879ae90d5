"""Where normalfit.dask's time goes, stage by stage, against the command
line on the same heights (issue 36 point 4; docs/dask.md).

On the cluster of examples/dask/zarr_normals.py (a LocalCluster of 2
worker processes, 1 thread each, 1 GiB each), the same Zarr of float32
heights is taken through more and more of the conversion:

1. read: the chunks decoded and summed (Zarr's codec);
2. + fit: ``normalfit.dask.normals`` (8-bit, N = 3, wrap, scale 8): each
   chunk's strips for its neighbours' halos, and its window assembled
   and fitted; each chunk's first texel kept (a sum of the normals would
   cost more than their fit);
3. + write: ``normalfit.dask.to_zarr`` of the normals (Zarr's default
   codec), as the example does.

Then the library's fit alone (``_normalfit.window_normals``, what each
fit task runs) on the same chunks one after another in this process, the
graph's own share (the fit stage less the read and the fits alone) and
the write's codec and files (the write stage less the fit stage).

Each stage's figure is the workers' CPU time (user + system, psutil) and
the client's (which runs the scheduler), best of --rounds: a CPU time is
what a stage costs whatever else the machine runs, where a wall time on a
shared machine is not. The command line's CPU time on the same heights
(the example's EXR, uncompressed, to an 8-bit PNG) follows, and the
ratio the issue asks about: texels per CPU second, cluster against
command line (the cluster's per worker thread against the command line's
per core, on an idle machine where both keep their cores busy).

    python normalfit-py/bench/dask_parts.py --dir /tmp/nf-parts --cli target/release/normalfit
    python normalfit-py/bench/dask_parts.py --dir /tmp/nf-parts --size 16384 --rounds 2
    python normalfit-py/bench/dask_parts.py --dir /tmp/nf-parts --raw   # both stores without a codec

--raw: both Zarr stores without a compressor (``compressors=None``), to
tell Zarr's codecs from the rest.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Callable

import dask.array as da
import distributed
import numpy as np
import psutil

import normalfit.dask as nd

sys.path.insert(0, os.fspath(Path(__file__).resolve().parents[2] / "examples" / "dask"))
import zarr_normals  # noqa: E402  (the example's heights, and its EXR writer)


def first_texels(normals: Any) -> Any:
    """Each chunk's first texel: the chunks computed, nothing else."""
    blocks = tuple((1,) * len(c) for c in normals.chunks[:2]) + ((3,),)
    return normals.map_blocks(lambda b: b[:1, :1], chunks=blocks, dtype=normals.dtype)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dir", type=Path, required=True, help="where the Zarr stores (and the EXR) go")
    parser.add_argument("--size", type=int, default=8192, help="side of the square raster (default 8192)")
    parser.add_argument("--chunk", type=int, default=2048, help="side of a chunk (default 2048, the example's)")
    parser.add_argument("--rounds", type=int, default=3, help="each stage this many times, the least CPU kept")
    parser.add_argument("--cli", type=Path, help="the normalfit binary, for the command line's row")
    parser.add_argument("--raw", action="store_true", help="both Zarr stores without a compressor")
    args = parser.parse_args()
    # The command line runs in the environment as it was before Dask's
    # LocalCluster set MALLOC_TRIM_THRESHOLD_ in it (see
    # examples/dask/zarr_normals.py).
    plain_env = dict(os.environ)
    args.dir.mkdir(parents=True, exist_ok=True)
    texels = args.size * args.size
    heights_path, normals_path = args.dir / "heights.zarr", args.dir / "normals.zarr"
    codec: dict[str, Any] = {"compressors": None} if args.raw else {}
    opts: dict[str, Any] = dict(patch=3, border="wrap", scale=8.0, dtype=np.uint8)

    cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, memory_limit="1GiB",
                                       dashboard_address=None)
    client = distributed.Client(cluster)
    workers = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
    me = psutil.Process()

    def cpu(procs: list[psutil.Process]) -> float:
        return sum(p.cpu_times().user + p.cpu_times().system for p in procs)

    if not heights_path.exists():
        raster = da.map_blocks(zarr_normals.generate_block,
                               chunks=da.core.normalize_chunks(args.chunk, (args.size, args.size)),
                               dtype=np.float32, meta=np.empty((0, 0), np.float32))
        nd.to_zarr(raster, heights_path)
    if args.raw:
        raw_path = args.dir / "heights-raw.zarr"
        if not raw_path.exists():
            nd.to_zarr(nd.read_zarr(heights_path), raw_path, **codec)
        heights = nd.read_zarr(raw_path)
    else:
        heights = nd.read_zarr(heights_path)

    def write() -> None:
        shutil.rmtree(normals_path, ignore_errors=True)
        nd.to_zarr(nd.normals(heights, **opts), normals_path, **codec)

    stages: list[tuple[str, Callable[[], Any]]] = [
        ("read (decode, sum)", lambda: heights.sum().compute()),
        ("+ fit (normalfit.dask.normals: halo and fit)", lambda: first_texels(nd.normals(heights, **opts)).compute()),
        ("+ write (normalfit.dask.to_zarr)", write),
    ]
    print(f"{args.size}² float32 heights, chunks {args.chunk}², N = 3, wrap, 8-bit; 2 worker processes of 1 thread; "
          f"Zarr stores {'without a codec' if args.raw else 'with Zarr’s default codec'}; load average {os.getloadavg()[0]:.1f}")
    print()
    print("| stage | workers' CPU | client's CPU | wall | Mtexels per CPU second |")
    print("|---|---:|---:|---:|---:|")
    full = 0.0
    cpus: list[float] = []
    for name, run in stages:
        best: tuple[float, float, float] | None = None
        for _ in range(args.rounds):
            w0, c0, t0 = cpu(workers), cpu([me]), time.perf_counter()
            run()
            figures = (cpu(workers) - w0, cpu([me]) - c0, time.perf_counter() - t0)
            if best is None or figures[0] + figures[1] < best[0] + best[1]:
                best = figures
        assert best is not None
        cpus.append(best[0] + best[1])
        full = cpus[-1]
        print(f"| {name} | {best[0]:.2f} s | {best[1]:.2f} s | {best[2]:.2f} s | {texels / full / 1e6:.1f} |")
    shutil.rmtree(normals_path, ignore_errors=True)
    client.close()
    cluster.close()

    # The library's fit alone: each chunk's window (the chunk and its halo
    # of r, wrapped) fitted with the stages' options as a fit task fits it,
    # in this process.
    r = opts["patch"] // 2
    whole = np.asarray(heights.compute(scheduler="threads"))
    padded = np.pad(whole, r, mode="wrap")
    fits = float("inf")
    for _ in range(args.rounds):
        used = 0.0
        for r0 in range(0, args.size, args.chunk):
            for c0 in range(0, args.size, args.chunk):
                r1, c1 = min(r0 + args.chunk, args.size), min(c0 + args.chunk, args.size)
                held = np.ascontiguousarray(padded[r0:r1 + 2 * r, c0:c1 + 2 * r])
                start = time.process_time()
                nd._normalfit.window_normals(
                    held, (args.size, args.size), (c0, r0), (r, r, r, r), opts["patch"], "orthogonal",
                    (opts["border"], opts["border"]), "opengl", opts["scale"], None, False, np.dtype(opts["dtype"]),
                    False, 1)
                used += time.process_time() - start
        fits = min(fits, used)
    read, fitted, written = cpus
    print(f"| the library's fits alone (each chunk's window, one after another here) | {fits:.2f} s | | | |")
    shares = (f"the graph's own share (the fit stage less the read and the fits alone): {fitted - read - fits:.2f} s; "
              f"the write's codec and files: {written - fitted:.2f} s")

    if args.cli is not None:
        exr, png = args.dir / "heights.exr", args.dir / "normals.png"
        if not exr.exists():
            zarr_normals.write_exr(heights_path, exr)
        command = [os.fspath(args.cli), "convert", os.fspath(exr), "-o", os.fspath(png), "--patch", "3",
                   "--border", "wrap", "--scale", "8", "--bits", "8", "--max-texels", str(texels), "--quiet"]
        least = float("inf")
        for _ in range(args.rounds):
            before, t0 = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
            subprocess.run(command, check=True, env=plain_env)
            wall, after = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN)
            used = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            if used < least:
                least, least_wall = used, wall
        png.unlink(missing_ok=True)
        print(f"| command line: EXR (uncompressed) → 8-bit PNG | {least:.2f} s | | {least_wall:.2f} s | "
              f"{texels / least / 1e6:.1f} |")
        print()
        print(f"cluster ÷ command line, texels per CPU second: {least / full:.2f}× (asked: ≥ 0.8×)")
    print()
    print(shares[0].upper() + shares[1:] + ".")


if __name__ == "__main__":
    main()
