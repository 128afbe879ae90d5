"""Normal maps from height maps inside Blender, through the normalfit package.

Two ways to use it:

* In Blender's UI: run this file once from the Text Editor (or install it as
  an add-on). The Image Editor's *Image* menu gains *Normal Map from Height
  (normalfit)*: it makes ``<name>_normal`` from the image shown, a new
  image Blender holds, ready for a Normal Map node.
* Headless, in a pipeline or a test::

      blender -b --python examples/blender/normal_map.py -- \\
          height.png normal.png [--patch 5] [--scale 4] [--border auto] \\
          [--convention opengl] [--bits 8|16]

  loads ``height.png`` as Blender does, makes its normal map and saves it
  with Blender's own PNG writer.

The pixels are the command line's, bit for bit: an 8- or 16-bit image's
stored values are recovered exactly from Blender's floats (v / 255 or
v / 65535) and handed to ``normalfit.normals`` as integers, and the
encoded RGB it returns is written back as Blender stores it.

``import normalfit`` must work in Blender's Python: install the wheel
where that Python looks (``pip install --target DIR normalfit-*.whl`` and
start Blender with ``--python-use-system-env`` and ``PYTHONPATH=DIR``).
"""

from __future__ import annotations

import argparse
import sys

import bpy
import numpy as np

import normalfit

bl_info = {
    "name": "Normal Map from Height (normalfit)",
    "blender": (3, 0, 0),
    "category": "Image",
    "description": "Least-squares plane-fit normal maps from height maps",
}


def stored_heights(image: bpy.types.Image) -> np.ndarray:
    """The image's first channel as stored: uint8 or uint16 for integer
    files, float32 for float ones; rows top to bottom."""
    # Non-Color: Blender hands the stored values over untransformed.
    image.colorspace_settings.name = "Non-Color"
    width, height = image.size
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    first = pixels.reshape(height, width, image.channels)[::-1, :, 0]
    if image.is_float and image.depth <= 64:
        # A 16-bit integer file: Blender holds v / 65535 in float32, which
        # rounds back to v exactly.
        return np.rint(first * 65535.0).astype(np.uint16)
    if image.is_float:
        return np.ascontiguousarray(first)
    return np.rint(first * 255.0).astype(np.uint8)


def make_normal_map(image: bpy.types.Image, name: str, bits: int = 8, **options) -> bpy.types.Image:
    """A new Blender image holding the normal map of ``image``'s heights.

    ``options`` are ``normalfit.normals``'s (patch, fit, border,
    convention, scale, relief, invert)."""
    dtype = {8: np.uint8, 16: np.uint16}[bits]
    rgb = normalfit.normals(stored_heights(image), dtype=dtype, **options)
    height, width, _ = rgb.shape
    top = float(np.iinfo(dtype).max)
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[:, :, :3] = rgb / top
    out = bpy.data.images.new(name, width, height, alpha=False, float_buffer=bits == 16, is_data=True)
    out.colorspace_settings.name = "Non-Color"
    # Blender's rows run bottom to top.
    out.pixels.foreach_set(rgba[::-1].ravel())
    out.update()
    return out


def save_png(image: bpy.types.Image, path: str, bits: int) -> None:
    """Saves with Blender's PNG writer, as the user's File > Save would."""
    scene = bpy.context.scene
    settings = scene.render.image_settings
    settings.file_format = "PNG"
    settings.color_mode = "RGB"
    settings.color_depth = str(bits)
    settings.compression = 15
    # No view transform on save: the normals are data, not a picture.
    scene.view_settings.view_transform = "Standard"
    image.save_render(path, scene=scene)


class IMAGE_OT_normalfit_normal_map(bpy.types.Operator):
    """Make a normal map of the image shown, by normalfit's plane fits"""

    bl_idname = "image.normalfit_normal_map"
    bl_label = "Normal Map from Height (normalfit)"
    bl_options = {"REGISTER", "UNDO"}

    patch: bpy.props.IntProperty(name="Patch", default=3, min=3, max=63, step=2)
    scale: bpy.props.FloatProperty(name="Scale", default=1.0)
    border: bpy.props.EnumProperty(
        name="Border",
        items=[(b, b.title(), "") for b in ("wrap", "clamp", "mirror", "auto")],
        default="wrap",
    )
    convention: bpy.props.EnumProperty(
        name="Convention",
        items=[("opengl", "OpenGL (Blender)", ""), ("directx", "DirectX", "")],
        default="opengl",
    )

    @classmethod
    def poll(cls, context):
        space = context.space_data
        return space is not None and space.type == "IMAGE_EDITOR" and space.image is not None

    def execute(self, context):
        source = context.space_data.image
        try:
            normal = make_normal_map(
                source,
                f"{source.name}_normal",
                patch=self.patch,
                scale=self.scale,
                border=self.border,
                convention=self.convention,
            )
        except (ValueError, TypeError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        context.space_data.image = normal
        return {"FINISHED"}


def menu(self, context):
    self.layout.operator(IMAGE_OT_normalfit_normal_map.bl_idname)


def register():
    bpy.utils.register_class(IMAGE_OT_normalfit_normal_map)
    bpy.types.IMAGE_MT_image.append(menu)


def unregister():
    bpy.types.IMAGE_MT_image.remove(menu)
    bpy.utils.unregister_class(IMAGE_OT_normalfit_normal_map)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="normal_map.py", description=__doc__.splitlines()[0])
    parser.add_argument("input")
    parser.add_argument("output")
    parser.add_argument("--patch", type=int, default=3)
    parser.add_argument("--fit", default="orthogonal")
    parser.add_argument("--border", default="wrap")
    parser.add_argument("--convention", default="opengl")
    parser.add_argument("--scale", type=float)
    parser.add_argument("--bits", type=int, choices=(8, 16), default=8)
    args = parser.parse_args(argv)
    try:
        source = bpy.data.images.load(args.input, check_existing=False)
    except RuntimeError as e:
        print(f"normal_map.py: {args.input}: {e}", file=sys.stderr)
        return 2
    options = {"patch": args.patch, "fit": args.fit, "border": args.border, "convention": args.convention}
    if args.scale is not None:
        options["scale"] = args.scale
    try:
        normal = make_normal_map(source, "normal", bits=args.bits, **options)
    except (ValueError, TypeError, OSError) as e:
        print(f"normal_map.py: {args.input}: {e}", file=sys.stderr)
        return 2
    save_png(normal, args.output, args.bits)
    print(f"normal_map.py: {args.input} -> {args.output} ({normal.size[0]}x{normal.size[1]}, {args.bits}-bit)")
    return 0


if __name__ == "__main__":
    if "--" in sys.argv:
        # Headless: blender -b --python normal_map.py -- INPUT OUTPUT [options]
        sys.exit(main(sys.argv[sys.argv.index("--") + 1 :]))
    register()
