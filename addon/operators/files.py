"""``scratch.clear``, ``scratch.import_file`` and ``scratch.export_file``.

Exporting writes the bytes stored in the .blend (a format-v1 file, see
:mod:`.storage`) unchanged, so exporting an unchanged object twice gives
identical files.  Files are written atomically (``scratch.save_bytes``: a
temporary file, then a rename).

Importing runs in Blender's UI thread, so its cost is bounded before it starts:
the file's headers say how many vertices it holds (nothing inflated), and a
file beyond :data:`MAX_IMPORT_VERTICES`, or whose import would not fit the
memory Blender is allowed, is refused with the estimate (the format allows 16
times more, for scripts and the command line).  The check of which scratches lie
outside the mesh's UV islands (a warning only) tests at most
:data:`MAX_CHECKED_VERTICES` vertices, evenly spread.
"""
from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ...mitsuba_bridge import scratch
from ...mitsuba_bridge.device.memory import check_memory, format_bytes
from ...mitsuba_bridge.errors import ParameterError
from ...mitsuba_bridge.scratch import ScratchSet
from .. import storage
from .editing import USER_ERRORS, ObjectModeOperator, combine, fail, plural, write
from ..mesh import MeshError, check_object, mesh_arrays
from .properties import mode_property
from ..geometry.uvmap import UVLocator

__all__ = ["SCRATCH_OT_clear", "SCRATCH_OT_import_file", "SCRATCH_OT_export_file", "MAX_IMPORT_VERTICES",
           "check_import"]

#: Most vertices an import takes in Blender: loading, validating and storing cost about 0.3 µs per vertex
#: (16.8 M vertices: 5.1 s on the 2-core development machine, profiled), so the largest import keeps Blender
#: busy about a second.  Files up to the format's 2**26 vertices are for scripts and the command line.
MAX_IMPORT_VERTICES = 1 << 22
#: Peak memory of an import per vertex (bytes): the inflated uv, the set, the stored file's bytes and
#: Blender's copy of them, 16 bytes each, and temporaries.
IMPORT_BYTES_PER_VERTEX = 96
#: The UV-island check (a warning) locates at most this many vertices (about 2 µs each).
MAX_CHECKED_VERTICES = 1 << 17


def check_import(path: Path) -> tuple[int, int]:
    """``(scratches, vertices)`` the file declares, or a user error with the estimate where importing it in
    Blender would take too long or need more memory than Blender is allowed."""
    count, vertices = scratch.declared_counts(path)
    if vertices > MAX_IMPORT_VERTICES:
        seconds = vertices * 0.3e-6
        raise ParameterError(
            f"{path.name} holds {vertices:,} vertices in {plural(count)}: importing it would keep Blender busy for "
            f"about {seconds:.0f} s and need about {format_bytes(vertices * IMPORT_BYTES_PER_VERTEX)}; at most "
            f"{MAX_IMPORT_VERTICES:,} vertices are imported in Blender (simplify the scratches, split the file, "
            "or render it with the command line)")
    check_memory(vertices * IMPORT_BYTES_PER_VERTEX, f"importing {path.name} ({vertices:,} vertices)",
                 advice="split the file")
    return count, vertices


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
            if not path.exists():
                raise MeshError(f"No scratch file at '{path}'")
            check_import(path)  # (a FIFO, a device or a folder is refused here too, without waiting)
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
            least = "at least " if loaded.vertex_count > MAX_CHECKED_VERTICES else ""  # (a sample was checked)
            self.report({"WARNING"}, f"{least}{plural(outside)} of {path.name} {verb} outside the UV islands of "
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
    # (evenly spread vertices, at most MAX_CHECKED_VERTICES: a warning need not cost seconds)
    checked = np.unique(np.linspace(0, scratches.vertex_count - 1, min(scratches.vertex_count, MAX_CHECKED_VERTICES))
                        .astype(np.int64))
    triangle, _ = UVLocator(arrays.triangle_uv).locate(scratches.uv[checked])
    missing = checked[triangle < 0]
    outside = int(len(np.unique(scratches.scratch_index_of_vertices()[missing]))) if missing.size else 0
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
