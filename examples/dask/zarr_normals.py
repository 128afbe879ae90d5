"""A height raster too large to want in one process, as Zarr, to a Zarr of
encoded normals on a Dask cluster; then the same conversion in one process
for comparison, and a check that both give the same bits.

    python examples/dask/zarr_normals.py --dir /tmp/nf-dask            # 32768², 4 GiB of float32
    python examples/dask/zarr_normals.py --dir /tmp/nf-dask --size 4096  # a quick run
    python examples/dask/zarr_normals.py --dir /tmp/nf-dask --cli target/release/normalfit  # and the CLI

Steps (each timed):
1. heights.zarr: a float32 raster of --size² generated chunk by chunk on
   the cluster (smooth waves plus noise, the same for any chunking).
2. normals.zarr: normalfit.dask.normals of normalfit.dask.read_zarr of it,
   written by normalfit.dask.to_zarr (a temporary store renamed into place)
   on a LocalCluster of 2 worker processes, 1 thread each, memory_limit
   1 GiB each. Printed: wall time, texels/s in all and per worker thread,
   the processor time of the workers and of this process (which runs the
   scheduler) and texels per processor second, and each worker process's
   peak RSS, sampled with psutil every 50 ms during the run.
3. With --cli PATH (the normalfit binary): the single-process command
   line on the same heights. heights.exr holds the same float32 values as
   one channel Y (uncompressed scanlines, written here a row of chunks at
   a time); `normalfit convert heights.exr -o normals.png` runs with the
   cluster's options (N, wrap, scale 8, --bits) and --max-texels the
   raster's size. Printed: wall time, texels/s in all and per core (the
   command line's fit uses every core of the machine), its CPU time over
   its wall time, texels per processor second and the cluster's over
   them (the ratio of docs/dask.md), and its peak RSS, sampled as the
   workers' are. Then the PNG's first --cli-check-rows rows (0: all) are
   read back with pypng, streaming, and compared with normals.zarr.
4. The comparison: normalfit.normals on the whole array in this process
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
import importlib.util
import os
import shutil
import struct
import subprocess
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


def write_exr(heights_path: Path, exr_path: Path) -> None:
    """The Zarr's heights, unchanged, as an OpenEXR file of one float32
    channel Y in uncompressed scanlines, written a row of chunks at a time.

    At this one setting the format is a header, a table of each row's
    offset, and per row its y, its byte count and its values, all little-
    endian: written here directly. (The OpenEXR package's File takes the
    whole array at once; its streaming OutputFile, deprecated, crashes once
    2 GiB of pixels are written, in OpenEXR 3.5.)"""
    import zarr

    stored = zarr.open_array(os.fspath(heights_path), mode="r")
    height, width = stored.shape

    def attribute(name: str, kind: str, value: bytes) -> bytes:
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    window = struct.pack("<4i", 0, 0, width - 1, height - 1)
    float_channel = struct.pack("<iB3xii", 2, 0, 1, 1)  # FLOAT, not linear, sampled 1 × 1
    header = b"".join([
        struct.pack("<2i", 20000630, 2),  # the magic number; version 2, a single part of scanlines
        attribute("channels", "chlist", b"Y\0" + float_channel + b"\0"),
        attribute("compression", "compression", b"\0"),  # none: one row per block
        attribute("dataWindow", "box2i", window),
        attribute("displayWindow", "box2i", window),
        attribute("lineOrder", "lineOrder", b"\0"),  # increasing y
        attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        attribute("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)),
        attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        b"\0",
    ])
    row_bytes = 4 * width
    first_row = len(header) + 8 * height
    offsets = first_row + np.arange(height, dtype="<u8") * (8 + row_bytes)
    with open(exr_path, "wb") as out:
        out.write(header)
        out.write(offsets.tobytes())
        step = stored.chunks[0]
        for y in range(0, height, step):
            rows = np.asarray(stored[y:y + step], dtype="<f4")
            blocks = np.empty((rows.shape[0], 2 + width), dtype="<i4")
            blocks[:, 0] = np.arange(y, y + rows.shape[0])
            blocks[:, 1] = row_bytes
            blocks[:, 2:] = rows.view("<i4")  # the floats' bits
            out.write(blocks.tobytes())


def run_cli(command: list[str], env: dict[str, str]) -> tuple[float, float, int]:
    """Runs the command line in `env`; returns its wall time, its CPU time
    (user and system, the kernel's, from wait4) and its peak RSS in bytes,
    sampled like the workers'. (wait4's ru_maxrss is not the program's: Python
    starts it with vfork, and Linux counts the parent's peak, which the
    child shared until exec, as the child's.)"""
    start = time.perf_counter()
    proc = subprocess.Popen(command, env=env)
    with PeakRss({"cli": proc.pid}) as rss:
        _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{command[0]} failed with exit code {proc.returncode}")
    return wall, usage.ru_utime + usage.ru_stime, rss.peak["cli"]


def png_matches_zarr(png_path: Path, normals_path: Path, rows: int) -> bool:
    """Whether the PNG has the Zarr's shape and depth and its first `rows`
    rows decode to the Zarr's normals, read row by row (pypng, streaming)."""
    import png
    import zarr

    stored = zarr.open_array(os.fspath(normals_path), mode="r")
    width, height, pixels, info = png.Reader(filename=os.fspath(png_path)).read()
    if (height, width, info["planes"], info["bitdepth"]) != (*stored.shape, stored.dtype.itemsize * 8):
        return False
    step = stored.chunks[0]
    band = stored[0:0]
    for y, row in enumerate(pixels):
        if y == rows:
            break
        if y % step == 0:
            band = stored[y:y + step]
        if not np.array_equal(np.frombuffer(row, dtype=stored.dtype).reshape(width, 3), band[y % step]):
            return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dir", type=Path, required=True,
                        help="where the files go (the Zarr stores: about 5 GiB at 32768²; --cli adds 4 GiB of EXR "
                             "and the PNG)")
    parser.add_argument("--size", type=int, default=32768, help="side of the square raster (default 32768)")
    parser.add_argument("--chunk", type=int, default=2048, help="side of a chunk (default 2048)")
    parser.add_argument("--patch", type=int, default=3, help="N (default 3)")
    parser.add_argument("--bits", type=int, choices=(8, 16), default=8, help="encoded normals' depth (default 8)")
    parser.add_argument("--memory-limit", default="1GiB", help="per worker (default 1GiB)")
    parser.add_argument("--scheduler", help="a running cluster's scheduler address instead of a LocalCluster")
    parser.add_argument("--cli", type=Path, metavar="PATH",
                        help="the normalfit binary: also convert the same heights, as an EXR, with the command "
                             "line in one process, and compare its PNG's rows (needs pypng)")
    parser.add_argument("--cli-check-rows", type=int, default=256, metavar="ROWS",
                        help="rows of the CLI's PNG compared with normals.zarr (default 256; 0: every row, "
                             "slow: pypng unfilters in Python)")
    parser.add_argument("--no-compare", action="store_true",
                        help="skip the in-memory normalfit.normals run and its check")
    parser.add_argument("--keep", action="store_true", help="keep the Zarr stores (and the EXR and PNG)")
    parser.add_argument("--raw", action="store_true",
                        help="both Zarr stores without a compressor (Zarr's default codec otherwise)")
    args = parser.parse_args()
    # The command line runs in the environment this process had before
    # Dask changed it: a LocalCluster sets MALLOC_TRIM_THRESHOLD_=65536
    # (for its workers, in this process's environment too), under which
    # glibc hands every freed block at the heap's top back and the command
    # line's blocks come back as fresh pages: at 32768², twice its
    # processor time, most of it the kernel's.
    plain_env = dict(os.environ)
    if args.cli_check_rows < 0:
        parser.error("--cli-check-rows: a number of rows, 0 for all")
    if args.cli is not None:
        if not os.access(args.cli, os.X_OK):
            parser.error(f"--cli {args.cli}: not an executable file")
        # Here rather than after the cluster's minutes.
        if importlib.util.find_spec("png") is None:
            parser.error("--cli reads the command line's PNG back with pypng: pip install pypng")

    args.dir.mkdir(parents=True, exist_ok=True)
    heights_path, normals_path = args.dir / "heights.zarr", args.dir / "normals.zarr"
    exr_path, png_path = args.dir / "heights.exr", args.dir / "normals.png"
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
    codec: dict[str, Any] = {"compressors": None} if args.raw else {}
    nd.to_zarr(raster, heights_path, **codec)
    print(f"heights.zarr written in {time.perf_counter() - start:.1f} s")

    # 2. The normals on the cluster.
    shutil.rmtree(normals_path, ignore_errors=True)
    lazy = nd.normals(nd.read_zarr(heights_path), **opts)
    pids = client.run(os.getpid)
    # The processor time of the workers and of this process (the client,
    # and a LocalCluster's scheduler): known for local workers only.
    local = [psutil.Process(pid) for pid in pids.values()] + [psutil.Process()] if cluster is not None else []
    used = lambda: sum(p.cpu_times().user + p.cpu_times().system for p in local)  # noqa: E731
    with PeakRss(pids) as rss:
        start, cpu_before = time.perf_counter(), used()
        nd.to_zarr(lazy, normals_path, **codec)
        wall, cluster_cpu = time.perf_counter() - start, used() - cpu_before
    rate = texels / wall
    print(f"normals.zarr ({args.bits}-bit) on the cluster: {wall:.1f} s, {rate / 1e6:.1f} Mtexels/s, "
          f"{rate / cores / 1e6:.1f} Mtexels/s per worker thread"
          + (f"; processor time {cluster_cpu:.1f} s, {texels / cluster_cpu / 1e6:.1f} Mtexels per processor second"
             if local else ""))
    for name, peak in sorted(rss.peak.items()):
        print(f"  worker {name}: peak RSS {peak / 2**20:.0f} MiB (limit {args.memory_limit})")
    client.close()
    if cluster is not None:
        cluster.close()

    # 3. The command line, one process, on the same heights as an EXR.
    if args.cli is not None:
        start = time.perf_counter()
        write_exr(heights_path, exr_path)
        # Flushed before the command line starts, so that its time does not
        # include writing back the EXR just written.
        os.sync()
        print(f"heights.exr written in {time.perf_counter() - start:.1f} s "
              f"({exr_path.stat().st_size / 2**30:.2f} GiB, float32 Y, uncompressed)")
        command = [os.fspath(args.cli), "convert", os.fspath(exr_path), "-o", os.fspath(png_path),
                   "--patch", str(opts["patch"]), "--border", str(opts["border"]), "--scale", str(opts["scale"]),
                   "--bits", str(args.bits), "--max-texels", str(texels), "--quiet"]
        print("$ " + " ".join(command))
        wall, cpu, peak = run_cli(command, plain_env)
        machine = os.cpu_count() or 1
        rate = texels / wall
        print(f"normals.png ({args.bits}-bit) by the command line: {wall:.1f} s, {rate / 1e6:.1f} Mtexels/s, "
              f"{rate / machine / 1e6:.1f} Mtexels/s per core (its fit uses all {machine} cores; "
              f"CPU time {cpu:.1f} s, {cpu / wall:.2f} cores busy on average, {texels / cpu / 1e6:.1f} Mtexels per "
              f"processor second), peak RSS {peak / 2**20:.0f} MiB")
        if local:
            print(f"the cluster's texels per processor second over the command line's: {cpu / cluster_cpu:.2f}")
        rows = args.size if args.cli_check_rows == 0 else min(args.cli_check_rows, args.size)
        start = time.perf_counter()
        same = png_matches_zarr(png_path, normals_path, rows)
        which = "every row" if rows == args.size else f"the first {rows} rows"
        print(f"the CLI's PNG equals the cluster's normals on {which}: {same} ({time.perf_counter() - start:.1f} s)")
        if not same:
            raise SystemExit(1)

    # 4. One process, the whole array.
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
        exr_path.unlink(missing_ok=True)
        png_path.unlink(missing_ok=True)


if __name__ == "__main__":
    main()
