"""The brushes: ``scratch.paint_stroke`` and ``scratch.erase_stroke``, and their viewport tools.

Both are stroke operators (:mod:`.stroke`): interactive from the "Scratch
Brush" and "Scratch Eraser" tools of the 3D viewport's toolbar in Object Mode,
and replayable from scripts through their ``stroke`` property.
"""
from __future__ import annotations

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty

from ...mitsuba_bridge.errors import ParameterError
from ...mitsuba_bridge.scratch import ScratchSet
from .. import storage
from ..geometry.brush import pen_scratches, pressure_factor, spray_centres_with_pressure, stroke_pressure
from ..operators.editing import USER_ERRORS, check_numbers, combine, fail, plural, metres_per_unit, warn_relaxed_arcs, write
from ..geometry.erase import cut_scratches, touched_scratches
from ..geometry.lines import scratch_lines
from ..mesh import MeshError, cached, matrix_key, picker_for
from ..geometry.scatter import MAX_LENGTH_PER_SIZE, estimate_bytes, scratches_from_centres
from ..operators.properties import (LengthProperties, LooksProperties, StrokeProperties, draw_lengths, draw_looks,
                       seed_property)
from .stroke import SNAP_FRACTION, StrokeOperator, stroke_runs
from ...mitsuba_bridge.device.memory import check_memory
from ..geometry.uvmap import UVLocator

__all__ = ["SCRATCH_OT_paint_stroke", "SCRATCH_OT_erase_stroke", "SCRATCH_TOOL_brush", "SCRATCH_TOOL_eraser"]


def _stroke_on_surface(operator, context):
    """(object, surface, picker, runs) for a replayed stroke; raises errors for the user."""
    obj = context.active_object
    check_numbers(operator)
    picker = picker_for(obj, context.evaluated_depsgraph_get())
    surface = picker.surface
    locations, starts = operator.stroke_arrays()
    if len(locations) == 0:
        raise ParameterError("The stroke is empty")
    bad = ~np.isfinite(locations).all(axis=1)
    if bad.any():
        raise ParameterError(f"{plural(int(bad.sum()), 'stroke point')} of {len(locations)} "
                         f"{'is' if bad.sum() == 1 else 'are'} not a finite location")
    if operator.radius > MAX_LENGTH_PER_SIZE * surface.size:
        raise ParameterError(f"Radius ({operator.radius:.4g}) is more than {MAX_LENGTH_PER_SIZE:g} times the "
                         f"object's size ({surface.size:.4g}, its bounding box diagonal)")
    runs = stroke_runs(picker, locations, starts, SNAP_FRACTION * surface.size, operator.stroke_pressures())
    if not runs:
        raise MeshError(f"The stroke misses '{obj.name}': none of its {len(locations)} points "
                        "lies on the surface")
    return obj, surface, picker, runs


# Peak bytes per sample of the eraser's resampled strokes and scratches (3D and UV points, masks; with margin).
_BYTES_PER_SAMPLE = 400


def _length(runs) -> float:
    return sum(float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in runs)


def _samples(length: float, radius: float, pieces: int) -> int:
    """Samples of a polyline of ``length`` in ``pieces`` resampled every ``radius / 4``."""
    return int(min(4.0 * length / radius, 2.0**62)) + pieces


def _count(value: float) -> str:
    return f"{value:,.0f}" if value < 1e12 else f"{value:.3g}"


class SCRATCH_OT_paint_stroke(StrokeOperator, StrokeProperties, LooksProperties, LengthProperties,
                              bpy.types.Operator):
    """Paint scratches along a stroke on the active mesh: one scratch following it (Pen) or many around it (Spray)"""

    bl_idname = "scratch.paint_stroke"
    bl_label = "Paint Scratches"
    bl_options = {"REGISTER", "UNDO"}
    _header = "Scratch Brush"

    brush_mode: EnumProperty(
        name="Brush", default="PEN",
        items=[("PEN", "Pen", "One scratch following the stroke", "GREASEPENCIL", 0),
               ("SPRAY", "Spray", "Many scratches scattered around the stroke", "PARTICLES", 1)],
        description="What a stroke paints")
    density: FloatProperty(
        name="Density", default=5.0, min=0.0, soft_max=100.0,
        description="Spray: scratches per brush radius of stroke (a click sprays this many on average)")
    jitter: FloatProperty(
        name="Direction Jitter", subtype="ANGLE", default=np.radians(15.0), min=0.0, max=np.pi,
        description="Spray: scratch directions follow the stroke within ± this angle")
    seed: seed_property()
    # Per-setting pressure toggles, as on Blender's own brushes (off: a tablet paints as a mouse).
    use_pressure_width: BoolProperty(
        name="Width Pressure", default=False,
        description="Scale the scratch width by the pen pressure (the pen: its mean along the stroke)")
    use_pressure_depth: BoolProperty(
        name="Depth Pressure", default=False,
        description="Scale the scratch depth by the pen pressure (the pen: its mean along the stroke)")
    use_pressure_density: BoolProperty(
        name="Density Pressure", default=False,
        description="Spray: scale the number of scratches along the stroke by the pen pressure there")

    def _pressed(self, params: dict, pressure) -> dict:
        """``params`` (Looks.sample arrays) with width and depth scaled as the pressure toggles say."""
        params = dict(params)
        params["width"] = params["width"] * pressure_factor(pressure, self.use_pressure_width)
        params["depth"] = params["depth"] * pressure_factor(pressure, self.use_pressure_depth)
        return params

    def execute(self, context):
        try:
            obj, surface, picker, runs = _stroke_on_surface(self, context)
            looks = self.looks()
            rng = np.random.default_rng(self.seed)
            if self.brush_mode == "PEN":
                placed = pen_scratches(surface, [(t, b) for t, b, _, _ in runs],
                                       self._pressed(looks.sample(rng, 1),
                                                     stroke_pressure([p for _, _, p, _ in runs],
                                                                     [q for _, _, _, q in runs])))
            else:
                placed = self._spray(context, surface, picker, runs, looks, rng)
            if placed.scratches.count == 0:
                self.report({"WARNING"}, "The stroke is too short to paint a scratch" if self.brush_mode == "PEN"
                            else "The spray placed no scratch on the surface (raise the density?)")
                return {"CANCELLED"}
            result = combine(obj, placed.scratches, "ADD")
            write(obj, result)
        except USER_ERRORS as error:
            return fail(self, error)
        warn_relaxed_arcs(self, placed)
        self.report({"INFO"}, f"{obj.name}: painted {plural(placed.scratches.count)}; "
                              f"{plural(result.count)} in all")
        return {"FINISHED"}

    def _spray(self, context, surface, picker, runs, looks, rng):
        length_min, length_max = self.length_range(surface)
        if self.density <= 0:
            raise ParameterError("Density is 0: the spray would paint nothing")
        travelled = sum(float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for _, _, p, _ in runs)
        expected = self.density * (len(runs) + travelled / self.radius)
        check_memory(estimate_bytes(min(expected, 2.0**62) + 1), f"Spraying about {_count(expected)} scratches",
                     advice="lower the density or the radius")
        centres, directions, pressure = spray_centres_with_pressure(
            rng, [p for _, _, p, _ in runs], [surface.normal[t] for t, _, _, _ in runs], [q for _, _, _, q in runs],
            self.radius, self.density, self.jitter, self.use_pressure_density)
        triangle, bary, _, hit = picker.nearest(centres, 0.5 * self.radius + SNAP_FRACTION * surface.size)
        triangle, bary, directions, pressure = triangle[hit], bary[hit], directions[hit], pressure[hit]
        count = len(triangle)
        undirected = ~np.any(directions != 0, axis=1)
        directions[undirected] = surface.direction(triangle[undirected],
                                                   rng.uniform(0.0, 2.0 * np.pi, int(undirected.sum())))
        length = rng.uniform(length_min, length_max, count)
        bend = rng.uniform(-self.bend, self.bend, count) if self.bend > 0 else np.zeros(count)
        return scratches_from_centres(surface, triangle, bary, directions, length,
                                      self._pressed(looks.sample(rng, count), pressure),
                                      bend=bend, metres_per_unit=metres_per_unit(context))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.row().prop(self, "brush_mode", expand=True)
        layout.prop(self, "seed")
        spray = layout.column()
        spray.active = self.brush_mode == "SPRAY"
        spray.prop(self, "radius")
        spray.prop(self, "density")
        spray.prop(self, "jitter")
        draw_lengths(spray, self)
        draw_looks(layout.column(), self)
        _draw_pressure(layout, self)


class SCRATCH_OT_erase_stroke(StrokeOperator, StrokeProperties, bpy.types.Operator):
    """Erase the scratches of the active mesh under the stroke (within the brush radius)"""

    bl_idname = "scratch.erase_stroke"
    bl_label = "Erase Scratches"
    bl_options = {"REGISTER", "UNDO"}
    _header = "Scratch Eraser"

    erase_mode: EnumProperty(
        name="Erase", default="CUT",
        items=[("CUT", "Cut", "Remove the parts of scratches under the brush; the rest stays"),
               ("WHOLE", "Whole Scratches", "Remove every scratch the brush touches, entirely")],
        description="What the eraser removes")

    def execute(self, context):
        try:
            obj, surface, _, runs = _stroke_on_surface(self, context)
            scratches, _, digest = storage.read_scratch_file(obj)
            if scratches.count == 0:
                self.report({"INFO"}, f"{obj.name} has no scratches to erase")
                return {"CANCELLED"}
            locator = cached("uv_locator", obj, None, lambda: UVLocator(surface.uv, surface.usable))
            key = (digest, matrix_key(obj))  # the bytes' digest: lines never outlive the set they map
            lines = cached("erase_lines", obj, key, lambda: scratch_lines(scratches, locator, surface.corners))
            stroke_points = [p for _, _, p, _ in runs]
            # The stroke is sampled every radius / 4: a tiny radius on a long stroke costs memory.
            check_memory(_BYTES_PER_SAMPLE * _samples(_length(stroke_points), self.radius, len(runs)),
                         f"Erasing with a radius of {self.radius:.3g}", advice="use a larger radius")
            touched = touched_scratches(lines.a, lines.b, lines.scratch, stroke_points, self.radius,
                                        scratches.count)
            if not touched.any():
                self.report({"INFO"}, "No scratch under the stroke")
                return {"CANCELLED"}
            kept = scratches.select(~touched)
            remaining_lines = lines.without(touched)
            if self.erase_mode == "CUT":
                # ... and so is every touched scratch, along its whole length.
                cut_length = float(np.linalg.norm(lines.b - lines.a, axis=1)[touched[lines.scratch]].sum())
                check_memory(_BYTES_PER_SAMPLE * _samples(cut_length, self.radius, int(touched.sum())),
                             f"Cutting {plural(int(touched.sum()))} with a radius of {self.radius:.3g}",
                             advice="use a larger radius")

                def to_surface(uv):
                    triangle, bary = locator.locate(uv)
                    return surface.point(np.maximum(triangle, 0), bary), triangle >= 0

                cut, _ = cut_scratches(scratches.select(touched), to_surface, stroke_points, self.radius)
                result = ScratchSet.concatenate([kept, cut])
                remaining_lines = remaining_lines.followed_by(scratch_lines(cut, locator, surface.corners),
                                                              kept.count)
            else:
                result = kept
            digest = write(obj, result)
            # The next stroke starts from these lines instead of mapping every scratch again.
            cached("erase_lines", obj, (digest, matrix_key(obj)), lambda: remaining_lines)
        except USER_ERRORS as error:
            return fail(self, error)
        if self.erase_mode == "CUT":
            self.report({"INFO"}, f"{obj.name}: cut {plural(int(touched.sum()))} under the stroke; "
                                  f"{plural(result.count)} now")
        else:
            self.report({"INFO"}, f"{obj.name}: erased {plural(int(touched.sum()))}; "
                                  f"{plural(result.count)} left")
        return {"FINISHED"}

    def draw(self, context):
        self.layout.use_property_split = True
        self.layout.row().prop(self, "erase_mode", expand=True)
        self.layout.prop(self, "radius")


def _draw_pressure(layout, props) -> None:
    column = layout.column(heading="Pen Pressure", align=True)
    column.prop(props, "use_pressure_width", text="Width")
    column.prop(props, "use_pressure_depth", text="Depth")
    row = column.row(align=True)
    row.active = props.brush_mode == "SPRAY"
    row.prop(props, "use_pressure_density", text="Density")


# --------------------------------------------------------------------- tools
def _tool_properties(context, idname):
    tool = context.workspace.tools.from_space_view3d_mode("OBJECT", create=False)
    return None if tool is None else tool.operator_properties(idname)


def _draw_brush_cursor(context, xy, radius, colour):
    """The brush outline: the radius as a circle on the surface under the mouse, else a small ring."""
    import gpu
    from bpy_extras import view3d_utils
    from gpu_extras.batch import batch_for_shader
    from gpu_extras.presets import draw_circle_2d

    obj = context.active_object
    region, view = context.region, context.region_data
    outline = None
    if obj is not None and obj.type == "MESH" and view is not None and radius is not None:
        try:
            picker = picker_for(obj, context.evaluated_depsgraph_get())
        except USER_ERRORS:
            picker = None
        if picker is not None:
            # Cursors get window coordinates and draw in window space; views use region coordinates.
            mouse = (xy[0] - region.x, xy[1] - region.y)
            hit = picker.ray_cast(view3d_utils.region_2d_to_origin_3d(region, view, mouse),
                                  view3d_utils.region_2d_to_vector_3d(region, view, mouse))
            if hit is not None:
                triangle, _, centre = hit
                surface = picker.surface
                angle = np.linspace(0.0, 2.0 * np.pi, 48, endpoint=False)
                ring = (centre + radius * (np.cos(angle)[:, None] * surface.tangent[triangle]
                                           + np.sin(angle)[:, None] * surface.bitangent[triangle]))
                projected = [view3d_utils.location_3d_to_region_2d(region, view, p) for p in ring]
                if all(p is not None for p in projected):
                    outline = [(p.x + region.x, p.y + region.y) for p in projected]
    if outline is None:
        draw_circle_2d(xy, (colour[0], colour[1], colour[2], 0.5), 6.0, segments=16)
        return
    shader = gpu.shader.from_builtin("UNIFORM_COLOR")
    batch = batch_for_shader(shader, "LINE_LOOP", {"pos": outline})
    gpu.state.blend_set("ALPHA")
    shader.uniform_float("color", colour)
    batch.draw(shader)
    gpu.state.blend_set("NONE")


class _ScratchTool(bpy.types.WorkSpaceTool):
    """A brush of the 3D viewport's toolbar in Object Mode; ``operator`` runs on a left-drag."""

    bl_space_type = "VIEW_3D"
    bl_context_mode = "OBJECT"
    bl_widget = None


def _left_drag(operator: str):
    return ((operator, {"type": "LEFTMOUSE", "value": "PRESS"}, None),)


class SCRATCH_TOOL_brush(_ScratchTool):
    bl_idname = "scratch_iridescence.brush"
    bl_label = "Scratch Brush"
    bl_description = ("Paint microscopic scratches on the active mesh: drag to paint; "
                      "Pen draws one scratch along the stroke, Spray scatters many around it")
    bl_icon = "ops.gpencil.draw"
    operator = SCRATCH_OT_paint_stroke.bl_idname
    bl_keymap = _left_drag(operator)
    colour = (1.0, 0.6, 0.1, 0.9)

    def draw_settings(context, layout, tool):
        props = tool.operator_properties(SCRATCH_TOOL_brush.operator)
        layout.prop(props, "brush_mode", expand=True)
        row = layout.row(align=True)
        row.active = props.brush_mode == "SPRAY"
        row.prop(props, "radius")
        row.prop(props, "density")
        row.prop(props, "use_pressure_density", text="", icon="STYLUS_PRESSURE")
        layout.popover("SCRATCH_PT_brush_scratches")

    def draw_cursor(context, tool, xy):
        props = tool.operator_properties(SCRATCH_TOOL_brush.operator)
        radius = props.radius if props.brush_mode == "SPRAY" else None
        _draw_brush_cursor(context, xy, radius, SCRATCH_TOOL_brush.colour)


class SCRATCH_TOOL_eraser(_ScratchTool):
    bl_idname = "scratch_iridescence.eraser"
    bl_label = "Scratch Eraser"
    bl_description = "Erase the scratches under the stroke (within the brush radius)"
    bl_icon = "ops.gpencil.draw.eraser"
    operator = SCRATCH_OT_erase_stroke.bl_idname
    bl_keymap = _left_drag(operator)
    colour = (0.3, 0.8, 1.0, 0.9)

    def draw_settings(context, layout, tool):
        props = tool.operator_properties(SCRATCH_TOOL_eraser.operator)
        layout.prop(props, "erase_mode", expand=True)
        layout.prop(props, "radius")

    def draw_cursor(context, tool, xy):
        props = tool.operator_properties(SCRATCH_TOOL_eraser.operator)
        _draw_brush_cursor(context, xy, props.radius, SCRATCH_TOOL_eraser.colour)


class SCRATCH_PT_brush_scratches(bpy.types.Panel):
    """Popover of the Scratch Brush: what the painted scratches look like"""

    bl_space_type = "VIEW_3D"
    bl_region_type = "HEADER"
    bl_label = "Scratches"
    bl_ui_units_x = 14

    def draw(self, context):
        props = _tool_properties(context, SCRATCH_OT_paint_stroke.bl_idname)
        if props is None:
            return
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        spray = layout.column()
        spray.active = props.brush_mode == "SPRAY"
        spray.prop(props, "jitter")
        draw_lengths(spray, props)
        draw_looks(layout.column(), props)
        _draw_pressure(layout, props)


_CLASSES = (SCRATCH_OT_paint_stroke, SCRATCH_OT_erase_stroke, SCRATCH_PT_brush_scratches)
_TOOLS = (SCRATCH_TOOL_brush, SCRATCH_TOOL_eraser)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.utils.register_tool(SCRATCH_TOOL_brush, after={"builtin.annotate"}, separator=True, group=False)
    bpy.utils.register_tool(SCRATCH_TOOL_eraser, after={SCRATCH_TOOL_brush.bl_idname}, group=False)


def unregister():
    for tool in reversed(_TOOLS):
        bpy.utils.unregister_tool(tool)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
