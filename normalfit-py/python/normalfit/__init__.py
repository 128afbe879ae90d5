"""Tangent-space normal maps from height maps, by least-squares plane fits.

NumPy arrays in, NumPy arrays out, the same bits as the ``normalfit``
command line: the work is done by the Rust library the command line is
built on, with the GIL released.

>>> import numpy as np, normalfit
>>> heights = np.random.default_rng(1).random((64, 64), dtype=np.float32)
>>> n = normalfit.normals(heights, patch=5, scale=4.0)   # (64, 64, 3) float32
>>> rgb = normalfit.normals(heights, patch=5, scale=4.0, dtype=np.uint16)
>>> normalfit.check_tiling(heights).x.seamless   # noise tiles
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import _normalfit
from ._normalfit import AxisReport, TilingReport

__version__: str = _normalfit.__version__
__all__ = ["AxisReport", "TilingReport", "check_tiling", "normals"]


def normals(
    heights: Any,
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: str | tuple[str, str] = "wrap",
    convention: str = "opengl",
    scale: float | None = None,
    relief: float | None = None,
    invert: bool = False,
    dtype: Any = np.float32,
    residual: bool = False,
    out: Any = None,
    threads: int | None = None,
) -> Any:
    """The normal map of a height map.

    heights: a 2-D array (rows, columns) of uint8, uint16, float32 or
        float64. Integers are heights v / 255 and v / 65535, floats heights
        as they are (the contract's units, as the command line reads
        files). A C-contiguous, aligned array in native byte order is read
        in place; any other (a slice with steps, a transpose, Fortran
        order) is copied once, in row order, with the GIL released.

    The options are the command line's ``convert`` options, with the same
    names, defaults and values:

    patch: N, the side of the N x N patch fitted around each texel (odd, >= 3).
    fit: "orthogonal" (perpendicular distances) or "vertical".
    border: "wrap", "clamp" or "mirror" for both axes, or one per axis as
        an (x, y) pair or the command line's "x,y".
    convention: "opengl" ("gl", green up) or "directx" ("dx", green down).
    scale: the height gain S (default 1); relief: the gain as F x width.
        Give one or neither.
    invert: heights are depths.

    dtype: np.float32 (unit vectors, components in [-1, 1]), or np.uint8 /
        np.uint16 for the encoded RGB round(c_max (n + 1) / 2), bit for bit
        what ``normalfit convert --bits 8/16`` writes.
    residual: also return the fit's residual, a (rows, columns) float32
        array (root-mean-square distance of the patch's points from the
        plane, in texel widths): the result is then (normals, residual).
    out: a C-contiguous (rows, columns, 3) array of dtype to write into
        (returned); it must not share memory with heights.
    threads: run on a pool of this many threads (pools are kept per size);
        default: every core (rayon's global pool).

    Returns a (rows, columns, 3) array of dtype.

    Raises TypeError for a heights or out that is not an array of the
    right number of dimensions and dtype, ValueError for an option out of
    range, a height that is NaN or infinite, an out of the wrong shape,
    MemoryError when the memory is not there.
    """
    return _normalfit.normals(
        heights, patch, fit, border, convention, scale, relief, invert, dtype, residual, out, threads
    )


def check_tiling(image: Any, *, threshold: float = 1.5, kind: str = "auto") -> TilingReport:
    """Whether an image tiles seamlessly: ``normalfit tiling`` on an array.

    image: a 2-D (rows, columns) height map, or a 3-D (rows, columns,
        channels) array of 1 to 4 channels (gray, gray + alpha, RGB, RGBA),
        of uint8, uint16, float32 or float64, in the units the command line
        reads files in (integers divided by 255 or 65535). An encoded
        normal map is judged on R, G and B, a height map on its height
        (the luma of RGB).
    threshold: an axis is seamless when its score is at most this (> 0).
    kind: "auto" (decided from the pixels), "height" or "normal".

    Returns a TilingReport: kind, x and y (score, seamless), seamless,
    width, height, and suggested_borders, the (x, y) borders that add no
    seam (wrap where it tiles, mirror where not).
    """
    return _normalfit.check_tiling(image, threshold, kind)
