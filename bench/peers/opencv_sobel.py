"""Benchmark peer: normal map from cv2.Sobel.

    python opencv_sobel.py IN.png OUT.png S

Reads the height map with cv2.imread(IMREAD_UNCHANGED) (16-bit stays
16-bit); cv2.Sobel (3x3, float32 output, OpenCV's default border
BORDER_REFLECT_101 = mirror: cv2.Sobel does not take BORDER_WRAP) with the
scale folded in, so each sum becomes S * slope of h = value / max; the
normal is (-S*dh/dx, +S*dh/drow, 1) normalised with OpenCV's own array
operations (OpenGL, green up), written as round(255 * (n + 1) / 2) in an
8-bit RGB PNG with cv2.imwrite.
"""
import sys

import cv2
import numpy as np


def main():
    src, dst, scale = sys.argv[1], sys.argv[2], float(sys.argv[3])
    img = cv2.imread(src, cv2.IMREAD_UNCHANGED)
    if img is None:
        sys.exit(f"opencv_sobel: cannot read {src}")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    k = scale / 8.0 / float(np.iinfo(img.dtype).max)
    nx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=-k)
    ny = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=k)
    length = cv2.magnitude(cv2.magnitude(nx, ny), np.ones_like(nx))
    # z = 1 / |n|; x, y divided by |n|; then c = (n + 1) / 2 in [0, 255].
    nz = cv2.divide(1.0, length)
    bgr = cv2.merge([nz, cv2.divide(ny, length), cv2.divide(nx, length)])
    out = cv2.convertScaleAbs(bgr, alpha=127.5, beta=127.5)
    if not cv2.imwrite(dst, out):
        sys.exit(f"opencv_sobel: cannot write {dst}")


if __name__ == "__main__":
    main()
