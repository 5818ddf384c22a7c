"""The "Scratch BSDF" node group: where a scratched object's material places the scratch BSDF.

Cycles renders the group's contents (a smooth aluminium-coloured Glossy BSDF,
a stand-in); this engine replaces the group node by the object's
``scratch_diffraction`` BSDF, so a material can, for instance, mix painted metal
and scratches by a mask texture (docs/rendering.md, "Scratches in a material").
"""
from __future__ import annotations

import bpy

from .materials import SCRATCH_GROUP

__all__ = ["scratch_group", "add_scratch_node"]

#: Aluminium's normal-incidence reflectance, roughly: what Cycles shows in the group's place.
STAND_IN_COLOUR = (0.91, 0.92, 0.92, 1.0)


def scratch_group():
    """The file's "Scratch BSDF" shader node group (created once)."""
    group = bpy.data.node_groups.get(SCRATCH_GROUP)
    if group is not None and group.bl_idname == "ShaderNodeTree":
        return group
    group = bpy.data.node_groups.new(SCRATCH_GROUP, "ShaderNodeTree")
    group.interface.new_socket(name="BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    output = group.nodes.new("NodeGroupOutput")
    glossy = group.nodes.new("ShaderNodeBsdfAnisotropic")
    glossy.inputs["Color"].default_value = STAND_IN_COLOUR
    glossy.inputs["Roughness"].default_value = 0.0
    group.links.new(glossy.outputs["BSDF"], output.inputs["BSDF"])
    return group


def add_scratch_node(material):
    """A group node of :func:`scratch_group` in ``material``'s node tree (not connected)."""
    node = material.node_tree.nodes.new("ShaderNodeGroup")
    node.node_tree = scratch_group()
    node.label = SCRATCH_GROUP
    return node
