"""Operator properties shared by the generator and the brushes (defined once, as mixins).

Units:

* lengths along the surface (``length_min``, brush ``radius`` ...) are Blender
  lengths (``unit='LENGTH'``): scene units, displayed with the scene's unit
  system; metres = value × ``scene.unit_settings.scale_length``;
* widths and depths are **nanometres**, displayed with Blender's wavelength
  unit ("250 nm", "4 µm").  Blender's length unit cannot show them: its
  smallest unit is the micrometre and 250 nm would read "0 m".  On a Blender
  without the wavelength unit they show as plain numbers labelled "(nm)".
  They are physical sizes, independent of the scene's unit scale.
"""
from __future__ import annotations

import math

import bpy
from bpy.props import CollectionProperty, EnumProperty, FloatProperty, IntProperty

from ...mitsuba_bridge.errors import ParameterError
from ...mitsuba_bridge.scratch import Gaussian, Profile, Uniform
from ..geometry.scatter import Looks, check_length_range
from ..geometry.units import NM, format_length

__all__ = ["LooksProperties", "LengthProperties", "StrokeProperties", "NM_UNIT", "seed_property",
           "mode_property", "draw_looks", "draw_lengths"]


def _has_wavelength_unit() -> bool:
    try:
        return "WAVELENGTH" in bpy.types.Property.bl_rna.properties["unit"].enum_items.keys()
    except (AttributeError, KeyError):  # pragma: no cover - very old Blender
        return False


#: Unit used to display nanometre values.
NM_UNIT = "WAVELENGTH" if _has_wavelength_unit() else "NONE"
_NM_SUFFIX = "" if NM_UNIT == "WAVELENGTH" else " (nm)"

_DISTRIBUTIONS = [
    ("UNIFORM", "Uniform", "U[min, max]: uniform between a smallest and a largest value"),
    ("GAUSSIAN", "Gaussian", "G[mean, std]: normal distribution; values <= 0 are drawn again"),
]


def _nm(name: str, description: str, default: float, **limits):
    limits.setdefault("min", 0.0)
    limits.setdefault("soft_max", 20000.0)
    return FloatProperty(name=name + _NM_SUFFIX, description=description + " (nanometres)",
                         default=default, unit=NM_UNIT, precision=1, step=100, **limits)


class LooksProperties:
    """Width, depth, profile and variation of new scratches (docs/model.md §7)."""

    depth_distribution: EnumProperty(name="Depth", items=_DISTRIBUTIONS, default="GAUSSIAN",
                                     description="How scratch depths are distributed")
    depth_min: _nm("Depth Min", "Smallest depth of U[min, max]", 100.0)
    depth_max: _nm("Depth Max", "Largest depth of U[min, max]", 500.0)
    depth_mean: _nm("Depth Mean", "Mean depth of G[mean, std]", 250.0)
    depth_std: _nm("Depth Std", "Standard deviation of the depth in G[mean, std]", 80.0)
    width_distribution: EnumProperty(name="Width", items=_DISTRIBUTIONS, default="GAUSSIAN",
                                     description="How scratch widths are distributed")
    width_min: _nm("Width Min", "Smallest width of U[min, max]", 1000.0)
    width_max: _nm("Width Max", "Largest width of U[min, max]", 6000.0)
    width_mean: _nm("Width Mean", "Mean width of G[mean, std]", 4000.0)
    width_std: _nm("Width Std", "Standard deviation of the width in G[mean, std]", 1300.0)
    profile: EnumProperty(
        name="Profile", default="RECTANGULAR",
        items=[("RECTANGULAR", "Rectangular", "Flat bottom and vertical walls"),
               ("TRIANGULAR", "Triangular", "V-groove, deepest on the centre line")],
        description="Cross-section of the scratches")
    depth_variation_amplitude: FloatProperty(
        name="Depth Variation", min=0.0, soft_max=2.0, default=0.0, precision=2,
        description="Relative amplitude of the depth's noise along a scratch (1.1 = 110 %, "
                    "the depth then touches zero in places); 0: constant depth")
    depth_variation_frequency: FloatProperty(
        name="Depth Frequency", min=0.0, soft_max=0.2, default=0.04, precision=4, step=1,
        description="Frequency of the depth noise: 1/255 is one oscillation along the whole "
                    "scratch, 0.04 about ten")
    width_variation_amplitude: FloatProperty(
        name="Width Variation", min=0.0, soft_max=2.0, default=0.0, precision=2,
        description="Relative amplitude of the width's noise along a scratch; 0: constant width")
    width_variation_frequency: FloatProperty(
        name="Width Frequency", min=0.0, soft_max=0.2, default=0.04, precision=4, step=1,
        description="Frequency of the width noise: 1/255 is one oscillation along the whole scratch")

    def looks(self) -> Looks:
        """The chosen parameters; raises ValueError with a message for the user."""
        return Looks(
            width=self._distribution("width"), depth=self._distribution("depth"),
            profile=Profile[self.profile],
            width_variation=(self.width_variation_amplitude, self.width_variation_frequency),
            depth_variation=(self.depth_variation_amplitude, self.depth_variation_frequency))

    def _distribution(self, what: str):
        kind = getattr(self, f"{what}_distribution")
        if kind == "UNIFORM":
            low, high = getattr(self, f"{what}_min") * NM, getattr(self, f"{what}_max") * NM
            if not (math.isfinite(low) and math.isfinite(high)):
                raise ParameterError(f"{what.title()}: U[{format_length(low)}, {format_length(high)}] needs finite "
                                 "numbers")
            if high < low:
                raise ParameterError(f"{what.title()}: the maximum ({format_length(high)}) is below the "
                                 f"minimum ({format_length(low)})")
            if high <= 0:
                raise ParameterError(f"{what.title()}: the maximum must be above 0")
            return Uniform(low, high)
        mean, std = getattr(self, f"{what}_mean") * NM, getattr(self, f"{what}_std") * NM
        if not (math.isfinite(mean) and math.isfinite(std)):
            raise ParameterError(f"{what.title()}: G[{format_length(mean)}, {format_length(std)}] needs finite numbers")
        try:
            return Gaussian(mean, std)
        except ParameterError:
            raise ParameterError(f"{what.title()}: G[{format_length(mean)}, {format_length(std)}] has "
                             "(almost) no positive values; raise the mean or lower the spread") from None


class LengthProperties:
    """Length and bend of new scratches (lengths on the surface)."""

    length_min: FloatProperty(
        name="Length Min", description="Shortest scratch, measured along the surface",
        subtype="DISTANCE", unit="LENGTH", default=0.005, min=1e-7, soft_max=1.0, precision=2)
    length_max: FloatProperty(
        name="Length Max", description="Longest scratch, measured along the surface",
        subtype="DISTANCE", unit="LENGTH", default=0.03, min=1e-7, soft_max=1.0, precision=2)
    bend: FloatProperty(
        name="Bend", description="Largest angle by which a scratch turns along its length "
                                 "(gentle arcs; each scratch draws its bend in ± this); 0: straight",
        subtype="ANGLE", default=0.0, min=0.0, max=math.pi)

    def length_range(self, surface=None) -> tuple[float, float]:
        """(min, max) in scene units; raises ParameterError with a message for the user.

        ``surface`` (optional) also bounds the length by the object's size.
        """
        check_length_range(self.length_min, self.length_max, surface)
        return self.length_min, self.length_max


class StrokeProperties:
    """The stroke a brush operator replays (world-space points on or near the surface)."""

    stroke: CollectionProperty(name="Stroke", type=bpy.types.OperatorStrokeElement,
                               options={"HIDDEN", "SKIP_SAVE"})
    radius: FloatProperty(
        name="Radius", description="Brush radius, measured on the surface",
        subtype="DISTANCE", unit="LENGTH", default=0.02, min=1e-7, soft_max=1.0, precision=3)


def seed_property():
    return IntProperty(name="Seed", description="Seed of the random numbers: the same seed gives "
                                                "the same scratches", default=0, min=0)


def mode_property(what: str):
    return EnumProperty(
        name="Mode", default="REPLACE",
        items=[("ADD", "Add", f"Add the {what} scratches to the object's scratches"),
               ("REPLACE", "Replace", f"Replace the object's scratches with the {what} ones")])


# ------------------------------------------------------------------ drawing
def draw_looks(layout, props) -> None:
    """Every looks property; the ones the current distribution ignores greyed out."""
    for what in ("depth", "width"):
        column = layout.column(align=True)
        column.prop(props, f"{what}_distribution")
        uniform = getattr(props, f"{what}_distribution") == "UNIFORM"
        for name, active in (("min", uniform), ("max", uniform), ("mean", not uniform), ("std", not uniform)):
            row = column.row(align=True)
            row.active = active
            row.prop(props, f"{what}_{name}")
    layout.prop(props, "profile")
    for what in ("depth", "width"):
        column = layout.column(align=True)
        column.prop(props, f"{what}_variation_amplitude")
        row = column.row(align=True)
        row.active = getattr(props, f"{what}_variation_amplitude") > 0
        row.prop(props, f"{what}_variation_frequency")


def draw_lengths(layout, props) -> None:
    column = layout.column(align=True)
    column.prop(props, "length_min")
    column.prop(props, "length_max")
    layout.prop(props, "bend")
