"""``scratch.clear``, ``scratch.import_file`` and ``scratch.export_file``.

Exporting writes the bytes stored in the .blend (a format-v1 file, see
:mod:`.storage`) unchanged, so exporting an unchanged object twice gives
identical files.  Files are written atomically (``scratch.save_bytes``: a
temporary file, then a rename).
"""
from __future__ import annotations

from pathlib import Path

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ...mitsuba_bridge import scratch
from ...mitsuba_bridge.scratch import ScratchSet
from .. import storage
from .editing import USER_ERRORS, ObjectModeOperator, combine, fail, plural, write
from ..mesh import MeshError, check_object, mesh_arrays
from .properties import mode_property
from ..geometry.uvmap import UVLocator

__all__ = ["SCRATCH_OT_clear", "SCRATCH_OT_import_file", "SCRATCH_OT_export_file"]


class SCRATCH_OT_clear(ObjectModeOperator, bpy.types.Operator):
    """Remove every scratch of the active object"""

    bl_idname = "scratch.clear"
    bl_label = "Clear Scratches"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        obj = context.active_object
        try:
            check_object(obj)
        except MeshError as error:
            return fail(self, error)
        count = storage.scratch_summary(obj)["count"]
        if storage.DATA_KEY not in obj:
            self.report({"INFO"}, f"{obj.name} has no scratches")
            return {"CANCELLED"}
        storage.clear_scratches(obj)
        self.report({"INFO"}, f"{obj.name}: removed {plural(count)}")
        return {"FINISHED"}


class SCRATCH_OT_import_file(ObjectModeOperator, bpy.types.Operator, ImportHelper):
    """Load scratches from a scratch file (format v1, .npz) onto the active mesh"""

    bl_idname = "scratch.import_file"
    bl_label = "Import Scratches"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".npz"
    filter_glob: StringProperty(default="*.npz", options={"HIDDEN"})
    mode: mode_property("imported")

    def execute(self, context):
        obj = context.active_object
        try:
            check_object(obj)
            path = Path(bpy.path.abspath(self.filepath))
            if not path.is_file():
                raise MeshError(f"No scratch file at '{path}'")
            loaded = scratch.load(path)
            if loaded.count == 0 and self.mode == "ADD":
                self.report({"INFO"}, f"{path.name} holds no scratches: nothing to add to {obj.name}")
                return {"CANCELLED"}
            replaced = storage.scratch_summary(obj)["count"] if self.mode == "REPLACE" else 0
            result = combine(obj, loaded, self.mode)
            outside, no_uv_reason = _outside_uv(obj, context, loaded)
            write(obj, result)
        except USER_ERRORS as error:
            return fail(self, error)
        self.report({"INFO"}, f"{obj.name}: imported {plural(loaded.count)} from {path.name}")
        if loaded.count == 0 and replaced:
            self.report({"WARNING"}, f"{path.name} holds no scratches: the {plural(replaced)} of {obj.name} "
                                     "were replaced by none (Undo brings them back)")
        if no_uv_reason:
            self.report({"WARNING"}, f"{no_uv_reason}: the imported scratches are stored but will not show "
                                     "until it has a UV map with faces (UV > Unwrap)")
        elif outside:
            verb = "lies" if outside == 1 else "lie"
            self.report({"WARNING"}, f"{plural(outside)} of {path.name} {verb} outside the UV islands of "
                                     f"{obj.name} and will not show")
        return {"FINISHED"}


def _outside_uv(obj, context, scratches: ScratchSet) -> tuple[int, str]:
    """(How many scratches have a vertex outside every UV triangle, why that cannot be told or "").

    Scratches live in UV space, so on a mesh without a UV map (or without
    faces) none of them can show: the reason is returned for a warning.
    """
    if scratches.count == 0:
        return 0, ""
    try:
        arrays = mesh_arrays(obj, context.evaluated_depsgraph_get())
    except MeshError as error:
        return 0, str(error).split(";")[0]
    triangle, _ = UVLocator(arrays.triangle_uv).locate(scratches.uv)
    missing = triangle < 0
    outside = int(len(set(scratches.scratch_index_of_vertices()[missing].tolist()))) if missing.any() else 0
    return outside, ""


class SCRATCH_OT_export_file(ObjectModeOperator, bpy.types.Operator, ExportHelper):
    """Write the active object's scratches to a scratch file (format v1, .npz)"""

    bl_idname = "scratch.export_file"
    bl_label = "Export Scratches"
    bl_options = {"REGISTER"}

    filename_ext = ".npz"
    filter_glob: StringProperty(default="*.npz", options={"HIDDEN"})

    def invoke(self, context, event):
        obj = context.active_object
        if obj is not None and not self.filepath:
            self.filepath = bpy.path.clean_name(obj.name) + self.filename_ext
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        obj = context.active_object
        try:
            check_object(obj)
            # The bytes written are the ones just validated (a damaged set is refused, never exported).
            stored, data, _ = storage.read_scratch_file(obj)
            if data is None:
                data = scratch.dumps(ScratchSet.empty())
            path = Path(bpy.path.abspath(self.filepath))
            scratch.save_bytes(data, path)
        except USER_ERRORS as error:
            return fail(self, error)
        self.report({"INFO"}, f"{obj.name}: exported {plural(stored.count)} to {path}")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory(
    (SCRATCH_OT_clear, SCRATCH_OT_import_file, SCRATCH_OT_export_file))
