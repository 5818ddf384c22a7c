"""Fig. 7(b): an aluminium plate with 3 000 random scratches under a small lamp.

The supplement's parameters: depth G_D[250, 80] nm, width G_W[4, 1.3] µm,
depth variation D[1.1, 0.04].  The scratches are put on with the add-on's
**Generate Scratches** operator (random directions, gentle arcs, 2–6 cm long),
exactly as a user would from the Object → Scratches panel.
"""
from __future__ import annotations

import math

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "SCRATCHES"]

PLATE_M = 0.10
#: The generator's settings: the supplement's distributions (nanometres) and our lengths and bend.
SCRATCHES = dict(count=3000, seed=7, length_min=0.02, length_max=0.06, bend=math.radians(30),
                 depth_distribution="GAUSSIAN", depth_mean=250.0, depth_std=80.0,
                 width_distribution="GAUSSIAN", width_mean=4000.0, width_std=1300.0,
                 depth_variation_amplitude=1.1, depth_variation_frequency=0.04)
LAMP_ELEVATION_DEG = 40.0
#: The camera looks from a little above the lamp's mirror direction: its reflection lies just beyond the
#: plate's far edge and the arcs around it cross the plate, coloured a few degrees off the highlight.
CAMERA_ABOVE_MIRROR_DEG = 15.0
EXPOSURE = -3.5

FIGURE = Figure(
    key="fig07_plate", label="Fig. 7(b)", title="Scratched plate",
    paper="The paper's Fig. 7 sets renderings beside photographs of scratched objects; (b) is a metal plate "
          "with 3 000 random scratches: iridescent glints that circle the light's reflection, each scratch "
          "lighting up where it lies perpendicular to the half vector, coloured by diffraction.",
    scratches="3 000 scratches (Generate operator: random directions, arcs bent up to ±30°, 2–6 cm), "
              "G_D[250, 80] nm, G_W[4, 1.3] µm, D[1.1, 0.04], rectangular; aluminium, coherence diameter 30 µm",
    design="A 10 cm aluminium plate on a dark table in a dark studio, one small lamp (a 3 mm sphere, 35 cm "
           "away) and the camera opposite it at the same 40° elevation, so the lamp's reflection sits in the "
           "middle of the plate and the scratch glints form rings around it.",
    renders=(Render("lamp", "3 000 random scratches around a lamp's reflection", {},
                    resolution=(640, 480), samples=256, paper_minutes=15, paper_megapixels=1.0),),
)


def build_scene(scene, *, resolution=(640, 480), samples: int = 256, count: int | None = None):
    """The plate, its table, the lamp and the camera; returns the plate. ``count`` overrides 3 000 (tests)."""
    import bpy

    from . import staging

    plate = staging.metal_plate("Scratched plate", PLATE_M, metal="Al")
    staging.operator(bpy.ops.scratch.generate, plate, **{**SCRATCHES, "count": count or SCRATCHES["count"]})
    staging.table()
    staging.point_light(scene, "Lamp", staging.towards(LAMP_ELEVATION_DEG, 0.0, 0.35), power_w=20.0,
                        radius=0.0015)
    staging.constant_world(scene, (0.01, 0.01, 0.012))
    staging.camera(scene, staging.towards(LAMP_ELEVATION_DEG + CAMERA_ABOVE_MIRROR_DEG, 180.0, 0.24),
                   (0.0, 0.004, 0.0), lens_mm=50.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return plate
