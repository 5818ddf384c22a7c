"""Supplement Fig. 17: 3 000 scratches of D = 1 µm, W = 2 µm, D[1.1, 0.03], rectangular against triangular.

Only the cross-section changes between the two pictures (same seed, same
positions, depths and widths), through the Generate operator's *Profile*.
A rectangular groove reflects like a thin film of thickness D, |e^{iκ} − 1|²
with κ = 2π(cos θ_i + cos θ_o)D/λ: for D = 1 µm several interference orders
fall into the visible range and the glints take pastel, angle-dependent
colours.  A V-groove has facets of slope 2D/W = 1 (0 to 2.1 with the depth
variation): they add geometric reflections far from the mirror direction,
whose colour the spread of slopes washes towards white.
"""
from __future__ import annotations

import math

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "SCRATCHES"]

PLATE_M = 0.10
SCRATCHES = dict(count=3000, seed=17, length_min=0.02, length_max=0.06, bend=math.radians(30),
                 depth_distribution="GAUSSIAN", depth_mean=1000.0, depth_std=0.0,
                 width_distribution="GAUSSIAN", width_mean=2000.0, width_std=0.0,
                 depth_variation_amplitude=1.1, depth_variation_frequency=0.03)
LAMP_ELEVATION_DEG = 40.0
CAMERA_ABOVE_MIRROR_DEG = 15.0
EXPOSURE = -4.0

FIGURE = Figure(
    key="fig17_profile", label="Supplement Fig. 17", title="Rectangular and triangular profiles",
    paper="A plate with 3 000 uniformly distributed scratches rendered twice; depth and width stay the same, "
          "only the profile changes from rectangular (left) to triangular (right). The different scratch "
          "response function changes the reflectance and thus the colour of the scratches.",
    scratches="3 000 scratches (Generate operator, same seed for both), D = 1 µm, W = 2 µm, D[1.1, 0.03]; "
              "rectangular (left) and triangular (right); aluminium, coherence diameter 30 µm",
    design="The Fig. 7(b) set-up: a small lamp 40° above the table, the camera 15° above its mirror direction, "
           "so the lamp's reflection lies beyond the plate's far edge and the glints of scratches "
           "perpendicular to the half vector form arcs across the plate.",
    renders=(
        Render("rectangular", "rectangular grooves: pastel interference colours on arcs around the reflection",
               {"profile": "RECTANGULAR"}, resolution=(640, 480), samples=256, paper_minutes=30),
        Render("triangular", "V-grooves: facet reflections spread the glints, whiter",
               {"profile": "TRIANGULAR"}, resolution=(640, 480), samples=256, paper_minutes=31),
    ),
)


def build_scene(scene, *, profile: str = "RECTANGULAR", resolution=(640, 480), samples: int = 256,
                count: int | None = None):
    """The plate with the given scratch profile; returns the plate. ``count`` overrides 3 000 (tests)."""
    import bpy

    from . import staging

    plate = staging.metal_plate("Scratched plate", PLATE_M, metal="Al")
    staging.operator(bpy.ops.scratch.generate, plate,
                     **{**SCRATCHES, "count": count or SCRATCHES["count"], "profile": profile})
    staging.table()
    staging.point_light(scene, "Lamp", staging.towards(LAMP_ELEVATION_DEG, 0.0, 0.35), power_w=20.0,
                        radius=0.0015)
    staging.constant_world(scene, (0.01, 0.01, 0.012))
    staging.camera(scene, staging.towards(LAMP_ELEVATION_DEG + CAMERA_ABOVE_MIRROR_DEG, 180.0, 0.24),
                   (0.0, 0.004, 0.0), lens_mm=50.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return plate
