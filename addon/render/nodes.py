"""Shader Editor → Add → Shader → Scratch BSDF: places the scratch BSDF inside a material.

The operator adds the "Scratch BSDF" node group (``gather/scratch_group.py``) to
the active object's active material and, by default, mixes it with the shader
already connected to the output through a Mix Shader at factor 1 (scratches
everywhere, as without the group); connecting a mask to the factor then limits
the scratches to where the mask is white (docs/rendering.md, "Scratches in a material").
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty

from .gather.materials import linked_node
from .gather.scratch_group import add_scratch_node

__all__ = ["SCRATCH_OT_add_scratch_bsdf"]


class SCRATCH_OT_add_scratch_bsdf(bpy.types.Operator):
    """Add the Scratch BSDF node group to the active material; Mitsuba Scratch renders the object's scratches
    where it is (Cycles shows a smooth metal stand-in)"""

    bl_idname = "scratch.add_scratch_bsdf"
    bl_label = "Scratch BSDF"
    bl_options = {"REGISTER", "UNDO"}

    mix: BoolProperty(name="Mix with the Current Shader", default=True,
                      description="Insert a Mix Shader (factor 1) between the current surface shader and the "
                                  "output, with the Scratch BSDF as its second shader")

    @classmethod
    def poll(cls, context):
        obj = context.object
        material = obj.active_material if obj is not None else None
        if material is None or material.node_tree is None:
            cls.poll_message_set("The active object needs a material with shader nodes")
            return False
        return True

    def execute(self, context):
        material = context.object.active_material
        tree = material.node_tree
        output = tree.get_output_node("CYCLES")
        group = add_scratch_node(material)
        if output is None:
            self.report({"INFO"}, "Added the Scratch BSDF node; connect it to a Material Output")
            return {"FINISHED"}
        group.location = (output.location.x - 200, output.location.y - 200)
        current = linked_node(output.inputs["Surface"])
        if current is None or not self.mix:
            if current is None:
                tree.links.new(group.outputs[0], output.inputs["Surface"])
            return {"FINISHED"}
        mix = tree.nodes.new("ShaderNodeMixShader")
        mix.location = (output.location.x - 180, output.location.y)
        mix.inputs["Fac"].default_value = 1.0
        tree.links.new(output.inputs["Surface"].links[0].from_socket, mix.inputs[1])
        tree.links.new(group.outputs[0], mix.inputs[2])
        tree.links.new(mix.outputs[0], output.inputs["Surface"])
        return {"FINISHED"}


def _menu(self, context):
    if getattr(context.space_data, "tree_type", "") == "ShaderNodeTree":
        self.layout.operator(SCRATCH_OT_add_scratch_bsdf.bl_idname, text="Scratch BSDF (Mitsuba Scratch)")


def register():
    bpy.utils.register_class(SCRATCH_OT_add_scratch_bsdf)
    bpy.types.NODE_MT_category_shader_shader.append(_menu)


def unregister():
    bpy.types.NODE_MT_category_shader_shader.remove(_menu)
    bpy.utils.unregister_class(SCRATCH_OT_add_scratch_bsdf)
