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
EXPOSURE = -2.5

FIGURE = Figure(
    key="fig10_base", label="Fig. 10 (b, c)", title="Specular and diffuse base",
    paper="A scratched plate with 1 500 scratches whose base reflectance is specular (b) or diffuse (c): the "
          "scratch glints keep their colours on both, while the plate itself turns from a mirror of its "
          "surroundings into a matte surface.",
    scratches="1 500 scratches (Generate operator, same seed for both), D = 250 nm, W = 1 µm, D[1.1, 0.04], "
              "rectangular; aluminium, coherence diameter 30 µm; diffuse base ρ_d = 0.08 (the most aluminium's "
              "F ≈ 0.91 leaves)",
    design="The Fig. 7(b) studio: one small lamp, the camera 15° above its mirror direction, dark walls. The "
           "polished plate mirrors the dark studio and shows black between the glints; the satin plate is lit "
           "by the lamp and shows as grey, with the same glints on top. (Under an open sky both plates look "
           "alike: the mirror then reflects the bright sky as much as the diffuse base scatters the sun.)",
    renders=(
        Render("specular", "specular base: a black mirror of the dark studio between the glints",
               {"diffuse": False}, resolution=(720, 540), samples=512, paper_minutes=23),
        Render("diffuse", "diffuse base (ρ_d = 0.08): a satin grey plate, the same glints",
               {"diffuse": True}, resolution=(720, 540), samples=512, paper_minutes=23),
    ),
)


def build_scene(scene, *, diffuse: bool = False, resolution=(720, 540), samples: int = 512,
                count: int | None = None):
    """The plate with a specular or a diffuse base in the lamp studio; returns the plate. ``count`` overrides
    1 500 (tests)."""
    from . import staging

    return staging.studio_plate(scene, {**SCRATCHES, "count": count or SCRATCHES["count"]}, resolution=resolution,
                                samples=samples, exposure=EXPOSURE, size_m=PLATE_M,
                                diffuse_reflectance=DIFFUSE_REFLECTANCE if diffuse else None)
