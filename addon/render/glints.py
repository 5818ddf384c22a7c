"""Can the scene's lights show a scratched object's glints? The Scratches panel's verdict and the one click
that fixes it (Add Glint Lighting).

Blender's startup cube under its point light is a dark mirror once scratched: a light that comes from one
direction shows glints only near the mirror direction (:mod:`mitsuba_bridge.scene.glints`). The panel
asks :func:`glint_check` (cached until the next depsgraph update), the render report says the same
(gather), and :class:`SCRATCH_OT_add_glint_lighting` adds a sun where the camera (or the 3D view) sees
the object's largest facing facet mirror it.
"""
from __future__ import annotations

import math
from typing import Optional

import bpy
import numpy as np
from bpy.app.handlers import persistent
from bpy.props import FloatProperty

from ...mitsuba_bridge.scene import SkyWorld
from ...mitsuba_bridge.scene.glints import GlintCheck, check_glints, mirror_light_direction, surface_samples
from ...mitsuba_bridge.scratch import ScratchFormatError
from ..storage import has_scratches, read_scratches
from .gather.camera import gather_camera
from .gather.lights import gather_light
from .gather.materials import linked_node
from .gather.meshes import mesh_parts
from .gather.report import Warnings
from .gather.world import sky_from_node
from .view import view_camera

__all__ = ["glint_check", "SCRATCH_OT_add_glint_lighting", "GLINT_SUN_NAME", "GLINT_SUN_STRENGTH"]

GLINT_SUN_NAME = "Glint Sun"
#: W/m². The scratches gather the sun's irradiance into the few degrees of their reach, so the lit scratches'
#: radiance is tens of times the irradiance per steradian: Blender's default sun (1 W/m²) clips them to a white
#: blob under the default AgX view (the startup cube: 2.1 % of its image at white). At 0.05 the halo's core
#: mostly stays below white (0.3 %), still 9× the grey world (tests/addon/test_glint_lighting.py).
GLINT_SUN_STRENGTH = 0.05
_checks: dict = {}
_generation = [0]


@persistent
def _changed(*_args):
    _generation[0] += 1


def _surfaces(obj, depsgraph):
    """(centres, normals) of ``obj``'s evaluated triangles in world space."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        parts = mesh_parts(mesh, obj.name)
    finally:
        evaluated.to_mesh_clear()
    samples = [surface_samples(part, np.array(obj.matrix_world)) for _, part in parts]
    if not samples:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return tuple(np.concatenate([sample[i] for sample in samples]) for i in (0, 1))


def _lights(scene, depsgraph) -> list:
    warnings = Warnings()
    lights = (gather_light(obj.evaluated_get(depsgraph), np.array(obj.matrix_world), warnings)
              for obj in scene.objects if obj.type == "LIGHT" and not obj.hide_render)
    return [light for light in lights if light is not None]


def _world(world):
    """What of the world can show glints: "environment" (an image, assumed to), a :class:`SkyWorld` (its sun), or
    None (a uniform colour or black: no glints). Images are not read: this runs as the panel redraws."""
    tree = world.node_tree if world is not None else None
    output = tree.get_output_node("CYCLES") if tree is not None else None
    background = linked_node(output.inputs["Surface"]) if output is not None else None
    if background is None or background.bl_idname != "ShaderNodeBackground":
        return None
    source = linked_node(background.inputs["Color"])
    if source is None:
        return None
    if source.bl_idname == "ShaderNodeTexEnvironment":
        return "environment"
    if source.bl_idname == "ShaderNodeTexSky":
        return sky_from_node(source, float(background.inputs["Strength"].default_value), Warnings())
    return None


def _emissive(scene) -> bool:
    """Whether a visible object's material emits (an extended light: counted as able to show glints)."""
    for obj in scene.objects:
        if obj.hide_render or obj.type not in ("MESH", "CURVE", "SURFACE", "FONT", "META"):
            continue
        for slot in obj.material_slots:
            tree = slot.material.node_tree if slot.material is not None else None
            for node in tree.nodes if tree is not None else ():
                if node.bl_idname == "ShaderNodeEmission" and node.inputs["Strength"].default_value > 0:
                    return True
                if node.bl_idname == "ShaderNodeBsdfPrincipled" and \
                        node.inputs["Emission Strength"].default_value > 0:
                    return True
    return False


def glint_check(context, obj) -> Optional[GlintCheck]:
    """Whether the scene's lights can show ``obj``'s glints, seen by the scene camera (None: no scratches or no
    camera to judge by). Cached until Blender reports the next change."""
    scene = getattr(context, "scene", None) or bpy.context.scene
    if obj is None or obj.type != "MESH" or not has_scratches(obj) or scene.camera is None:
        return None
    key = (obj.name_full, scene.name_full, _generation[0])
    if key not in _checks:
        _checks.clear()
        depsgraph = bpy.context.evaluated_depsgraph_get()
        try:
            scratches = read_scratches(obj)
        except ScratchFormatError:
            return None  # the panel shows the damage already
        world = _world(scene.world)
        camera = gather_camera(scene, scene.camera, Warnings())
        _checks[key] = check_glints(_surfaces(obj, depsgraph), scratches, camera, _lights(scene, depsgraph),
                                    world if isinstance(world, SkyWorld) else None,
                                    emissive=world == "environment" or _emissive(scene))
    return _checks[key]


class SCRATCH_OT_add_glint_lighting(bpy.types.Operator):
    """Add a sun where the camera sees the active object mirror it, so that its scratches glint"""

    bl_idname = "scratch.add_glint_lighting"
    bl_label = "Add Glint Lighting"
    bl_options = {"REGISTER", "UNDO"}

    strength: FloatProperty(name="Strength", description="The sun's strength (irradiance, W/m²)",
                            default=GLINT_SUN_STRENGTH, min=0.0, soft_max=100.0)

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def _camera(self, context):
        """The scene camera's view, else the 3D view's (the operator run from a viewport without a camera)."""
        if context.scene.camera is not None:
            return gather_camera(context.scene, context.scene.camera, Warnings())
        region = getattr(context, "region_data", None)
        if region is None:
            return None
        return view_camera(region.view_matrix, region.window_matrix, region.is_perspective)

    def execute(self, context):
        obj = context.active_object
        camera = self._camera(context)
        if camera is None:
            self.report({"ERROR"}, "No camera to place the light for: add a camera, or run this from a 3D view")
            return {"CANCELLED"}
        surfaces = _surfaces(obj, context.evaluated_depsgraph_get())
        found = mirror_light_direction(surfaces, camera)
        if found is None:
            self.report({"ERROR"}, f"The camera sees no face of '{obj.name}' to mirror a light in")
            return {"CANCELLED"}
        direction, point = found
        light = bpy.data.lights.new(GLINT_SUN_NAME, "SUN")
        light.energy = self.strength
        sun = bpy.data.objects.new(GLINT_SUN_NAME, light)
        context.collection.objects.link(sun)
        # a sun shines along its local −Z: point its +Z at the mirror direction; placed there, for the outliner
        sun.rotation_euler = _track_z(direction)
        size = max(obj.dimensions) if max(obj.dimensions) > 0 else 1.0
        sun.location = point + direction * 3.0 * size
        self.report({"INFO"}, f"Added '{sun.name}' {math.degrees(math.asin(np.clip(direction[2], -1, 1))):.0f}° "
                              f"above the horizon, where '{obj.name}' mirrors it into the camera")
        return {"FINISHED"}


def _track_z(direction) -> tuple:
    from mathutils import Vector

    return tuple(Vector(direction).to_track_quat("Z", "Y").to_euler())


def register():
    bpy.utils.register_class(SCRATCH_OT_add_glint_lighting)
    for handlers in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.undo_post,
                     bpy.app.handlers.redo_post, bpy.app.handlers.load_post):
        if _changed not in handlers:
            handlers.append(_changed)


def unregister():
    for handlers in (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.undo_post,
                     bpy.app.handlers.redo_post, bpy.app.handlers.load_post):
        if _changed in handlers:
            handlers.remove(_changed)
    _checks.clear()
    bpy.utils.unregister_class(SCRATCH_OT_add_glint_lighting)
