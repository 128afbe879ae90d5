"""normalfit in Blender: normal maps of image datablocks by least-squares
plane fits, the command line's pixels bit for bit.

Installs from a zip like any add-on (`python normalfit-py/blender/build_zip.py`
makes it; Edit > Preferences > Add-ons > Install…). Adds
`bpy.ops.normalfit.normal_map(image=NAME, patch=3, scale=1.0, fit=…,
border=…, convention=…, invert=…, channel=…, wire=…)`, which makes
`NAME_normal` (float, Non-Color) and can wire it into the active
material, and the Image Editor's Image > Normal Map from Height entry. The
normalfit package must be importable in Blender's Python: the add-on's
preferences install its wheel there (docs/blender.md).
"""

from __future__ import annotations

bl_info = {
    "name": "normalfit",
    "author": "normalfit",
    "version": (0, 1, 0),
    "blender": (3, 0, 0),
    "location": "Image Editor > Image > Normal Map from Height (normalfit)",
    "description": "Least-squares plane-fit normal maps from height maps",
    "category": "Image",
}


def register() -> None:
    from . import operators

    operators.register()


def unregister() -> None:
    from . import operators

    operators.unregister()
