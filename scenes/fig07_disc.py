"""Fig. 7(d): an aluminium disc with 3 700 random scratches under a small lamp.

The supplement's parameters: depth G_D[250, 80] nm, width G_W[5, 1.6] µm,
depth variation D[1.1, 0.03] (the Fig. 7(b) plate's, with wider scratches
and slower variation).  The paper did not scratch Fig. 7 with its editing
tool; here the **Generate Scratches** operator scatters them over the disc's
planar UV map, as a user would from the Object → Scratches panel.
"""
from __future__ import annotations

import math

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "SCRATCHES", "DISC_RADIUS_M"]

DISC_RADIUS_M = 0.045
#: The generator's settings: the supplement's distributions (nanometres) and our lengths and bend.
SCRATCHES = dict(count=3700, seed=17, length_min=0.015, length_max=0.05, bend=math.radians(25),
                 depth_distribution="GAUSSIAN", depth_mean=250.0, depth_std=80.0,
                 width_distribution="GAUSSIAN", width_mean=5000.0, width_std=1600.0,
                 depth_variation_amplitude=1.1, depth_variation_frequency=0.03)
EXPOSURE = -3.5

FIGURE = Figure(
    key="fig07_disc", label="Fig. 7(d)", title="Scratched disc",
    paper="Fig. 7 sets renderings beside photographs of scratched objects; (d) is a metal disc with 3 700 "
          "random scratches, a little wider than those of the plate in (b), whose glints circle the light's "
          "reflection in diffraction colours.",
    scratches="3 700 scratches (Generate operator: random directions, arcs bent up to ±25°, 1.5–5 cm), "
              "G_D[250, 80] nm, G_W[5, 1.6] µm, D[1.1, 0.03], rectangular; aluminium, coherence diameter 30 µm",
    design="A 9 cm aluminium disc (a flat 256-gon) on a dark table in the Fig. 7(b) studio: one small lamp 40° "
           "high, the camera on the other side 15° above the lamp's mirror direction. The lamp's reflection lies "
           "near the disc's far rim; the scratches perpendicular to the half vector light up along arcs around "
           "it across the whole disc.",
    renders=(Render("lamp", "3 700 random scratches around a lamp's reflection", {},
                    resolution=(640, 540), samples=128, paper_minutes=25),),
)


def build_scene(scene, *, resolution=(640, 540), samples: int = 512, count: int | None = None):
    """The disc, its table, the lamp and the camera; returns the disc. ``count`` overrides 3 700 (tests)."""
    import bpy

    from . import staging

    look = staging.material("Disc aluminium", (0.91, 0.92, 0.92), roughness=0.05, metallic=1.0)
    disc = staging.disc("Scratched disc", DISC_RADIUS_M, (0.0, 0.0, 0.002), look)
    disc.scratch_iridescence.base_material = "Al"
    staging.operator(bpy.ops.scratch.generate, disc, **{**SCRATCHES, "count": count or SCRATCHES["count"]})
    staging.table()
    staging.lamp_studio(scene)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return disc
