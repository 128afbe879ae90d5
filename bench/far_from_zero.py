"""How the fit's rounding grows with the heights' distance from zero
(docs/fit.md, "Far from zero").

A DEM on a 1/64 grid (hills, a ridge and roughness; every height, and
every difference of two, exact in f64) is raised by an offset and fitted
(float32 normals, clamp, scale 1), against the same DEM not raised: the
two have the same exact normals, so any difference is the fit's own
rounding. Prints a Markdown table, the largest component difference per
offset, weights, N and fit.

    python3 bench/far_from_zero.py      # needs the normalfit Python package
"""
import numpy as np, normalfit
w, h = 256, 192
y, x = np.mgrid[0:h, 0:w].astype(np.float64)
dem = 3 * np.sin(0.21 * x) * np.cos(0.17 * y) + 0.4 * x - 0.25 * y + 2 * np.exp(-abs(x - y) / 6)
dem += ((np.arange(w * h).reshape(h, w) * 2654435761) % 1009 / 1009 - 0.5) * 0.3
dem = np.round(dem * 64) / 64
print("| offset | weights | N | orthogonal | vertical |")
print("|---|---|---|---|---|")
for offset in [400.0, 8848.0, 2.0**17, 2.0**20]:
    for weights in ["uniform", "binomial"]:
        for n in [3, 9, 41]:
            cells = []
            for fit in ["orthogonal", "vertical"]:
                kw = dict(patch=n, fit=fit, weights=weights, border="clamp", dtype=np.float64, pixel_size=1.0, units="map") if False else dict(patch=n, fit=fit, weights=weights, border="clamp", dtype=np.float32, scale=1.0)
                a = normalfit.normals(dem, **kw)
                b = normalfit.normals(dem + offset, **kw)
                cells.append(f"{np.abs(a - b).max():.1e}")
            print(f"| {offset:g} | {weights} | {n} | {cells[0]} | {cells[1]} |")
