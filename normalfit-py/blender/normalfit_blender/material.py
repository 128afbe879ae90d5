"""Wiring a normal map into a material, as an artist does by hand: an
Image Texture node (Non-Color) into a Normal Map node (tangent space) into
the shader's Normal input."""

from __future__ import annotations

from typing import Any


def shader_of(tree: Any) -> Any:
    """The node the active Material Output's Surface comes from (the
    Principled BSDF of a new material), or the first Principled BSDF."""
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    output = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    if output is not None and output.inputs["Surface"].is_linked:
        node = output.inputs["Surface"].links[0].from_node
        if "Normal" in node.inputs:
            return node
    return next((n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), None)


def wire_normal_map(material: Any, image: Any) -> Any:
    """Puts `image` into `material`'s node tree as its normal map and
    returns the Normal Map node. Nodes already there are reused: the Image
    Texture node that shows `image`, and the Normal Map node it feeds.
    Raises ValueError when the material has no shader with a Normal input."""
    material.use_nodes = True
    tree = material.node_tree
    shader = shader_of(tree)
    if shader is None:
        raise ValueError(f"material {material.name!r} has no shader with a Normal input to wire the normal map into")
    texture = next((n for n in tree.nodes if n.type == "TEX_IMAGE" and n.image == image), None)
    if texture is None:
        texture = tree.nodes.new("ShaderNodeTexImage")
        texture.image = image
        texture.location = (shader.location.x - 600, shader.location.y - 300)
    texture.image.colorspace_settings.name = "Non-Color"
    fed = [link.to_node for link in texture.outputs["Color"].links if link.to_node.type == "NORMAL_MAP"]
    normal_map = fed[0] if fed else tree.nodes.new("ShaderNodeNormalMap")
    if not fed:
        normal_map.location = (shader.location.x - 250, shader.location.y - 300)
        tree.links.new(texture.outputs["Color"], normal_map.inputs["Color"])
    normal_map.space = "TANGENT"
    tree.links.new(normal_map.outputs["Normal"], shader.inputs["Normal"])
    return normal_map
