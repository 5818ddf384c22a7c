"""Settings stored on objects: ``Object.scratch_iridescence`` (one PointerProperty per ID type).

The scratches themselves are not here but in :mod:`storage` (bulk bytes); this
group holds what a user edits in panels: how the scratched surface renders and
how the overlay shows it.  The coherence diameter is a physical size in
micrometres, like the scratch widths, independent of the scene's unit scale;
the render path converts it to metres once (``render.gather``).  Files saved
before the ``scratch_iridescence`` name (``Object.scratch``, a diameter in scene
units) are upgraded on load by :mod:`versioning`.
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty

from ..mitsuba_bridge.bsdf.parameters import (BASE_MATERIALS, CROSSING_ITEMS, DEFAULT_COHERENCE_DIAMETER_M,
                                             DEFAULT_CROSSINGS, DEFAULT_DEPTH_PHASE, DEPTH_PHASE_ITEMS)

M_TO_UM = 1e6

__all__ = ["SCRATCH_PG_object"]


def _tag_object(settings, context):
    # Properties defined in Python tag no depsgraph update: tag the object so that the
    # Rendered viewport (view_update) hears of the new BSDF settings.
    settings.id_data.update_tag(refresh={"OBJECT"})


class SCRATCH_PG_object(bpy.types.PropertyGroup):
    """Scratch rendering and display settings of one object."""

    # ---- rendering (read by the render path; the BSDF's parameters) ----
    base_material: EnumProperty(
        name="Base Material",
        description="Metal under the scratches (spectral conductor data from Mitsuba)",
        items=[(code, label, description) for code, label, description in BASE_MATERIALS],
        default="Al",
        update=_tag_object,
    )
    coherence_diameter_um: FloatProperty(
        name="Coherence Diameter (µm)",
        description="Diameter of the area over which the light is coherent, in micrometres (a physical "
                    "size, whatever the scene's unit scale); direct sunlight is about 30-100 µm. Larger "
                    "values give sharper diffraction lines and cost more",
        default=DEFAULT_COHERENCE_DIAMETER_M * M_TO_UM,
        min=1.0, soft_min=5.0, soft_max=200.0, precision=1, step=100,
        update=_tag_object,
    )
    coherent: BoolProperty(
        name="Coherent",
        description="Add the waves of all scratches in a coherence area (interference, grating "
                    "colours); off: add their intensities, as the paper's comparison mode",
        default=True,
        update=_tag_object,
    )
    crossings: EnumProperty(
        name="Crossings",
        description="How crossing scratches combine",
        items=[(code, label, description) for code, label, description in CROSSING_ITEMS],
        default=DEFAULT_CROSSINGS,
        update=_tag_object,
    )
    depth_phase: EnumProperty(
        name="Depth Phase",
        description="Phase a scratch's depth gives the reflected wave (matters for scratches deeper than "
                    "about a wavelength)",
        items=[(code, label, description) for code, label, description in DEPTH_PHASE_ITEMS],
        default=DEFAULT_DEPTH_PHASE,
        update=_tag_object,
    )
    diffuse_reflectance: FloatVectorProperty(
        name="Diffuse Base",
        description="Optional incoherent Lambertian base under the scratches (black: none)",
        subtype="COLOR", size=3, min=0.0, max=1.0, default=(0.0, 0.0, 0.0),
        update=_tag_object,
    )

    # ---- viewport overlay ----
    show_overlay: BoolProperty(
        name="Show Scratches", description="Draw this object's scratches in the viewport", default=True,
    )
    overlay_color_by: EnumProperty(
        name="Colour By",
        items=[("DEPTH", "Depth", "Colour scratches by depth"),
               ("WIDTH", "Width", "Colour scratches by width")],
        default="DEPTH",
    )


def register():
    bpy.utils.register_class(SCRATCH_PG_object)
    bpy.types.Object.scratch_iridescence = bpy.props.PointerProperty(type=SCRATCH_PG_object)


def unregister():
    del bpy.types.Object.scratch_iridescence
    bpy.utils.unregister_class(SCRATCH_PG_object)
