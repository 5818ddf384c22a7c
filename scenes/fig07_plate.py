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
EXPOSURE = -3.5

FIGURE = Figure(
    key="fig07_plate", label="Fig. 7(b)", title="Scratched plate",
    paper="The paper's Fig. 7 sets renderings beside photographs of scratched objects; (b) is a metal plate "
          "with 3 000 random scratches: iridescent glints that circle the light's reflection, each scratch "
          "lighting up where it lies perpendicular to the half vector, coloured by diffraction.",
    scratches="3 000 scratches (Generate operator: random directions, arcs bent up to ±30°, 2–6 cm), "
              "G_D[250, 80] nm, G_W[4, 1.3] µm, D[1.1, 0.04], rectangular; aluminium, coherence diameter 30 µm",
    design="A 10 cm aluminium plate on a dark table in a dark studio, one small lamp (a 3 mm sphere 35 cm away, "
           "40° high) and the camera on the other side 15° above the lamp's mirror direction (24 cm, 50 mm lens): "
           "the lamp's reflection lies at the plate's far edge, and the glints of the scratches perpendicular to "
           "the half vector form arcs around it across the whole plate, coloured by diffraction a few degrees "
           "off the highlight.",
    renders=(Render("lamp", "3 000 random scratches around a lamp's reflection", {},
                    resolution=(720, 540), samples=512, paper_minutes=15, paper_megapixels=1.0),),
)


def build_scene(scene, *, resolution=(720, 540), samples: int = 512, count: int | None = None):
    """The plate, its table, the lamp and the camera; returns the plate. ``count`` overrides 3 000 (tests)."""
    from . import staging

    return staging.studio_plate(scene, {**SCRATCHES, "count": count or SCRATCHES["count"]}, resolution=resolution,
                                samples=samples, exposure=EXPOSURE, size_m=PLATE_M)
