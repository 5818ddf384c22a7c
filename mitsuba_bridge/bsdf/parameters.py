"""Names and defaults of the ``scratch_diffraction`` plugin, without importing Mitsuba.

The plugin, the scene builder and the Blender add-on all read their defaults
from here, so the three never disagree.
"""
from __future__ import annotations

PLUGIN_NAME = "scratch_diffraction"

#: Default coherence diameter δ_c in metres (σ = δ_c / 6 = 5 µm).  The mirror
#: lobe's angular width is then λ / (2√2 π σ) ≈ 0.7° at 550 nm, about the sun's
#: disc, and the paper's CD (≈ 21 tracks of 1.6 µm pitch per coherence area)
#: implies δ_c ≈ 32 µm (docs/model.md §2).
DEFAULT_COHERENCE_DIAMETER_M = 30e-6

DEFAULT_MATERIAL = "Al"

#: (code, label, description) of the base metals offered in the user interface;
#: the code is a material name of Mitsuba's ``conductor`` plugin, or ``none``.
BASE_MATERIALS = (
    ("Al", "Aluminium", "Aluminium (Mitsuba conductor 'Al')"),
    ("Ag", "Silver", "Silver (Mitsuba conductor 'Ag')"),
    ("Au", "Gold", "Gold (Mitsuba conductor 'Au')"),
    ("Cu", "Copper", "Copper (Mitsuba conductor 'Cu')"),
    ("Cr", "Chromium", "Chromium (Mitsuba conductor 'Cr')"),
    ("none", "Perfect Mirror", "Reflects everything (no Fresnel term)"),
)
#: Depth phase per unit depth: "kirchhoff" 2π(γ_i + γ_o)/λ (docs/model.md §2), "incidence" 4πγ_i/λ, or
#: "bounded": the Kirchhoff BRDF divided by max(1, Â(ω_i), Â(ω_o)), Â an albedo estimate (docs/model.md §4.1).
DEFAULT_DEPTH_PHASE = "kirchhoff"
#: (code, label, description) of the depth phases offered in the user interface.
DEPTH_PHASE_ITEMS = (
    ("kirchhoff", "Kirchhoff", "The paper's phase 2π(γi + γo)D/λ: reciprocal; deep scratches (D, W of "
                               "several µm) reflect up to 40 % more than falls on them"),
    ("incidence", "Incidence", "Phase 4πγi·D/λ: never reflects more than falls on it, but not reciprocal "
                               "(docs/bsdf.md, Energy)"),
    ("bounded", "Bounded", "The paper's phase, divided where a deep scratch would reflect more than falls on it: "
                           "reciprocal, unchanged for shallow scratches, but each scratch in view costs about "
                           "a hundred times more (docs/bsdf.md, Energy)"),
)
DEPTH_PHASES = tuple(code for code, _, _ in DEPTH_PHASE_ITEMS)
#: Where scratches cross: "additive" sums their transfer functions (the paper, docs/model.md §2),
#: "height_field" gives the overlap the deeper one's depth (docs/model.md §3.4).
DEFAULT_CROSSINGS = "additive"
#: (code, label, description) of the crossing treatments offered in the user interface.
CROSSING_ITEMS = (
    ("additive", "Additive", "Overlapping scratches add their effects, as in the paper: a crossing "
                             "counts both depths"),
    ("height_field", "Height Field", "Where scratches cross or run over each other, the deepest one wins, "
                                     "as on a real surface (several times slower on densely scratched sets, "
                                     "V-grooves most)"),
)
CROSSINGS = tuple(code for code, _, _ in CROSSING_ITEMS)
#: The footprint filter (docs/model.md §11.2): each camera sample averages the BSDF over a Gaussian of
#: this many times its share of the pixel (pixel / √spp) as standard deviation.
FOOTPRINT_SCALE = 0.5


def sample_footprint(pixel_angle: float, pixel_width: float, spp_total: float) -> tuple[float, float]:
    """``(footprint_angle, footprint_width)`` of one sample of a render of ``spp_total`` samples per pixel:
    a pixel's angle (radians, perspective cameras) and width (scene units, orthographic ones) divided
    among its samples and scaled by :data:`FOOTPRINT_SCALE` (docs/model.md §11.2)."""
    scale = FOOTPRINT_SCALE / max(float(spp_total), 1.0) ** 0.5
    return pixel_angle * scale, pixel_width * scale
