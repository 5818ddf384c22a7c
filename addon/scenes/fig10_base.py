"""Fig. 10: a plate with 1 500 scratches of D = 250 nm, W = 1 µm, D[1.1, 0.04], specular against diffuse base.

The scratch model describes the specular (coherent) reflection of a scratched
surface; a diffuse base adds an incoherent Lambertian term ρ_d/π below it
(the Object → Scratches *Diffuse Base* colour).  On aluminium (F ≈ 0.91)
energy allows ρ_d ≤ 1 − F, so the diffuse plate uses ρ_d = 0.08: a satin
finish instead of a polished one, with the same scratches.
"""
from __future__ import annotations

import math

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "SCRATCHES", "DIFFUSE_REFLECTANCE"]

PLATE_M = 0.10
SCRATCHES = dict(count=1500, seed=10, length_min=0.02, length_max=0.06, bend=math.radians(30),
                 depth_distribution="GAUSSIAN", depth_mean=250.0, depth_std=0.0,
                 width_distribution="GAUSSIAN", width_mean=1000.0, width_std=0.0,
                 depth_variation_amplitude=1.1, depth_variation_frequency=0.04)
DIFFUSE_REFLECTANCE = (0.08, 0.08, 0.08)
LAMP_ELEVATION_DEG = 40.0
CAMERA_ABOVE_MIRROR_DEG = 15.0
EXPOSURE = -2.5

FIGURE = Figure(
    key="fig10_base", label="Fig. 10 (b, c)", title="Specular and diffuse base",
    paper="A scratched plate with 1 500 scratches whose base reflectance is specular (b) or diffuse (c): the "
          "scratch glints keep their colours on both, while the plate itself turns from a mirror of its "
          "surroundings into a matte surface.",
    scratches="1 500 scratches (Generate operator, same seed for both), D = 250 nm, W = 1 µm, D[1.1, 0.04], "
              "rectangular; aluminium, coherence diameter 30 µm; diffuse base ρ_d = 0.08 (the most aluminium's "
              "F ≈ 0.91 leaves)",
    design="Outdoors under Blender's sky with its sun 35° high and the camera 12° above the sun's mirror "
           "direction (as in the demo): the sun's reflection lies just beyond the plate, the scratch glints arc "
           "around it. The polished plate mirrors the dark-blue sky behind the camera; the satin plate is lit "
           "by sun and sky and shows as grey, with the same glints on top.",
    renders=(
        Render("specular", "specular base: a mirror of the sky, with iridescent glints",
               {"diffuse": False}, resolution=(640, 400), samples=256, paper_minutes=23),
        Render("diffuse", "diffuse base (ρ_d = 0.08): a satin grey plate, the same glints",
               {"diffuse": True}, resolution=(640, 400), samples=256, paper_minutes=23),
    ),
)


def build_scene(scene, *, diffuse: bool = False, resolution=(640, 400), samples: int = 256,
                count: int | None = None):
    """The plate under sun and sky; returns the plate. ``count`` overrides 1 500 (tests)."""
    import bpy

    from . import staging

    plate = staging.metal_plate("Scratched plate", PLATE_M, metal="Al")
    if diffuse:
        plate.scratch.diffuse_reflectance = DIFFUSE_REFLECTANCE
    staging.operator(bpy.ops.scratch.generate, plate, **{**SCRATCHES, "count": count or SCRATCHES["count"]})
    staging.table()
    staging.point_light(scene, "Lamp", staging.towards(LAMP_ELEVATION_DEG, 0.0, 0.35), power_w=20.0,
                        radius=0.0015)
    staging.constant_world(scene, (0.01, 0.01, 0.012))
    staging.camera(scene, staging.towards(LAMP_ELEVATION_DEG + CAMERA_ABOVE_MIRROR_DEG, 180.0, 0.24),
                   (0.0, 0.004, 0.0), lens_mm=50.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return plate
