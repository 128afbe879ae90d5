"""Code as a user writes it, for mypy --strict against the stubs (checked
by test_stubs.py; not a test module itself)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

import normalfit

heights: npt.NDArray[np.uint16] = np.zeros((8, 8), np.uint16)
unit = normalfit.normals(heights, patch=5, fit="vertical", border=("wrap", "mirror"), convention="dx", scale=2.0)
rgb = normalfit.normals(heights, dtype=np.uint16, threads=2, border="clamp,wrap")
report: normalfit.TilingReport = normalfit.check_tiling(heights, threshold=2.0, kind="height")
score: float = report.x.score
borders: tuple[str, str] = report.suggested_borders
seamless: bool = report.seamless and report.y.seamless
version: str = normalfit.__version__
summary: normalfit.ConversionSummary = normalfit.convert("in.png", "out.png", border="auto", bits=16, alpha="height")
used: tuple[str, str] = summary.borders
warnings: list[str] = summary.warnings
decoded = normalfit.decode_normals("out.png")
lit = normalfit.lit_view("in.png", light=(45.0, 60.0), tile=True)
metres = normalfit.normals(heights, pixel_size=(30.0, 20.0), fit="vertical")
mapped = normalfit.normals(heights, units="map", pixel_size=10.0)
raw = normalfit.convert("t.r16", "n.png", size=(1025, 1025), byte_order="big", units="map", pixel_size=2.0)
band = normalfit.convert("dem.tif", "n.exr", band=2, units="map")
tile = normalfit.convert("tile.png", "n.png", decode="terrarium", size="256x256")
lit_dem = normalfit.lit_view("dem.tif", units="map", band=1)
from_file: normalfit.TilingReport = normalfit.check_tiling("in.png", channel="r")
back, info = normalfit.height(unit, scale=2.0, fit="vertical", convention="auto", model="exact")
range_: tuple[float, float] = info.range
written: normalfit.HeightInfo = normalfit.height_file("out.png", "height.exr", border=("wrap", "mirror"))

import dask.array as da  # noqa: E402
import normalfit.dask  # noqa: E402

lazy_heights = da.zeros((64, 64), chunks=16, dtype=np.float32)
lazy = normalfit.dask.normals(lazy_heights, patch=5, border=("wrap", "mirror"), dtype=np.uint16)
lazy_n, lazy_r = normalfit.dask.normals(lazy_heights, residual=True, threads=1)
lazy_report: normalfit.TilingReport = normalfit.dask.check_tiling(lazy_heights, threshold=2.0)
stored: Path = normalfit.dask.to_zarr(lazy, "normals.zarr", overwrite=True)
