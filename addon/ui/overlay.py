"""Viewport overlay: the active object's scratches drawn on its surface, coloured by depth or width.

The line data is built with numpy by pure functions (:mod:`.lines`, tested
headless) and cached per object, keyed by the scratch token (changes on every
write, restored by undo), the colour mode and the mesh state (:func:`.mesh.cached`),
so drawing an unchanged object only draws.  The GPU shader and batch are made
lazily inside the draw callback: background Blender has no GPU.  Lines are
drawn in object space under the object's matrix, so moving the object costs
nothing; they are lifted off the surface by a small fraction of the object's
size to stay visible.

Damaged stored scratches draw nothing; the failure is cached like the lines
(one decode attempt per change, not one per redraw) and the Scratches panel
shows its message (:func:`overlay_error`).
"""
from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from ...mitsuba_bridge.scratch import ScratchFormatError
from .. import storage
from ..operators.editing import USER_ERRORS
from ..geometry.lines import overlay_arrays, scratch_lines
from ..mesh import cached, mesh_arrays, peek
from ..geometry.uvmap import UVLocator

__all__ = ["OverlayData", "overlay_data", "overlay_error", "drawable_data", "register", "unregister"]

#: Lines are lifted off the surface by this fraction of the object's size.
LIFT_FRACTION = 2e-4
LINE_WIDTH = 1.5


@dataclass(frozen=True, eq=False)
class OverlayData:
    """What the overlay draws for one object: vertex positions and colours (float32)."""

    positions: np.ndarray
    colours: np.ndarray
    value_range: tuple[float, float]
    unplaced: int
    key: tuple


def overlay_data(obj, depsgraph) -> OverlayData:
    """The overlay's arrays for ``obj`` (cached; see the module docstring)."""
    token = storage.scratch_token(obj)
    colour_by = obj.scratch_iridescence.overlay_color_by

    def build_lines():
        try:
            scratches = storage.read_scratches(obj)
        except ScratchFormatError as error:
            return _Unreadable(token, error)
        arrays = mesh_arrays(obj, depsgraph)
        corners = arrays.corners
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1), 1e-300)[:, None]
        size = float(np.linalg.norm(arrays.positions.max(axis=0) - arrays.positions.min(axis=0)))
        return scratch_lines(scratches, UVLocator(arrays.triangle_uv), corners, normal,
                             offset=LIFT_FRACTION * size)

    def build_arrays():
        lines = cached("overlay_lines", obj, token, build_lines)
        if isinstance(lines, _Unreadable):
            raise lines.error.with_traceback(None)
        positions, colours, value_range = overlay_arrays(lines, colour_by)
        return OverlayData(positions, colours, value_range, lines.unplaced, (token, colour_by, id(lines)))

    return cached("overlay", obj, (token, colour_by), build_arrays)


@dataclass(frozen=True)
class _Unreadable:
    """A stored set that failed to decode, cached in place of its lines."""

    token: str | None
    error: ScratchFormatError


def overlay_error(obj) -> str | None:
    """The message of the last failure to read ``obj``'s stored scratches for the overlay, if still current."""
    lines = peek("overlay_lines", obj)
    if isinstance(lines, _Unreadable) and lines.token == storage.scratch_token(obj):
        return str(lines.error)
    return None


# ------------------------------------------------------------------ drawing
_gpu_state = {"shader": None, "batch": None, "key": None}
_handle = []


def _visible(context, obj) -> bool:
    space = context.space_data
    overlay = getattr(space, "overlay", None)
    return (obj is not None and obj.type == "MESH" and obj.mode == "OBJECT"
            and overlay is not None and overlay.show_overlays
            and obj.scratch_iridescence.show_overlay and storage.has_scratches(obj) and obj.visible_get())


def drawable_data(context):
    """The overlay data of the active object, or None when there is nothing to draw.

    A user error (a mesh the overlay cannot use) draws nothing; the panel and the
    operators report it.  Anything else is a bug and raises.
    """
    obj = context.active_object
    if not _visible(context, obj):
        return None
    try:
        data = overlay_data(obj, context.view_layer.depsgraph)
    except USER_ERRORS:
        return None
    return data if len(data.positions) else None


def _draw():
    context = bpy.context
    if bpy.app.background:
        return
    data = drawable_data(context)
    if data is None:
        return
    obj = context.active_object
    import gpu
    from gpu_extras.batch import batch_for_shader

    if _gpu_state["shader"] is None:
        _gpu_state["shader"] = gpu.shader.from_builtin("POLYLINE_SMOOTH_COLOR")
    shader = _gpu_state["shader"]
    if _gpu_state["key"] != data.key:
        _gpu_state["batch"] = batch_for_shader(shader, "LINES", {"pos": data.positions, "color": data.colours})
        _gpu_state["key"] = data.key
    gpu.matrix.push()
    gpu.matrix.multiply_matrix(obj.matrix_world)
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.blend_set("ALPHA")
    shader.uniform_float("viewportSize", gpu.state.viewport_get()[2:])
    shader.uniform_float("lineWidth", LINE_WIDTH)
    _gpu_state["batch"].draw(shader)
    gpu.state.blend_set("NONE")
    gpu.state.depth_test_set("NONE")
    gpu.matrix.pop()


def register():
    if not _handle:
        _handle.append(bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_VIEW"))


def unregister():
    while _handle:
        bpy.types.SpaceView3D.draw_handler_remove(_handle.pop(), "WINDOW")
    _gpu_state.update(shader=None, batch=None, key=None)
