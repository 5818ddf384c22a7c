"""Fig. 9: a grated plate, 1 600 scratches of D = W = 1 µm, incoherent against coherent superposition.

Coherence only matters where several scratches share one coherence area
(δ_c = 30 µm here), and it only survives the pixel's average where their
spacing is regular: random spacings give random phases whose cross terms
average out, so a plate with scattered scratches looks the same either way.
The plate therefore carries four ruled grating bands of 400 parallel grooves
at a 2.5 µm pitch (12 grooves per coherence area), ruled with the add-on's
**Pen** brush: one replayed stroke that lifts and comes back for every groove
(``is_start``), as along a ruler.

A strip light parallel to the grooves, close to the plate, makes the half
vector's component across the grooves sweep 0.18–0.28 from the first band to
the last, so the first grating order (λ = P·|h·n|) is blue on the first band,
green, orange and red on the next ones.  Incoherently the bands only show one
groove's envelope: the same pale colour on all four.
"""
from __future__ import annotations

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "GROOVES", "PITCH_M", "BAND_Y_M"]

PLATE_M = 0.10
GROOVES, PITCH_M = 1600, 2.5e-6
BAND_Y_M = (0.0, 0.005, 0.010, 0.015)   # where the four bands start (plate centre at 0)
GROOVE_LENGTH_M = 0.07
STRIP_LIGHT = dict(location=(0.0, 0.08, 0.09), size=(0.08, 0.002), power_w=0.35)
EXPOSURE = -2.0

FIGURE = Figure(
    key="fig09_grating", label="Fig. 9", title="Grated plate: incoherent and coherent",
    paper="The same grated plate rendered twice: adding the scratches' intensities (incoherent, left) and "
          "their complex amplitudes (coherent, right). Only the coherent sum shows the colourful grating "
          "orders of regularly spaced scratches.",
    scratches="1 600 scratches, D = 1 µm, W = 1 µm, rectangular, no variation: four bands of 400 parallel "
              "grooves, pitch 2.5 µm, 7 cm long, 5 mm apart (Pen brush, one replayed stroke); aluminium, "
              "coherence diameter 30 µm (12 grooves per coherence area)",
    design="A macro view (135 mm lens) of the bands under a narrow strip light 9 cm above the plate, parallel "
           "to the grooves: along the strip the half vector stays perpendicular to the grooves over several "
           "centimetres, so each band glows along its length; across it the light is 2 mm narrow, so each band "
           "picks a pure wavelength of the first order, λ = P·|h·n| ≈ 460, 540, 620, 710 nm from the first band "
           "to the last.",
    renders=(
        Render("incoherent", "incoherent: four bands of the same pale colour", {"coherent": False},
               resolution=(720, 450), samples=256, paper_minutes=14),
        Render("coherent", "coherent: the grating orders, a different pure colour on every band",
               {"coherent": True}, resolution=(720, 450), samples=256, paper_minutes=19),
    ),
)


def groove_stroke(grooves: int = GROOVES, pitch_m: float = PITCH_M, band_y_m=BAND_Y_M,
                  length_m: float = GROOVE_LENGTH_M, height_m: float = 0.002) -> list[dict]:
    """The ruler stroke: two points per groove, each groove a new scratch (``is_start``)."""
    from . import staging

    per_band = grooves // len(band_y_m)
    y = np.concatenate([y0 + pitch_m * np.arange(per_band) for y0 in band_y_m])
    points = np.zeros((len(y), 2, 3))
    points[:, 0, 0], points[:, 1, 0] = -0.5 * length_m, 0.5 * length_m
    points[:, :, 1] = y[:, None]
    points[:, :, 2] = height_m
    starts = np.zeros((len(y), 2), dtype=bool)
    starts[:, 0] = True
    return staging.stroke(points.reshape(-1, 3), starts.ravel())


def build_scene(scene, *, coherent: bool = True, resolution=(720, 450), samples: int = 256,
                grooves: int = GROOVES):
    """The ruled plate under the strip light; returns the plate. ``grooves`` < 1 600 for quick tests."""
    import bpy

    from . import staging

    plate = staging.metal_plate("Grated plate", PLATE_M, metal="Al")
    plate.scratch_iridescence.coherent = coherent
    staging.operator(bpy.ops.scratch.paint_stroke, plate, stroke=groove_stroke(grooves), brush_mode="PEN",
                     depth_distribution="GAUSSIAN", depth_mean=1000.0, depth_std=0.0,
                     width_distribution="GAUSSIAN", width_mean=1000.0, width_std=0.0)
    staging.table()
    centre = (0.0, 0.5 * (BAND_Y_M[0] + BAND_Y_M[-1]), 0.0)
    staging.area_light(scene, "Strip light", STRIP_LIGHT["location"], centre, power_w=STRIP_LIGHT["power_w"],
                       size=STRIP_LIGHT["size"])
    staging.constant_world(scene, (0.01, 0.01, 0.012))
    # Aimed a little beyond the bands, so the strip light's own reflection (2.5 cm before them) stays out of view.
    staging.camera(scene, (0.0, -0.16, 0.10), (0.0, centre[1] + 0.005, 0.0), lens_mm=110.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return plate
