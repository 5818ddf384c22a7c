"""Interactive strokes: mouse → surface points → a replayable ``stroke`` collection.

:class:`StrokeOperator` is the modal half of the brush operators, in the
manner of Blender's paint operators: ``invoke`` starts a stroke, ``modal``
extends it while the button is held (rays from the mouse onto the active
object), releasing the button fills ``stroke`` with ``OperatorStrokeElement``
items (world-space ``location``; ``is_start`` marks where the stroke came back
onto the surface) and calls ``execute``, which only ever reads ``stroke``.
Scripts and tests call ``execute`` directly with their own ``stroke``.

Viewport navigation passes through; Esc or right-click cancels, restoring the
header, status bar and drawing exactly as they were (nothing is written before
the stroke ends).  :class:`StrokeDrawer` owns everything drawn meanwhile.
"""
from __future__ import annotations

import random
import time

import bpy
import numpy as np

from ..operators.editing import USER_ERRORS, ObjectModeOperator, fail
from ..mesh import Picker, check_object, picker_for

__all__ = ["StrokeOperator", "StrokeDrawer", "stroke_runs", "NAVIGATION_EVENTS"]

#: Events handed to the viewport during a stroke (orbit, pan, zoom).
NAVIGATION_EVENTS = {
    "MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "WHEELINMOUSE", "WHEELOUTMOUSE",
    "TRACKPADPAN", "TRACKPADZOOM", "MOUSEROTATE", "MOUSESMARTZOOM",
    "NDOF_MOTION", "NDOF_BUTTON_FIT", "NDOF_BUTTON_TOP", "NDOF_BUTTON_FRONT", "NDOF_BUTTON_RIGHT",
    "NUMPAD_1", "NUMPAD_2", "NUMPAD_3", "NUMPAD_4", "NUMPAD_5", "NUMPAD_6", "NUMPAD_7", "NUMPAD_8",
    "NUMPAD_9", "NUMPAD_0", "NUMPAD_PERIOD",
}

#: A replayed stroke point farther than this fraction of the object's size from it misses.
SNAP_FRACTION = 0.01


def stroke_runs(picker: Picker, locations, is_start, max_distance: float, pressure=None):
    """Snap stroke points to the surface and cut the stroke where it leaves it.

    Returns a list of runs, each (triangle, bary, point, pressure) arrays of
    consecutive points on the surface; a new run starts at every ``is_start``
    point and after every point that misses (farther than ``max_distance``).
    ``pressure`` (N,) is the tablet pressure of each point (default 1).
    """
    locations = np.asarray(locations, dtype=np.float64).reshape(-1, 3)
    if len(locations) == 0:
        return []
    triangle, bary, point, hit = picker.nearest(locations, max_distance)
    is_start = np.asarray(is_start, dtype=bool)
    pressure = np.ones(len(locations)) if pressure is None else np.asarray(pressure, dtype=np.float64)
    starts = is_start | np.r_[True, ~hit[:-1]]
    run_id = np.cumsum(starts)
    runs = []
    for run in np.unique(run_id[hit]):
        member = hit & (run_id == run)
        runs.append((triangle[member], bary[member], point[member], pressure[member]))
    return runs


class StrokeDrawer:
    """Header and status text plus the stroke preview, for the life of one stroke.

    Saves nothing it cannot restore: ``restore`` clears the texts it set and
    removes its draw handler.  GPU objects are made inside the draw callback.
    """

    def __init__(self, context, header: str, status: str, colour=(1.0, 0.6, 0.1, 0.9)):
        self.area = context.area
        self.workspace = context.workspace
        self.points: list[tuple[float, float, float]] = []
        self.colour = colour
        self._handle = None
        if self.area is not None:
            self.area.header_text_set(header)
        if self.workspace is not None:
            self.workspace.status_text_set(status)
        if not bpy.app.background:
            self._handle = bpy.types.SpaceView3D.draw_handler_add(self._draw, (), "WINDOW", "POST_VIEW")

    def redraw(self):
        if self.area is not None:
            self.area.tag_redraw()

    def restore(self):
        if self._handle is not None:
            bpy.types.SpaceView3D.draw_handler_remove(self._handle, "WINDOW")
            self._handle = None
        if self.area is not None:
            self.area.header_text_set(None)
            self.area.tag_redraw()
        if self.workspace is not None:
            self.workspace.status_text_set(None)

    def _draw(self):
        if len(self.points) < 2:
            return
        import gpu
        from gpu_extras.batch import batch_for_shader

        shader = gpu.shader.from_builtin("POLYLINE_UNIFORM_COLOR")
        batch = batch_for_shader(shader, "LINE_STRIP", {"pos": self.points})
        gpu.state.blend_set("ALPHA")
        shader.uniform_float("viewportSize", gpu.state.viewport_get()[2:])
        shader.uniform_float("lineWidth", 2.0)
        shader.uniform_float("color", self.colour)
        batch.draw(shader)
        gpu.state.blend_set("NONE")


class StrokeOperator(ObjectModeOperator):
    """Mixin for brush operators: the modal stroke (see the module docstring).

    Subclasses define ``execute`` (reading ``self.stroke``), ``_header`` and
    ``_status``; a ``seed`` property, if any, gets a fresh value per stroke
    unless set by the caller.
    """

    _header = "Scratch stroke"
    _status = "LMB drag: stroke  ·  Esc / RMB: cancel  ·  MMB / wheel: navigate"

    def invoke(self, context, event):
        obj = context.active_object
        try:
            check_object(obj)
            self._picker = picker_for(obj, context.evaluated_depsgraph_get())
        except USER_ERRORS as error:
            return fail(self, error)
        if context.area is None or context.area.type != "VIEW_3D" or context.region_data is None:
            return self.execute(context)  # not in a viewport: replay whatever stroke was given
        if "seed" in self.properties.bl_rna.properties and not self.properties.is_property_set("seed"):
            self.seed = random.randrange(2**31)
        self._samples = []  # (location, mouse, is_start, time, pressure)
        self._off_surface = True
        self._started = time.monotonic()
        self._drawer = StrokeDrawer(context, f"{self._header}: drag over {obj.name}", self._status)
        self._sample(context, event)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type in NAVIGATION_EVENTS:
            return {"PASS_THROUGH"}
        if event.type in {"MOUSEMOVE", "INBETWEEN_MOUSEMOVE"}:
            self._sample(context, event)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "RELEASE":
            return self._end(context)
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            self._drawer.restore()
            self.report({"INFO"}, "Stroke cancelled")
            return {"CANCELLED"}
        return {"RUNNING_MODAL"}

    # -- begin / extend / end
    def _sample(self, context, event):
        from bpy_extras import view3d_utils

        mouse = (event.mouse_region_x, event.mouse_region_y)
        origin = view3d_utils.region_2d_to_origin_3d(context.region, context.region_data, mouse)
        direction = view3d_utils.region_2d_to_vector_3d(context.region, context.region_data, mouse)
        hit = self._picker.ray_cast(origin, direction)
        if hit is None:
            self._off_surface = True
            return
        _, _, point = hit
        # a mouse reports 1.0; a tablet its pen's pressure (recorded, so that execute replays it)
        self._samples.append((tuple(point), mouse, self._off_surface, time.monotonic() - self._started,
                              float(event.pressure)))
        self._off_surface = False
        self._drawer.points.append(tuple(point))
        self._drawer.redraw()

    def _end(self, context):
        self._drawer.restore()
        self.stroke.clear()
        for location, mouse, is_start, moment, pressure in self._samples:
            element = self.stroke.add()
            element.name = ""
            element.location = location
            element.mouse = mouse
            element.mouse_event = mouse
            element.pressure = pressure
            element.is_start = is_start
            element.time = moment
        if not self._samples:
            self.report({"WARNING"}, "The stroke never touched the surface")
            return {"CANCELLED"}
        return self.execute(context)

    # -- replay helpers for execute()
    def stroke_arrays(self):
        """(locations (N, 3), is_start (N,)) of the ``stroke`` collection."""
        count = len(self.stroke)
        locations = np.empty(count * 3, dtype=np.float32)
        starts = np.zeros(count, dtype=bool)
        if count:
            self.stroke.foreach_get("location", locations)
            starts = np.array([element.is_start for element in self.stroke], dtype=bool)
        return locations.reshape(-1, 3).astype(np.float64), starts

    def stroke_pressures(self) -> np.ndarray:
        """(N,) tablet pressure (0–1) of the ``stroke`` collection's points."""
        pressure = np.empty(len(self.stroke), dtype=np.float32)
        if len(pressure):
            self.stroke.foreach_get("pressure", pressure)
        return pressure.astype(np.float64)
