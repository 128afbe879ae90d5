"""Writes the luminance/chroma (subsampled) OpenEXR files beside this script
with OpenEXR's own library (the Python bindings, `pip install openexr`,
3.5.3 when made), so normalfit's reader is checked against files it did not
write. Run: python3 make.py. tests/integration/exr_layouts.rs knows the values:

  Y(x, y)  = ((3x + 5y) mod 17) / 8 - 1          (exact in half and float)
  A(x, y)  = ((x + 2y) mod 5) / 4
  RY, BY   = 0.25 and -0.5, sampled 2 × 2 (never heights)
"""
import numpy as np
import OpenEXR

W, H = 24, 20
y, x = np.mgrid[0:H, 0:W]
Y = ((3 * x + 5 * y) % 17) / 8.0 - 1.0
A = ((x + 2 * y) % 5) / 4.0
# The bindings take full-size arrays and keep every second sample of a
# channel sampled 2 × 2.
RY = np.full((H, W), 0.25)
BY = np.full((H, W), -0.5)


def write(name, compression, y_type=np.float16, alpha=False, **header):
    channels = {
        "Y": OpenEXR.Channel("Y", Y.astype(y_type)),
        "RY": OpenEXR.Channel("RY", RY.astype(np.float16), 2, 2),
        "BY": OpenEXR.Channel("BY", BY.astype(np.float16), 2, 2),
    }
    if alpha:
        channels["A"] = OpenEXR.Channel("A", A.astype(np.float16))
    header = dict(compression=compression, type=OpenEXR.scanlineimage, **header)
    with OpenEXR.File(header, channels) as f:
        f.write(name)


write("yc_none.exr", OpenEXR.NO_COMPRESSION)
write("yc_rle.exr", OpenEXR.RLE_COMPRESSION)
write("yc_zips.exr", OpenEXR.ZIPS_COMPRESSION)
write("yc_zip.exr", OpenEXR.ZIP_COMPRESSION)
# Float Y, a full-resolution alpha, bottom-to-top line order, and a data
# window from (-4, 6) to (19, 25): y = 6 is the first row, and the chroma
# lines are those of even y.
window = (np.array([-4, 6], dtype=np.int32), np.array([-4 + W - 1, 6 + H - 1], dtype=np.int32))
write(
    "yca_zip_float_decreasing.exr",
    OpenEXR.ZIP_COMPRESSION,
    np.float32,
    True,
    lineOrder=OpenEXR.DECREASING_Y,
    dataWindow=window,
    displayWindow=window,
)
# PIZ: refused (see docs/convert.md).
write("yc_piz.exr", OpenEXR.PIZ_COMPRESSION)
