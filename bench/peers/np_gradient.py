"""Benchmark peer: normal map from numpy.gradient (central differences).

    python np_gradient.py IN.png OUT.png S

Reads the height map with cv2.imread(IMREAD_UNCHANGED) (16-bit stays
16-bit), h = value / max in [0, 1]; np.gradient gives the slope per texel
(central differences inside, one-sided at the edges); the normal is
(-S*dh/dx, +S*dh/drow, 1) normalised (OpenGL, green up), written as
round(255 * (n + 1) / 2) in an 8-bit RGB PNG with cv2.imwrite.
"""
import sys

import cv2
import numpy as np


def main():
    src, dst, scale = sys.argv[1], sys.argv[2], float(sys.argv[3])
    img = cv2.imread(src, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit(f"np_gradient: cannot read {src}")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    h = img.astype(np.float32) / np.float32(np.iinfo(img.dtype).max)
    d_row, d_x = np.gradient(h)
    nx = -scale * d_x
    ny = scale * d_row
    inv = 1.0 / np.sqrt(nx * nx + ny * ny + 1.0)
    # OpenCV writes BGR: blue = z, green = y, red = x.
    bgr = np.stack([inv, ny * inv, nx * inv], axis=-1)
    out = np.rint((bgr + 1.0) * 127.5).astype(np.uint8)
    if not cv2.imwrite(dst, out):
        sys.exit(f"np_gradient: cannot write {dst}")


if __name__ == "__main__":
    main()
