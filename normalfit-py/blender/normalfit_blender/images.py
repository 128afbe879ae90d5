"""Heights out of a Blender image, normals into one: the conversions that
make the add-on's pixels the command line's, bit for bit.

Blender hands every image over as float32 RGBA, rows bottom to top. With
the Non-Color colour space those floats are the stored values over the
largest one (v / 255, v / 65535), which round back to v exactly; the
heights are then taken by the contract's channel rule (docs/spec.md §1),
as `normalfit convert` takes them from the file:

* a gray image (Blender expands gray to R = G = B): the gray values, as
  integers of the file's depth, or floats for a float image;
* a colour image: the chosen channel, by default the luma
  0.2126 R + 0.7152 G + 0.0722 B of the stored values in contract units,
  formed in float64 in the library's order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

LUMA = (0.2126, 0.7152, 0.0722)
CHANNELS = ("luma", "r", "g", "b", "a")


def rgba_of(image: Any) -> np.ndarray:
    """The image's pixels as Blender holds them, float32 (rows, columns, 4),
    rows top to bottom as in the file. Sets the Non-Color colour space, so
    that the floats are the stored values, untransformed."""
    image.colorspace_settings.name = "Non-Color"
    width, height = image.size
    if width == 0 or height == 0:
        raise ValueError(f"image {image.name!r} has no pixels (is its file missing?)")
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    planes = pixels.reshape(height, width, image.channels)[::-1]
    if image.channels < 4:
        # Gray (1) or gray + alpha (2) buffers: the gray stands for R, G, B.
        gray = planes[:, :, :1]
        alpha = planes[:, :, 1:2] if image.channels == 2 else np.ones_like(gray)
        planes = np.concatenate([gray, gray, gray, alpha], axis=2)
    return planes


def integer_dtype(image: Any) -> type[np.integer] | None:
    """The stored integer type of an image loaded from a file, or None for
    floats (OpenEXR, HDR, a generated float image). Blender holds a 16-bit
    PNG or TIFF in a float buffer of 4 × 16 bits (`depth` ≤ 64)."""
    if not image.is_float:
        return np.uint8
    if image.depth <= 64 and image.source == "FILE" and image.file_format in {"PNG", "TIFF"}:
        return np.uint16
    return None


def stored_heights(image: Any, channel: str = "luma") -> np.ndarray:
    """The image's heights by the contract's channel rule: uint8 or uint16
    stored values for integer files (gray), float32 for float images
    (gray), float64 contract units for a colour image's luma, or the named
    channel (`r`, `g`, `b`, `a`) of a colour image."""
    if channel not in CHANNELS:
        raise ValueError(f"channel must be one of {', '.join(CHANNELS)}, got {channel!r}")
    rgba = rgba_of(image)
    integer = integer_dtype(image)
    if integer is not None:
        top = float(np.iinfo(integer).max)
        stored: np.ndarray = np.rint(rgba * np.float32(top)).astype(integer)
    else:
        stored = rgba
    red, green, blue = (stored[:, :, c] for c in range(3))
    gray = bool(np.array_equal(red, green) and np.array_equal(red, blue))
    if channel == "a":
        return np.ascontiguousarray(stored[:, :, 3])
    if gray:
        return np.ascontiguousarray(red)
    if channel != "luma":
        return np.ascontiguousarray(stored[:, :, "rgb".index(channel)])
    # The library's luma: each channel in contract units (v · (1 / max) for
    # integers), then 0.2126 r + 0.7152 g + 0.0722 b, left to right, in f64.
    unit = 1.0 / float(np.iinfo(integer).max) if integer is not None else 1.0
    r, g, b = (plane.astype(np.float64) * unit for plane in (red, green, blue))
    return (LUMA[0] * r + LUMA[1] * g) + LUMA[2] * b


def encoded(normals: np.ndarray) -> np.ndarray:
    """The stored colours c = (n + 1) / 2 of float32 unit normals, in
    float32 as the command line's float (EXR) output stores them."""
    return (normals + np.float32(1.0)) * np.float32(0.5)


def gray(values: np.ndarray) -> np.ndarray:
    """A (rows, columns) float32 plane as (rows, columns, 3), R = G = B."""
    return np.repeat(values[:, :, np.newaxis], 3, axis=2).astype(np.float32, copy=False)


def put_rgb(bpy_data: Any, name: str, rgb: np.ndarray) -> Any:
    """A float, non-colour Blender image `name` holding `rgb` ((rows,
    columns, 3) float32, rows top to bottom), alpha 1. An image of that
    name and size is reused (its pixels replaced, so the materials that use
    it follow); otherwise a new one is made (Blender numbers a name that is
    taken by an image of another size)."""
    height, width, _ = rgb.shape
    image = bpy_data.images.get(name)
    if image is None or tuple(image.size) != (width, height) or not image.is_float or image.source != "GENERATED":
        image = bpy_data.images.new(name, width, height, alpha=False, float_buffer=True, is_data=True)
    image.colorspace_settings.name = "Non-Color"
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[:, :, :3] = rgb
    # Blender's rows run bottom to top.
    image.pixels.foreach_set(rgba[::-1].ravel())
    image.update()
    return image
