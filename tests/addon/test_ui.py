"""Tools, panels, redo panels, overlay data and the modal stroke logic, headless.

Drawing needs a GPU and modal operators need a window, so these tests drive
the Python side with small stand-ins for layouts, events and drawers.
"""
from types import SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from strokes import stroke  # noqa: E402
from scratch_iridescence.addon.ui import overlay, panels  # noqa: E402
from scratch_iridescence.addon.operators.files import SCRATCH_OT_export_file, SCRATCH_OT_import_file  # noqa: E402
from scratch_iridescence.addon.operators.generate import SCRATCH_OT_generate  # noqa: E402
from scratch_iridescence.addon.tools.paint import (SCRATCH_OT_erase_stroke, SCRATCH_OT_paint_stroke,  # noqa: E402
                                             SCRATCH_PT_brush_scratches, SCRATCH_TOOL_brush, SCRATCH_TOOL_eraser)
from scratch_iridescence.addon.tools.stroke import StrokeOperator  # noqa: E402


class Layout:
    """Records what a draw function shows; every other layout call is accepted and ignored."""

    def __init__(self, shown=None):
        self.shown = [] if shown is None else shown

    def prop(self, data, name, **_):
        self.shown.append(name)

    def operator(self, idname, **_):
        self.shown.append(idname)
        return SimpleNamespace()

    def popover(self, panel, **_):
        self.shown.append(panel)

    def label(self, text="", **_):
        self.shown.append("label:" + text)

    def column(self, **_):
        return Layout(self.shown)

    row = box = split = column

    def __getattr__(self, name):
        return lambda *args, **kwargs: None


def operator_properties(operator_class):
    """The operator's own properties (RNA definitions)."""
    module, name = operator_class.bl_idname.split(".")
    return [p for p in getattr(getattr(bpy.ops, module), name).get_rna_type().properties
            if p.identifier != "rna_type"]


def defaults(operator_class):
    return {p.identifier: getattr(p, "default", None) for p in operator_properties(operator_class)}


@pytest.mark.parametrize("operator_class", [SCRATCH_OT_generate, SCRATCH_OT_paint_stroke, SCRATCH_OT_erase_stroke])
def test01_redo_panels_show_every_parameter(addon, operator_class):
    values = defaults(operator_class)
    layout = Layout()
    operator_class.draw(SimpleNamespace(layout=layout, **values), bpy.context)
    hidden = {p.identifier for p in operator_properties(operator_class) if p.is_hidden}
    assert set(values) - hidden <= set(layout.shown)


def test02_editing_operators_take_part_in_undo(addon):
    for cls in (SCRATCH_OT_generate, SCRATCH_OT_paint_stroke, SCRATCH_OT_erase_stroke, SCRATCH_OT_import_file):
        assert {"REGISTER", "UNDO"} <= set(cls.bl_options), cls
    assert bpy.types.SCRATCH_OT_clear.bl_options >= {"REGISTER", "UNDO"}
    assert "UNDO" not in SCRATCH_OT_export_file.bl_options  # writing a file changes nothing in the .blend


def test03_length_and_size_units(addon):
    props = {p.identifier: p for p in operator_properties(SCRATCH_OT_generate)}
    assert props["length_min"].unit == "LENGTH" and props["length_max"].unit == "LENGTH"
    assert props["depth_mean"].unit == "WAVELENGTH" and props["width_min"].unit == "WAVELENGTH"
    assert bpy.utils.units.to_string("METRIC", "WAVELENGTH", props["depth_mean"].default) == "250 nm"
    assert bpy.utils.units.to_string("METRIC", "LENGTH", 250e-9) == "0 m"  # why widths are not LENGTH


def test04_tools_are_in_the_object_mode_toolbar(addon):
    from bl_ui.space_toolsystem_common import ToolSelectPanelHelper

    toolbar = ToolSelectPanelHelper._tool_class_from_space_type("VIEW_3D")
    tools = {item.idname: item for item in ToolSelectPanelHelper._tools_flatten(toolbar._tools["OBJECT"])
             if item is not None}
    for tool, operator in ((SCRATCH_TOOL_brush, "scratch.paint_stroke"),
                           (SCRATCH_TOOL_eraser, "scratch.erase_stroke")):
        item = tools[tool.bl_idname]
        assert item.label == tool.bl_label and item.draw_cursor is not None
        keymap = bpy.context.window_manager.keyconfigs.addon.keymaps[item.keymap[0]]
        assert [(k.idname, k.type, k.value) for k in keymap.keymap_items] == [(operator, "LEFTMOUSE", "PRESS")]


def test05_tool_settings_draw(addon):
    brush_props = SimpleNamespace(**defaults(SCRATCH_OT_paint_stroke))
    eraser_props = SimpleNamespace(**defaults(SCRATCH_OT_erase_stroke))
    tool = SimpleNamespace(operator_properties=lambda idname: brush_props if "paint" in idname else eraser_props)
    layout = Layout()
    SCRATCH_TOOL_brush.draw_settings(bpy.context, layout, tool)
    assert {"brush_mode", "radius", "density", "SCRATCH_PT_brush_scratches"} <= set(layout.shown)
    layout = Layout()
    SCRATCH_TOOL_eraser.draw_settings(bpy.context, layout, tool)
    assert layout.shown == ["erase_mode", "radius"]
    popover = Layout()
    SCRATCH_PT_brush_scratches.draw(SimpleNamespace(layout=popover), bpy.context)  # no tool active: nothing


def test06_object_panel_shows_count_summary_buttons_and_settings(scratched_plane):
    layout = Layout()
    context = SimpleNamespace(object=scratched_plane)
    panels.SCRATCH_PT_scratches.draw(SimpleNamespace(layout=layout), context)
    assert "label:50 scratches" in layout.shown
    assert any(text.startswith("label:Mean depth 250 nm, mean width 1 µm") for text in layout.shown)
    assert {"scratch.generate", "scratch.clear", "scratch.import_file", "scratch.export_file"} <= set(layout.shown)
    layout = Layout()
    panels.SCRATCH_PT_scratch_render.draw(SimpleNamespace(layout=layout), context)
    assert layout.shown == ["base_material", "coherence_diameter_um", "coherent", "diffuse_reflectance", "crossings",
                            "depth_phase"]
    layout = Layout()
    panels.SCRATCH_PT_scratch_overlay.draw_header(SimpleNamespace(layout=layout), context)
    panels.SCRATCH_PT_scratch_overlay.draw(SimpleNamespace(layout=layout), context)
    assert {"show_overlay", "overlay_color_by"} <= set(layout.shown)
    assert panels.SCRATCH_PT_scratches.poll(context)
    bpy.ops.object.empty_add()
    assert not panels.SCRATCH_PT_scratches.poll(SimpleNamespace(object=bpy.context.active_object))


def test07_overlay_data_is_built_once_per_change(scratched_plane):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    data = overlay.overlay_data(scratched_plane, depsgraph)
    assert overlay.overlay_data(scratched_plane, depsgraph) is data  # cached
    assert data.positions.dtype == np.float32 and data.positions.shape == data.colours.shape[:1] + (3,)
    assert data.unplaced == 0
    # Lines lie on the plane (lifted a little) where the scratches are.
    assert np.abs(data.positions[:, 2]).max() < 1e-3 and np.abs(data.positions[:, :2]).max() <= 1.0
    low, high = panels.colour_range(scratched_plane)
    assert 0 < low <= high
    scratched_plane.scratch_iridescence.overlay_color_by = "WIDTH"
    by_width = overlay.overlay_data(scratched_plane, depsgraph)
    assert by_width is not data and np.array_equal(by_width.positions, data.positions)
    bpy.ops.scratch.generate(count=20)
    assert len(overlay.overlay_data(scratched_plane, depsgraph).positions) != len(data.positions)


def test08_overlay_follows_mesh_edits(scratched_plane):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    data = overlay.overlay_data(scratched_plane, depsgraph)
    scratched_plane.data.vertices[0].co.z = 0.5
    scratched_plane.data.update()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    assert not np.array_equal(overlay.overlay_data(scratched_plane, depsgraph).positions, data.positions)


def test09_overlay_draw_callback_is_registered_and_safe_headless(scratched_plane):
    assert overlay._handle
    overlay._draw()  # background mode: returns without touching the GPU


class Event(SimpleNamespace):
    def __init__(self, type, value="PRESS"):
        super().__init__(type=type, value=value, mouse_region_x=0, mouse_region_y=0, pressure=1.0)


class Drawer:
    def __init__(self):
        self.restored = 0

    def restore(self):
        self.restored += 1


def modal_operator():
    operator = SimpleNamespace(_drawer=Drawer(), _samples=[], stroke=[], reports=[], executed=False)
    operator.report = lambda kind, text: operator.reports.append(text)
    operator._sample = lambda context, event: operator._samples.append(event.type)
    operator.execute = lambda context: {"FINISHED"}
    return operator


@pytest.mark.parametrize("event", ["MIDDLEMOUSE", "WHEELUPMOUSE", "TRACKPADPAN", "NDOF_MOTION", "NUMPAD_5"])
def test10_navigation_passes_through_a_stroke(addon, event):
    operator = modal_operator()
    assert StrokeOperator.modal(operator, bpy.context, Event(event)) == {"PASS_THROUGH"}
    assert operator._drawer.restored == 0


@pytest.mark.parametrize("event", ["ESC", "RIGHTMOUSE"])
def test11_escape_and_right_click_cancel_cleanly(addon, event):
    operator = modal_operator()
    StrokeOperator.modal(operator, bpy.context, Event("MOUSEMOVE"))
    assert StrokeOperator.modal(operator, bpy.context, Event(event)) == {"CANCELLED"}
    assert operator._drawer.restored == 1 and operator._samples == ["MOUSEMOVE"]


def test12_release_ends_the_stroke_through_execute(plane):
    operator = modal_operator()
    operator._samples = [((-0.5, 0.0, 0.0), (10, 10), True, 0.0, 0.25), ((0.5, 0.0, 0.0), (90, 10), False, 0.1, 0.75)]

    class Stroke(list):
        def add(self):
            self.append(SimpleNamespace())
            return self[-1]

    operator.stroke = Stroke()
    assert StrokeOperator._end(operator, bpy.context) == {"FINISHED"}
    assert operator._drawer.restored == 1
    assert [tuple(e.location) for e in operator.stroke] == [(-0.5, 0.0, 0.0), (0.5, 0.0, 0.0)]
    assert [e.is_start for e in operator.stroke] == [True, False]
    assert [e.pressure for e in operator.stroke] == [0.25, 0.75]  # the tablet's pressure, replayed by execute
    empty = modal_operator()
    empty.stroke = Stroke()
    assert StrokeOperator._end(empty, bpy.context) == {"CANCELLED"} and empty._drawer.restored == 1


def test13_menu_and_panel_classes_are_registered(addon):
    for name in ("SCRATCH_PT_scratches", "SCRATCH_PT_scratch_render", "SCRATCH_PT_scratch_overlay",
                 "SCRATCH_MT_object", "SCRATCH_PT_brush_scratches"):
        assert hasattr(bpy.types, name)
    assert stroke([(0, 0, 0)])[0]["is_start"]
