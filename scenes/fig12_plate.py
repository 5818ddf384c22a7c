"""Fig. 12 (right): a plate with 481 905 scratches of depth and width G[4.0, 0.01] µm.

The supplement's densest plate: deep, wide grooves (4 µm, almost constant) by
the hundred thousand, rendered at 1 MP with 3 wavelengths.  Here the **Generate
Scratches** operator scatters them over a 15 cm aluminium plate, short (1–5 mm)
so that they cover about a quarter of it, as a sanded or scoured plate is
covered; the supplement gives no lengths.
"""
from __future__ import annotations

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "SCRATCHES", "PLATE_M"]

PLATE_M = 0.15
#: G_{D,W}[4.0, 0.01] µm (the operator takes nanometres); our lengths.
SCRATCHES = dict(count=481_905, seed=12, length_min=0.001, length_max=0.005,
                 depth_distribution="GAUSSIAN", depth_mean=4000.0, depth_std=10.0,
                 width_distribution="GAUSSIAN", width_mean=4000.0, width_std=10.0)
EXPOSURE = -3.0

FIGURE = Figure(
    key="fig12_plate", label="Fig. 12 (right)", title="Densely scratched plate",
    paper="The supplement's densest plate: 481 905 scratches whose depth and width are both G[4.0, 0.01] µm, "
          "rendered at 1 MP with only 3 wavelengths per sample (31 min). We have not seen the figure itself. "
          "Grooves of one width and depth all diffract alike: their glints share one pattern of colours by "
          "angle from the light's mirror direction.",
    scratches="481 905 scratches (Generate operator: random directions, straight, 1–5 mm), G_D[4.0, 0.01] µm, "
              "G_W[4.0, 0.01] µm, rectangular, no variation; aluminium, coherence diameter 30 µm; about a quarter "
              "of the plate lies in a groove, 2.6 grooves per coherence area on average",
    design="A 15 cm aluminium plate on a dark table in the Fig. 7(b) studio (one small lamp 40° high, the camera "
           "on the other side 15° above its mirror direction, 34 cm away). Every groove has the same 4 µm "
           "width and depth, so every glint has the same spectrum at a given angle from the lamp's mirror "
           "direction (the groove's transform across it and its depth phase 2π(γ_i + γ_o)D/λ, both functions "
           "of that angle and λ alone): the sparkle, dense enough to fill the plate, forms concentric rainbow "
           "rings around the lamp's reflection, white at its centre. The paper renders 3 wavelengths per "
           "sample; we render 4 (hero wavelength sampling) — the benchmark table compares per wavelength "
           "sample.",
    renders=(Render("lamp", "481 905 deep scratches around a lamp's reflection", {},
                    resolution=(720, 540), samples=16, paper_minutes=31, paper_megapixels=1.0,
                    paper_wavelengths=3),),
)


def build_scene(scene, *, resolution=(720, 540), samples: int = 64, count: int | None = None):
    """The plate, its table, the lamp and the camera; returns the plate. ``count`` overrides 481 905 (tests)."""
    import bpy

    from . import staging

    plate = staging.metal_plate("Scratched plate", PLATE_M, metal="Al")
    staging.operator(bpy.ops.scratch.generate, plate, **{**SCRATCHES, "count": count or SCRATCHES["count"]})
    staging.table()
    staging.lamp_studio(scene, camera_distance_m=0.34, target=(0.0, 0.006, 0.0))
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return plate
