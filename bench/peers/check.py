"""Checks that a benchmark output is a plausible normal map.

    python check.py [--size-only] OUT WIDTH HEIGHT [REFERENCE.png]

Prints one short line for the table and exits 0 when the output is
plausible, 1 when it is wrong (missing, unreadable, wrong size, not unit
vectors, unrelated to the reference), 2 on bad arguments.

Reads PNG and uncompressed DDS (nvcompress -rgb). With numpy and OpenCV
importable it decodes the pixels: n = 2c - 1 must be unit length (within the
8-bit rounding) with z > 0, and when REFERENCE (normalfit's output for the
same input) is given it reports how the two agree: the mean angle between
the normals (after matching sign conventions), the peer's tilt relative to
normalfit's (1.00 = same gain), and a flipped red or green channel. Without
numpy, or with --size-only (for outputs too big to decode in memory), it
checks the header's size only, and says so.
"""
import struct
import sys


def header_size(path):
    """(width, height, kind) from a PNG or DDS header, stdlib only."""
    with open(path, "rb") as f:
        head = f.read(128)
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR":
        w, h, depth, ctype = struct.unpack(">IIBB", head[16:26])
        kinds = {0: "gray", 2: "RGB", 3: "palette", 4: "gray+alpha", 6: "RGBA"}
        return w, h, f"PNG {depth}-bit {kinds.get(ctype, '?')}"
    if head[:4] == b"DDS ":
        h, w = struct.unpack("<II", head[12:20])
        return w, h, "DDS"
    raise ValueError("neither PNG nor DDS")


def read_dds(path, np):
    """Pixels of an uncompressed RGB(A) DDS as an (h, w, 3) uint8 RGB array."""
    with open(path, "rb") as f:
        data = f.read()
    h, w = struct.unpack("<II", data[12:20])
    flags, fourcc, bits, rmask, gmask, bmask = struct.unpack("<I4sIIII", data[80:104])
    if flags & 0x4:  # DDPF_FOURCC: block-compressed
        raise ValueError(f"compressed DDS ({fourcc!r}) is not decoded here")
    if bits not in (24, 32):
        raise ValueError(f"{bits}-bit DDS is not decoded here")
    step = bits // 8
    raw = np.frombuffer(data, np.uint8, count=w * h * step, offset=128)
    px = raw.reshape(h, w, step)
    if step == 4:
        px = px.view("<u4").reshape(h, w)
    else:
        px = (px[..., 0].astype(np.uint32) | px[..., 1].astype(np.uint32) << 8
              | px[..., 2].astype(np.uint32) << 16)

    def channel(mask):
        shift = (mask & -mask).bit_length() - 1
        return ((px & mask) >> shift).astype(np.uint8)

    return np.stack([channel(rmask), channel(gmask), channel(bmask)], axis=-1)


def read_rgb(path, np, cv2):
    """(h, w, 3) RGB normals in [-1, 1] as float64."""
    if open(path, "rb").read(4) == b"DDS ":
        rgb = read_dds(path, np)
        top = 255.0
    else:
        img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
        if img is None:
            raise ValueError("OpenCV cannot decode it")
        if img.ndim != 3 or img.shape[2] < 3:
            raise ValueError("not a colour image")
        rgb = img[..., 2::-1]  # BGR(A) -> RGB
        top = float(np.iinfo(img.dtype).max)
    return rgb.astype(np.float64) * (2.0 / top) - 1.0


def main():
    args = sys.argv[1:]
    size_only = bool(args) and args[0] == "--size-only"
    if size_only:
        args = args[1:]
    if len(args) not in (3, 4):
        print("usage: " + __doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    path, width, height = args[0], int(args[1]), int(args[2])
    ref = args[3] if len(args) == 4 else None
    try:
        w, h, kind = header_size(path)
    except FileNotFoundError:
        print("WRONG: no output file")
        return 1
    except (OSError, ValueError) as e:
        print(f"WRONG: {e}")
        return 1
    if (w, h) != (width, height):
        print(f"WRONG: {w}x{h}, expected {width}x{height}")
        return 1
    if size_only:
        print(f"size ok ({kind}; pixels not checked)")
        return 0
    try:
        import cv2
        import numpy as np
    except ImportError:
        print(f"size ok ({kind}; pixels not checked: no numpy/OpenCV)")
        return 0
    try:
        n = read_rgb(path, np, cv2)
    except (OSError, ValueError) as e:
        print(f"WRONG: {e}")
        return 1
    length = np.sqrt((n * n).sum(axis=-1))
    bad_len = float(np.mean(np.abs(length - 1.0) > 0.02))
    neg_z = float(np.mean(n[..., 2] <= 0.0))
    if bad_len > 0.01 or neg_z > 0.01:
        print(f"WRONG: not unit normals ({bad_len:.0%} off unit length, {neg_z:.0%} with z <= 0)")
        return 1
    if ref is None:
        print("ok")
        return 0
    r = read_rgb(ref, np, cv2)
    if r.shape != n.shape:
        print("WRONG: reference has another size")
        return 1
    notes = []
    for axis, name in ((0, "red"), (1, "green")):
        a, b = n[..., axis].ravel(), r[..., axis].ravel()
        if a.std() == 0.0 or b.std() == 0.0:
            print(f"WRONG: {name} is constant")
            return 1
        corr = float(np.corrcoef(a, b)[0, 1])
        if abs(corr) < 0.3:
            print(f"WRONG: {name} unrelated to normalfit's (r = {corr:.2f})")
            return 1
        if corr < 0:
            notes.append(f"{name} flipped")
            n[..., axis] = -n[..., axis]
    unit_n = n / np.maximum(length, 1e-9)[..., None]
    unit_r = r / np.maximum(np.sqrt((r * r).sum(axis=-1)), 1e-9)[..., None]
    cos = np.clip((unit_n * unit_r).sum(axis=-1), -1.0, 1.0)
    angle = float(np.degrees(np.arccos(cos)).mean())
    gain = float(np.sqrt((n[..., :2] ** 2).sum(axis=-1)).mean()
                 / max(np.sqrt((r[..., :2] ** 2).sum(axis=-1)).mean(), 1e-12))
    line = f"ok, Δ {angle:.1f}°, tilt ×{gain:.2f}"
    if notes:
        line += " (" + ", ".join(notes) + ")"
    print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
