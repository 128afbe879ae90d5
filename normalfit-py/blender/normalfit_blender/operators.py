"""The add-on's operators (`bpy.ops.normalfit.*`), its menu entries and
its preferences, which install the normalfit package into Blender's own
Python when it is missing."""

from __future__ import annotations

import importlib
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from platform import machine as platform_machine
from typing import Any

import bpy

from . import images, material

ADDON = __package__ or "normalfit_blender"

FITS = [
    ("orthogonal", "Orthogonal", "Least squares of the distances to the plane (the default)"),
    ("vertical", "Vertical", "Least squares of the height differences (Prewitt's gradient at 3×3)"),
]
BORDERS = [
    ("wrap", "Wrap", "The image tiles: patches wrap around its edges"),
    ("clamp", "Clamp", "Edge texels repeat"),
    ("mirror", "Mirror", "The image is mirrored at its edges"),
    ("auto", "Auto", "Wrap where the image tiles, else mirror (normalfit's seam check)"),
]
CONVENTIONS = [
    ("opengl", "OpenGL (Blender)", "Green up: what Blender's Normal Map node expects"),
    ("directx", "DirectX", "Green down: for engines that use DirectX's convention"),
]
CHANNELS = [
    ("luma", "Luma", "0.2126 R + 0.7152 G + 0.0722 B of a colour image (a gray image: its gray)"),
    ("r", "R", "Red"),
    ("g", "G", "Green"),
    ("b", "B", "Blue"),
    ("a", "A", "Alpha"),
]


def package() -> Any:
    """The normalfit package, or ImportError saying how to install it."""
    try:
        return importlib.import_module("normalfit")
    except ImportError as e:
        raise ImportError(
            "the normalfit package is not installed in Blender's Python: install its wheel from the add-on's "
            "preferences (Edit > Preferences > Add-ons > normalfit), or see docs/blender.md"
        ) from e


def chosen_image(context: Any, name: str) -> Any:
    """The image named `name`, or the one the editor shows: the Image
    Editor's image, or the active Image Texture node's."""
    if name:
        image = bpy.data.images.get(name)
        if image is None:
            raise ValueError(f"no image named {name!r} in this file")
        return image
    space = getattr(context, "space_data", None)
    if space is not None and space.type == "IMAGE_EDITOR" and space.image is not None:
        return space.image
    node = getattr(context, "active_node", None)
    if node is not None and node.type == "TEX_IMAGE" and node.image is not None:
        return node.image
    raise ValueError("no image: name one (image=...), or show one in the Image Editor or an active Image Texture node")


class HeightMapOperator:
    """What the operators that read an image of heights share: the image,
    the options of the fit they all take, and showing the image they make.
    A mix-in, as Blender's API documents them: its property annotations
    are registered on each operator class that inherits them."""

    image: bpy.props.StringProperty(name="Image", description="The height map (default: the image shown)")
    patch: bpy.props.IntProperty(
        name="Patch", description="The patch's side N (odd): larger is smoother", default=3, min=3, max=1023, step=2
    )
    scale: bpy.props.FloatProperty(
        name="Scale", description="Texel widths the full height range spans", default=1.0, min=0.0, soft_max=64.0
    )
    border: bpy.props.EnumProperty(name="Border", items=BORDERS, default="wrap")
    invert: bpy.props.BoolProperty(name="Invert", description="Dark is high", default=False)
    channel: bpy.props.EnumProperty(name="Channel", items=CHANNELS, default="luma")

    def heights(self, context: Any) -> tuple[Any, Any, Any]:
        """The package, the source image and its heights."""
        normalfit = package()
        source = chosen_image(context, self.image)
        return normalfit, source, images.stored_heights(source, self.channel)

    def show(self, context: Any, made: Any) -> set[str]:
        """Shows `made` in the Image Editor the operator ran from, and says
        what was made."""
        space = getattr(context, "space_data", None)
        if space is not None and space.type == "IMAGE_EDITOR":
            space.image = made
        self.report({"INFO"}, f"{made.name}: {made.size[0]}×{made.size[1]}, N = {self.patch}")
        return {"FINISHED"}


class NORMALFIT_OT_normal_map(HeightMapOperator, bpy.types.Operator):
    """Make the normal map of an image of heights by normalfit's least-squares plane fits"""

    bl_idname = "normalfit.normal_map"
    bl_label = "Normal Map from Height (normalfit)"
    bl_options = {"REGISTER", "UNDO"}

    fit: bpy.props.EnumProperty(name="Fit", items=FITS, default="orthogonal")
    convention: bpy.props.EnumProperty(name="Convention", items=CONVENTIONS, default="opengl")
    wire: bpy.props.BoolProperty(
        name="Wire into Material",
        description="Connect the map to the active object's material through a Normal Map node",
        default=False,
    )

    def execute(self, context: Any) -> set[str]:
        try:
            normalfit, source, heights = self.heights(context)
            normals = normalfit.normals(
                heights,
                patch=self.patch,
                scale=self.scale,
                fit=self.fit,
                border=self.border,
                convention=self.convention,
                invert=self.invert,
                dtype="float32",
            )
            made = images.put_rgb(bpy.data, f"{source.name}_normal", images.encoded(normals))
            if self.wire:
                self.wire_into_material(context, made)
        except (ImportError, ValueError, TypeError, OSError, MemoryError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return self.show(context, made)

    def wire_into_material(self, context: Any, made: Any) -> None:
        target = getattr(context, "object", None)
        mat = target.active_material if target is not None else None
        if mat is None:
            raise ValueError("Wire into Material needs an active object with a material")
        material.wire_normal_map(mat, made)
        if self.convention != "opengl":
            self.report({"WARNING"}, "Blender's Normal Map node reads OpenGL normals: this DirectX map will look inverted")


class NORMALFIT_OT_curvature(HeightMapOperator, bpy.types.Operator):
    """Make the curvature map of an image of heights: the mean curvature of normalfit's least-squares quadratic over each patch, convex positive"""

    bl_idname = "normalfit.curvature"
    bl_label = "Curvature from Height (normalfit)"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context: Any) -> set[str]:
        try:
            normalfit, source, heights = self.heights(context)
            values = normalfit.curvature(
                heights, patch=self.patch, scale=self.scale, border=self.border, invert=self.invert
            )
            # The curvature as it is (1 / texel width, convex positive) in
            # R, G and B of a float, non-colour image.
            made = images.put_rgb(bpy.data, f"{source.name}_curvature", images.gray(values))
        except (ImportError, ValueError, TypeError, OSError, MemoryError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return self.show(context, made)


class NORMALFIT_OT_install_package(bpy.types.Operator):
    """Install the normalfit package (a wheel file) into Blender's own Python"""

    bl_idname = "normalfit.install_package"
    bl_label = "Install normalfit Wheel"

    filepath: bpy.props.StringProperty(subtype="FILE_PATH")
    filter_glob: bpy.props.StringProperty(default="*.whl", options={"HIDDEN"})

    def invoke(self, context: Any, event: Any) -> set[str]:
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context: Any) -> set[str]:
        try:
            folder = install_wheel(Path(self.filepath))
        except (OSError, RuntimeError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"normalfit installed in {folder}")
        return {"FINISHED"}


def install_wheel(wheel: Path) -> Path:
    """Installs `wheel` into Blender's user modules folder, which Blender
    puts on its Python's path: the package then loads in every session,
    without touching Blender's installation. With pip where Blender's
    Python has it (or gets it from ensurepip, as Blender's bundled Python
    does); a distribution's Python without pip gets the wheel unpacked
    (`unpack_wheel`). NumPy is not installed: Blender brings its own.
    Returns the folder."""
    if wheel.suffix != ".whl" or not wheel.is_file():
        raise OSError(f"{wheel}: not a wheel file (normalfit-*.whl)")
    folder = Path(bpy.utils.user_resource("SCRIPTS", path="modules", create=True))
    pip = [sys.executable, "-m", "pip"]
    if subprocess.run([*pip, "--version"], capture_output=True).returncode != 0:
        subprocess.run([sys.executable, "-m", "ensurepip", "--upgrade"], capture_output=True, check=False)
    if subprocess.run([*pip, "--version"], capture_output=True).returncode == 0:
        done = subprocess.run(
            [*pip, "install", "--upgrade", "--no-deps", "--target", str(folder), str(wheel)],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            last = (done.stderr.strip().splitlines() or ["pip failed"])[-1]
            raise RuntimeError(f"{wheel.name}: {last}")
    else:
        unpack_wheel(wheel, folder)
    if str(folder) not in sys.path:
        sys.path.append(str(folder))
    importlib.invalidate_caches()
    return folder


def unpack_wheel(wheel: Path, folder: Path) -> None:
    """Installs `wheel` into `folder` without pip, as the wheel format
    defines it for a package like normalfit's (no scripts, no data):
    unpacked as it is. Checks first what pip would: a CPython wheel of an
    older or equal minor version (abi3), built for this machine's
    architecture. The old package's files are replaced."""
    parts = wheel.stem.split("-")
    if len(parts) < 5:
        raise OSError(f"{wheel.name}: not a wheel's name (name-version-python-abi-platform.whl)")
    python, platform = parts[-3], parts[-1]
    minor = sys.version_info[1]
    if not python.startswith("cp3") or int(python[3:] or 99) > minor:
        raise RuntimeError(f"{wheel.name}: built for {python}, and Blender's Python is 3.{minor}")
    # Wheels name x86-64 and ARM64 machines either way (amd64, arm64 on
    # Windows and macOS).
    same = {"amd64": "x86_64", "arm64": "aarch64"}
    machine = same.get(platform_machine().lower(), platform_machine().lower())
    if machine not in platform.replace("amd64", "x86_64").replace("arm64", "aarch64"):
        raise RuntimeError(f"{wheel.name}: built for {platform}, and this machine is {machine}")
    with zipfile.ZipFile(wheel) as z:
        tops = {name.split("/")[0] for name in z.namelist()}
        for top in tops:
            shutil.rmtree(folder / top, ignore_errors=True)
        z.extractall(folder)


class NormalfitPreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON

    def draw(self, context: Any) -> None:
        layout = self.layout
        try:
            normalfit = package()
        except ImportError:
            layout.label(text="The normalfit package is not installed in Blender's Python.", icon="ERROR")
            layout.operator(NORMALFIT_OT_install_package.bl_idname, icon="IMPORT")
            return
        version = getattr(normalfit, "__version__", "")
        layout.label(text=f"normalfit {version} from {Path(normalfit.__file__).parent}", icon="CHECKMARK")
        layout.operator(NORMALFIT_OT_install_package.bl_idname, text="Install Another Wheel", icon="IMPORT")


def image_menu(self: Any, context: Any) -> None:
    self.layout.operator(NORMALFIT_OT_normal_map.bl_idname)
    self.layout.operator(NORMALFIT_OT_curvature.bl_idname)


CLASSES = (NORMALFIT_OT_normal_map, NORMALFIT_OT_curvature, NORMALFIT_OT_install_package, NormalfitPreferences)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.IMAGE_MT_image.append(image_menu)


def unregister() -> None:
    bpy.types.IMAGE_MT_image.remove(image_menu)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
