#!/usr/bin/env python3
"""normalfit.xarray against xarray-spatial and gdaldem on one DEM: values and speed.

The DEM is bench/terrain.sh's (bench/.work/dem4096.tif: float32, 10 m
texels, UTM 33N; run bench/terrain.sh once to make it), opened with
rioxarray as a GIS user does. For slope, aspect and hillshade it prints:

* values, on the texels inside the one-texel edge (xarray-spatial leaves
  the edge NaN, gdaldem without -compute_edges leaves it nodata):
  the largest difference from gdaldem's and the share bit-equal, for
  xarray-spatial and for normalfit (Horn's weights: weights="binomial",
  fit="vertical", border="clamp", gdaldem's sun 315°/45°). The aspect is
  compared where gdaldem's slope exceeds 1°. xarray-spatial's hillshade
  is another formula (np.gradient's central differences, a float in
  [0, 1], its sun given as azimuth and altitude): its greys are 255·v,
  compared as such;
* speed: the best wall time of `repeat` calls on the NumPy-backed
  DataArray (xarray-spatial's numba functions compiled by a first call
  that is not timed), and on a Dask-backed one in 1024² chunks (the
  threaded scheduler, computed into NumPy), each tool in turn.

    python3 bench/xarray_peers.py [DEM] [repeat]

Needs: normalfit (the wheel) with its xarray extra, xarray-spatial,
rioxarray, and gdaldem on the PATH.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import rioxarray
import xrspatial

import normalfit
import normalfit.xarray as nx

dem = sys.argv[1] if len(sys.argv) > 1 else "bench/.work/dem4096.tif"
repeat = int(sys.argv[2]) if len(sys.argv) > 2 else 3
da = rioxarray.open_rasterio(dem).squeeze("band", drop=True)
heights = da.load()
HORN = dict(weights="binomial", fit="vertical", border="clamp")


def gdaldem(product: str) -> np.ndarray:
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, f"{product}.tif")
        subprocess.run(["gdaldem", product, "-q", dem, out], check=True)
        return rioxarray.open_rasterio(out).squeeze("band", drop=True).values


def inside(a: np.ndarray) -> np.ndarray:
    return np.asarray(a)[1:-1, 1:-1]


def compare(name: str, got: np.ndarray, want: np.ndarray, where: np.ndarray) -> str:
    got, want = inside(got).astype(np.float64)[where], inside(want).astype(np.float64)[where]
    diff = np.abs(got - want)
    if name == "aspect":
        diff = np.minimum(diff, 360.0 - diff)
    return f"max {diff.max():.4g}, {100.0 * np.mean(got == want):.2f} % equal"


def best(call) -> tuple[float, float]:
    """The best wall time and the least CPU time (user + system, every
    thread) of `repeat` calls."""
    walls, cpus = [], []
    for _ in range(repeat):
        cpu, start = time.process_time(), time.perf_counter()
        call()
        walls.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus)


print(f"DEM {dem}: {heights.shape[1]} × {heights.shape[0]}, {heights.dtype}; "
      f"xarray-spatial {xrspatial.__version__}, normalfit {normalfit.__version__}, "
      f"load {os.getloadavg()[0]:.2f}")

want = {p: gdaldem(p) for p in ("slope", "aspect", "hillshade")}
steep = inside(want["slope"]) > 1.0
everywhere = np.ones_like(steep)
ours = {
    "slope": nx.slope(heights, **HORN).values,
    "aspect": nx.aspect(heights, **HORN).values,
    "hillshade": nx.hillshade(heights, **HORN).values,
}
theirs = {
    "slope": xrspatial.slope(heights).values,
    "aspect": xrspatial.aspect(heights).values,
    "hillshade": 255.0 * xrspatial.hillshade(heights, azimuth=315, angle_altitude=45).values,
}
print()
print("| product | xarray-spatial vs gdaldem | normalfit vs gdaldem |")
print("|---|---|---|")
for p in ("slope", "aspect", "hillshade"):
    where = steep if p == "aspect" else everywhere
    print(f"| {p} | {compare(p, theirs[p], want[p], where)} | {compare(p, ours[p], want[p], where)} |")

chunked = heights.chunk({"y": 1024, "x": 1024})
calls = {
    "slope": (lambda a: xrspatial.slope(a), lambda a: nx.slope(a, **HORN)),
    "aspect": (lambda a: xrspatial.aspect(a), lambda a: nx.aspect(a, **HORN)),
    "hillshade": (
        lambda a: xrspatial.hillshade(a, azimuth=315, angle_altitude=45),
        lambda a: nx.hillshade(a, **HORN),
    ),
}
print()
print(f"best of {repeat}, each tool in turn; CPU is user + system of every thread:")
print()
print("| product | input | xarray-spatial wall | CPU | normalfit wall | CPU | speed-up (wall) |")
print("|---|---|---|---|---|---|---|")
for p, (xs, nf) in calls.items():
    for label, arr in (("NumPy", heights), ("Dask 1024²", chunked)):
        xs(arr).values  # compiles xarray-spatial's numba kernels
        (w_xs, c_xs), (w_nf, c_nf) = best(lambda: xs(arr).values), best(lambda: nf(arr).values)
        print(f"| {p} | {label} | {w_xs:.3f} s | {c_xs:.2f} s | {w_nf:.3f} s | {c_nf:.2f} s | {w_xs / w_nf:.2f}× |")
print()
print(f"load {os.getloadavg()[0]:.2f} after")
