"""Float32 GeoTIFF DEMs with NaN holes for timing `normalfit height --holes`:
a lake (a disc, 2 % of the texels), a river (a winding band ~1.5 % of the
side wide, cutting the map in two from top to bottom) and scattered holes
(10 % of the texels, seeded). Written as ENVI raw + header, then
gdal_translate (GDAL's command-line tools) to GeoTIFF.

    python3 bench/holes_height.py DIR SIDE [SIDE ...]
"""

import os
import subprocess
import sys

import numpy as np


def dem(n):
    y, x = np.mgrid[0:n, 0:n] / n
    z = 0.3 * np.sin(2 * np.pi * (1.5 * x + 0.5 * y)) + 0.2 * np.cos(2 * np.pi * 3 * y) * np.sin(2 * np.pi * 2 * x)
    z += 0.05 * np.sin(2 * np.pi * 11 * (x + 0.3 * y)) * np.cos(2 * np.pi * 9 * y)
    return z


def masks(n):
    y, x = np.mgrid[0:n, 0:n]
    r = np.sqrt(0.02 * n * n / np.pi)
    lake = (x - 0.6 * n) ** 2 + (y - 0.4 * n) ** 2 < r * r
    centre = 0.45 * n + 0.08 * n * np.sin(2 * np.pi * 2 * y / n)
    river = np.abs(x - centre) < max(1.5, 0.0075 * n)
    scattered = np.random.default_rng(3).random((n, n)) < 0.10
    return {"lake": lake, "river": river, "scattered": scattered}


def write(path, a):
    raw = path[:-4] + ".raw"
    a.astype("<f4").tofile(raw)
    with open(path[:-4] + ".hdr", "w") as f:
        f.write(
            f"ENVI\nsamples = {a.shape[1]}\nlines = {a.shape[0]}\nbands = 1\nheader offset = 0\n"
            "file type = ENVI Standard\ndata type = 4\ninterleave = bsq\nbyte order = 0\n"
        )
    subprocess.run(["gdal_translate", "-q", "-of", "GTiff", raw, path], check=True)
    os.remove(raw)
    os.remove(path[:-4] + ".hdr")


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    for n in map(int, sys.argv[2:]):
        z = dem(n)
        for name, m in masks(n).items():
            path = f"{out}/{name}{n}.tif"
            if not os.path.exists(path):
                write(path, np.where(m, np.nan, z))


main()
