"""``scratch.generate``: scatter scratches uniformly over the active mesh's surface."""
from __future__ import annotations

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty

from ...mitsuba_bridge.errors import ParameterError
from .. import storage
from .editing import (USER_ERRORS, ObjectModeOperator, check_numbers, combine, fail, metres_per_unit, plural,
                      warn_relaxed_arcs, write)
from ..mesh import check_object, world_surface
from ..geometry.scatter import ScatterSpec, estimate_bytes, expected_vertices, scatter
from .properties import LengthProperties, LooksProperties, draw_lengths, draw_looks, mode_property, seed_property
from ...mitsuba_bridge.device.memory import check_memory

__all__ = ["SCRATCH_OT_generate"]


class SCRATCH_OT_generate(ObjectModeOperator, LooksProperties, LengthProperties, bpy.types.Operator):
    """Scatter scratches uniformly over the surface of the active mesh (per area, inside UV islands, cut at seams)"""

    bl_idname = "scratch.generate"
    bl_label = "Generate Scratches"
    bl_options = {"REGISTER", "UNDO"}

    count: IntProperty(name="Count", description="Number of scratches to scatter (a scratch crossing "
                                                 "a UV seam becomes one scratch per side)",
                       default=1000, min=0, soft_min=1, soft_max=1_000_000)  # 0 is refused, not clamped
    seed: seed_property()
    mode: mode_property("generated")
    orientation: EnumProperty(
        name="Orientation", default="RANDOM",
        items=[("RANDOM", "Random", "Directions uniformly at random"),
               ("FIXED", "Fixed", "Directions at a fixed angle in the tangent space, with a spread")],
        description="How scratch directions are chosen")
    angle: FloatProperty(name="Angle", subtype="ANGLE", default=0.0,
                         description="Direction of the scratches, from the U axis towards the V axis "
                                     "of the object's tangent space (UV map)")
    angle_spread: FloatProperty(name="Spread", subtype="ANGLE", default=np.radians(10.0), min=0.0,
                                max=np.pi, description="Directions vary uniformly within ± this angle")

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=360)

    def execute(self, context):
        obj = context.active_object
        try:
            check_object(obj)
            check_numbers(self)
            surface = world_surface(obj, context.evaluated_depsgraph_get())
            length_min, length_max = self.length_range(surface)
            spec = ScatterSpec(
                count=self.count, length_min=length_min, length_max=length_max, looks=self.looks(),
                angle=None if self.orientation == "RANDOM" else self.angle, angle_spread=self.angle_spread,
                bend=self.bend, metres_per_unit=metres_per_unit(context))
            existing_bytes = storage.scratch_summary(obj)["count"] * 200 if self.mode == "ADD" else 0
            check_memory(estimate_bytes(spec.count, expected_vertices(spec)) + existing_bytes,
                         f"Generating {plural(spec.count)}", advice="ask for fewer")
            placed = scatter(surface, spec, np.random.default_rng(self.seed))
            if placed.scratches.count == 0:  # never replace scratches by nothing, nor report success
                raise ParameterError(f"None of the {plural(spec.count)} could be placed on '{obj.name}'; "
                                 "its scratches are unchanged")
            result = combine(obj, placed.scratches, self.mode)
            write(obj, result)
        except USER_ERRORS as error:
            return fail(self, error)

        warn_relaxed_arcs(self, placed)
        skipped = int((~surface.usable).sum())
        message = f"{obj.name}: generated {plural(placed.scratches.count)}"
        if placed.scratches.count != spec.count:
            message += f" from {spec.count:,} (cut at UV seams)"
        self.report({"INFO"}, message + f"; {plural(result.count)} in all")
        if skipped:
            self.report({"WARNING"}, f"{obj.name}: {plural(skipped, 'face')} without area in 3D or in "
                                     "the UV map got no scratches")
        return {"FINISHED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        column = layout.column()
        column.prop(self, "count")
        column.prop(self, "seed")
        column.row().prop(self, "mode", expand=True)
        draw_lengths(layout.column(), self)
        column = layout.column()
        column.prop(self, "orientation")
        fixed = column.column(align=True)
        fixed.active = self.orientation == "FIXED"
        fixed.prop(self, "angle")
        fixed.prop(self, "angle_spread")
        draw_looks(layout.column(), self)


register, unregister = bpy.utils.register_classes_factory((SCRATCH_OT_generate,))
