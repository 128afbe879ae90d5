"""Runs inside Blender for test_blender.py, as a user would: installs the
add-on from its zip, enables it, and runs its operator.

    blender -b --factory-startup --python-use-system-env \\
        --python blender_driver.py -- ADDON.zip JOB.json

JOB.json: {"source": image file, "operator": "normal_map" (the default)
or "curvature", "options": the operator's keywords,
"cli": the command line's float EXR of the same map (or null),
"wire": whether to make an object with a material to wire into,
"install": a wheel to install through the add-on's preferences (or null),
"unpack" and "into": a wheel to unpack into a folder, without pip (or null),
"out": an .npz to write}. The .npz holds `made` (the operator's image, `heights_normal` or `heights_curvature`,
float32 RGB, rows top to bottom), `cli` (the EXR as Blender reads it),
`links` (the material's links, "from_node.socket>to_node.socket") and
`error` (the operator's message when it refused). Exit 1 on anything
unexpected, with its traceback.
"""

from __future__ import annotations

import json
import sys
import traceback

import bpy
import numpy as np


def pixels_rgb(image: bpy.types.Image) -> np.ndarray:
    width, height = image.size
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, image.channels)[::-1, :, :3].copy()


def main(addon_zip: str, job_path: str) -> None:
    with open(job_path) as f:
        job = json.load(f)
    bpy.ops.preferences.addon_install(filepath=addon_zip, overwrite=True)
    bpy.ops.preferences.addon_enable(module="normalfit_blender")
    result: dict[str, np.ndarray] = {}
    if job.get("install"):
        from normalfit_blender import operators

        folder = operators.install_wheel(__import__("pathlib").Path(job["install"]))
        import normalfit

        result["installed"] = np.array(str(folder))
        result["imported"] = np.array(normalfit.__file__)
    if job.get("unpack"):
        from pathlib import Path

        from normalfit_blender import operators

        operators.unpack_wheel(Path(job["unpack"]), Path(job["into"]))
        sys.path.insert(0, job["into"])
        import normalfit

        result["imported"] = np.array(normalfit.__file__)
    source = bpy.data.images.load(job["source"], check_existing=False)
    source.name = "heights"
    if job.get("wire"):
        bpy.ops.mesh.primitive_plane_add()
        material = bpy.data.materials.new("ground")
        material.use_nodes = True
        bpy.context.object.data.materials.append(material)
    operator = job.get("operator", "normal_map")
    made = "heights" + {"normal_map": "_normal", "curvature": "_curvature"}[operator]
    try:
        getattr(bpy.ops.normalfit, operator)(image=job.get("image", "heights"), **job["options"])
    except RuntimeError as e:
        # The operator's report: Blender raises it in background mode.
        result["error"] = np.array(str(e))
    else:
        result["made"] = pixels_rgb(bpy.data.images[made])
        result["colorspace"] = np.array(bpy.data.images[made].colorspace_settings.name)
        result["is_float"] = np.array(bpy.data.images[made].is_float)
    if job.get("cli"):
        result["cli"] = pixels_rgb(bpy.data.images.load(job["cli"], check_existing=False))
    if job.get("wire"):
        tree = bpy.context.object.active_material.node_tree
        links = [f"{l.from_node.type}.{l.from_socket.name}>{l.to_node.type}.{l.to_socket.name}" for l in tree.links]
        images = [n.image.name for n in tree.nodes if n.type == "TEX_IMAGE" and n.image is not None]
        result["links"] = np.array(sorted(links))
        result["textures"] = np.array(images)
    np.savez(job["out"], **result)


if __name__ == "__main__":
    try:
        main(*sys.argv[sys.argv.index("--") + 1 :])
    except Exception:
        traceback.print_exc()
        sys.exit(1)
    sys.exit(0)
