"""A height raster too large to want in one process, as Zarr, to a Zarr of
encoded normals on a Dask cluster; then the same conversion in one process
for comparison, and a check that both give the same bits.

    python examples/dask/zarr_normals.py --dir /tmp/nf-dask            # 32768², 4 GiB of float32
    python examples/dask/zarr_normals.py --dir /tmp/nf-dask --size 4096  # a quick run

Steps (each timed):
1. heights.zarr: a float32 raster of --size² generated chunk by chunk on
   the cluster (smooth waves plus noise, the same for any chunking).
2. normals.zarr: normalfit.dask.normals of normalfit.dask.read_zarr of it,
   written by normalfit.dask.to_zarr (a temporary store renamed into place)
   on a LocalCluster of 2 worker processes, 1 thread each, memory_limit
   1 GiB each. Printed: wall time, texels/s and per core, and each worker
   process's peak RSS, sampled with psutil every 50 ms during the run.
3. The comparison: normalfit.normals on the whole array in this process
   (every core, the library's default), after reading the heights whole;
   and the two results compared chunk by chunk (--no-compare skips it, for
   a machine without the memory: 7 GiB at 32768² with --bits 8).

To run on a real cluster, replace the LocalCluster by a Client of the
cluster's scheduler (--scheduler tcp://host:8786), with the Zarr stores on
storage every worker reads (a shared file system, or an object store URL
through zarr's fsspec support).
"""

from __future__ import annotations

import argparse
import os
import shutil
import threading
import time
from pathlib import Path
from typing import Any

import dask.array as da
import distributed
import numpy as np
import psutil

import normalfit
import normalfit.dask as nd


def generate_block(block_info: Any = None) -> np.ndarray:
    """Heights of one chunk: waves of several lengths and a little noise,
    a function of the texels' coordinates alone (any chunking gives the
    same raster)."""
    (y0, y1), (x0, x1) = block_info[None]["array-location"]
    y, x = np.mgrid[y0:y1, x0:x1].astype(np.float32)
    h = 0.5 + 0.2 * np.sin(x * 0.013) * np.cos(y * 0.011) + 0.05 * np.sin((x + 2 * y) * 0.21)
    rng = np.random.default_rng([y0, x0])
    h += 0.01 * rng.random(h.shape, dtype=np.float32)
    return h.astype(np.float32)


class PeakRss:
    """The largest RSS seen of each of some processes, sampled in a thread."""

    def __init__(self, pids: dict[str, int], every: float = 0.05) -> None:
        self.procs = {name: psutil.Process(pid) for name, pid in pids.items()}
        self.peak = {name: 0 for name in pids}
        self.every = every
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)

    def run(self) -> None:
        while not self.stop.is_set():
            for name, proc in self.procs.items():
                try:
                    self.peak[name] = max(self.peak[name], proc.memory_info().rss)
                except psutil.Error:
                    pass
            time.sleep(self.every)

    def __enter__(self) -> PeakRss:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dir", type=Path, required=True, help="where the Zarr stores go (about 5 GiB at 32768²)")
    parser.add_argument("--size", type=int, default=32768, help="side of the square raster (default 32768)")
    parser.add_argument("--chunk", type=int, default=2048, help="side of a chunk (default 2048)")
    parser.add_argument("--patch", type=int, default=3, help="N (default 3)")
    parser.add_argument("--bits", type=int, choices=(8, 16), default=8, help="encoded normals' depth (default 8)")
    parser.add_argument("--memory-limit", default="1GiB", help="per worker (default 1GiB)")
    parser.add_argument("--scheduler", help="a running cluster's scheduler address instead of a LocalCluster")
    parser.add_argument("--no-compare", action="store_true", help="skip the single-process run and the check")
    parser.add_argument("--keep", action="store_true", help="keep the Zarr stores")
    args = parser.parse_args()

    args.dir.mkdir(parents=True, exist_ok=True)
    heights_path, normals_path = args.dir / "heights.zarr", args.dir / "normals.zarr"
    out_dtype = np.uint8 if args.bits == 8 else np.uint16
    opts = dict(patch=args.patch, border="wrap", scale=8.0, dtype=out_dtype)
    texels = args.size * args.size

    if args.scheduler:
        cluster = None
        client = distributed.Client(args.scheduler)
    else:
        cluster = distributed.LocalCluster(
            n_workers=2, processes=True, threads_per_worker=1, memory_limit=args.memory_limit,
            dashboard_address=None,
        )
        client = distributed.Client(cluster)
    cores = sum(client.nthreads().values())
    print(f"{args.size}² float32 heights ({texels * 4 / 2**30:.2f} GiB), chunks {args.chunk}², N = {args.patch}, "
          f"{cores} worker threads, memory_limit {args.memory_limit}")

    # 1. The heights.
    start = time.perf_counter()
    shutil.rmtree(heights_path, ignore_errors=True)
    raster = da.map_blocks(generate_block, chunks=da.core.normalize_chunks(args.chunk, (args.size, args.size)),
                           dtype=np.float32, meta=np.empty((0, 0), np.float32))
    nd.to_zarr(raster, heights_path)
    print(f"heights.zarr written in {time.perf_counter() - start:.1f} s")

    # 2. The normals on the cluster.
    shutil.rmtree(normals_path, ignore_errors=True)
    lazy = nd.normals(nd.read_zarr(heights_path), **opts)
    pids = client.run(os.getpid)
    with PeakRss(pids) as rss:
        start = time.perf_counter()
        nd.to_zarr(lazy, normals_path)
        wall = time.perf_counter() - start
    rate = texels / wall
    print(f"normals.zarr ({args.bits}-bit) on the cluster: {wall:.1f} s, {rate / 1e6:.1f} Mtexels/s, "
          f"{rate / cores / 1e6:.1f} Mtexels/s per core")
    for name, peak in sorted(rss.peak.items()):
        print(f"  worker {name}: peak RSS {peak / 2**20:.0f} MiB (limit {args.memory_limit})")
    client.close()
    if cluster is not None:
        cluster.close()

    # 3. One process, the whole array.
    if not args.no_compare:
        import zarr

        start = time.perf_counter()
        whole = np.asarray(zarr.open_array(os.fspath(heights_path), mode="r")[...])
        read = time.perf_counter() - start
        me = psutil.Process()
        start = time.perf_counter()
        reference = normalfit.normals(whole, **opts)
        single = time.perf_counter() - start
        print(f"one process, normalfit.normals on the whole array ({os.cpu_count()} cores): {single:.1f} s "
              f"({texels / single / 1e6:.1f} Mtexels/s; reading the Zarr whole took {read:.1f} s more), "
              f"RSS {me.memory_info().rss / 2**30:.1f} GiB")
        del whole
        stored = zarr.open_array(os.fspath(normals_path), mode="r")
        step = args.chunk
        same = all(
            np.array_equal(stored[y:y + step, x:x + step], reference[y:y + step, x:x + step])
            for y in range(0, args.size, step) for x in range(0, args.size, step)
        )
        print(f"the cluster's normals equal the whole array's, bit for bit: {same}")
        if not same:
            raise SystemExit(1)
    if not args.keep:
        shutil.rmtree(heights_path, ignore_errors=True)
        shutil.rmtree(normals_path, ignore_errors=True)


if __name__ == "__main__":
    main()
