"""An independent reference: SPEC.md's formula written plainly in NumPy, f64.

Every texel's N x N patch is gathered through the border maps and its sums
taken directly (no sliding sums, no tiles), so it shares nothing with the
library but the contract.
"""

from __future__ import annotations

import math

import numpy as np

BORDERS = ("wrap", "clamp", "mirror")


def border_map(mode: str, k: np.ndarray, n: int) -> np.ndarray:
    """SPEC section 2's table: index k (any integer) onto [0, n)."""
    if mode == "wrap":
        return np.mod(k, n)
    if mode == "clamp":
        return np.clip(k, 0, n - 1)
    if mode == "mirror":
        if n == 1:
            return np.zeros_like(k)
        period = 2 * (n - 1)
        m = np.mod(k, period)
        return np.where(m < n, m, period - m)
    raise ValueError(mode)


def heights_of(stored: np.ndarray) -> np.ndarray:
    """SPEC section 1: integers are v / (2^bits - 1), floats as stored."""
    if stored.dtype == np.uint8:
        return stored.astype(np.float64) / 255.0
    if stored.dtype == np.uint16:
        return stored.astype(np.float64) / 65535.0
    return stored.astype(np.float64)


def normals(
    stored: np.ndarray,
    *,
    patch: int = 3,
    fit: str = "orthogonal",
    border: tuple[str, str] = ("wrap", "wrap"),
    convention: str = "opengl",
    scale: float = 1.0,
    weights: str = "uniform",
) -> np.ndarray:
    """(H, W, 3) unit normals in f64, by the contract's closed forms; with
    weights="binomial" every sum weighted by w(i) w(j), w(k) = C(N - 1, k)
    / 2^(N - 1) (SPEC section 2, "Weights")."""
    z = scale * heights_of(stored)
    rows, cols = z.shape
    r = patch // 2
    offsets = np.arange(-r, r + 1)
    xs = border_map(border[0], np.arange(cols)[:, None] + offsets[None, :], cols)  # (W, N)
    ys = border_map(border[1], np.arange(rows)[:, None] + offsets[None, :], rows)  # (H, N)
    # p[y, x, j, i] = z(x + i, y + j)
    p = z[ys[:, None, :, None], xs[None, :, None, :]]
    sigma = -1.0 if convention == "opengl" else 1.0
    i = offsets[None, None, None, :].astype(np.float64)
    j = offsets[None, None, :, None].astype(np.float64)
    if weights == "binomial":
        axis = np.array([math.comb(patch - 1, k) / 2.0 ** (patch - 1) for k in range(patch)])
    elif weights == "uniform":
        axis = np.ones(patch)
    else:
        raise ValueError(weights)
    w = axis[None, None, :, None] * axis[None, None, None, :]
    count = float(w.sum())
    a = float((w * i * i).sum())
    cx = (w * i * p).sum(axis=(2, 3))
    cy = (w * sigma * j * p).sum(axis=(2, 3))
    czz = (w * p * p).sum(axis=(2, 3)) - (w * p).sum(axis=(2, 3)) ** 2 / count
    if fit == "vertical":
        nz = np.full_like(cx, a)
    else:
        d = (a - czz) / 2
        q = np.sqrt(d * d + cx * cx + cy * cy)
        with np.errstate(divide="ignore", invalid="ignore"):
            nz = np.where(d >= 0, d + q, (cx * cx + cy * cy) / (q - d))
    n = np.stack([-cx, -cy, nz], axis=-1)
    flat = cx * cx + cy * cy <= 1e-20 * (a + czz) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        n = n / np.linalg.norm(n, axis=-1, keepdims=True)
    n[flat] = (0.0, 0.0, 1.0)
    return n


def encode(n: np.ndarray, bits: int) -> np.ndarray:
    """SPEC section 3: round((2^bits - 1) (n + 1) / 2), ties to even."""
    top = 2**bits - 1
    return np.rint((n + 1.0) * (top / 2.0)).astype(np.uint8 if bits == 8 else np.uint16)


def curvature(stored: np.ndarray, patch: int, scale: float, border: str) -> np.ndarray:
    """The mean curvature, convex positive, of the least-squares quadratic
    z = a u^2 + b uv + c v^2 + d u + e v + f over each texel's patch (texel
    units, z = scale * heights_of(stored)): the 6 x 6 design matrix solved
    by numpy's least squares, per texel."""
    z = scale * heights_of(stored)
    h, w = z.shape
    r = patch // 2
    j, i = np.mgrid[-r : r + 1, -r : r + 1]
    u, v = i.ravel().astype(np.float64), j.ravel().astype(np.float64)
    design = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=1)
    pinv = np.linalg.pinv(design)
    out = np.empty((h, w))
    for y in range(h):
        rows = border_map(border, y + j.ravel(), h)
        for x in range(w):
            cols = border_map(border, x + i.ravel(), w)
            a, b, c, d, e, _ = pinv @ z[rows, cols]
            g = 1.0 + d * d + e * e
            out[y, x] = -((1 + e * e) * 2 * a - 2 * d * e * b + (1 + d * d) * 2 * c) / (2 * g**1.5)
    return out
