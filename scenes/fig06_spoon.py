"""Fig. 6 (bottom): a silver spoon with 100 000 scratches, U_D[0, 6] µm, U_W[0, 6] µm, D[1.1, 0.04].

The paper scratched its spoon with its editing tool and rendered it three
times (69, 83 and 368 min).  Here the spoon is modelled in code
(:func:`.shapes.spoon`: an ellipsoidal bowl, a neck and a handle lifted
towards its end) and scratched as use scratches cutlery: the **Spray** brush
along replayed strokes that circle inside the bowl (stirring, scraping a
plate) and run along the handle (the drawer, the dishwasher), a few long
**Pen** scratches, then random wear everywhere with the **Generate** operator,
as many as make 100 000 in all.  Every scratch draws its depth and width from
U[0, 6] µm and varies in depth along its length, D[1.1, 0.04].
"""
from __future__ import annotations

import math

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "TOTAL_SCRATCHES", "LOOKS", "painted_strokes"]

TOTAL_SCRATCHES = 100_000
#: U_D[0, 6] µm, U_W[0, 6] µm, D[1.1, 0.04] (the operators take nanometres).
LOOKS = dict(depth_distribution="UNIFORM", depth_min=0.0, depth_max=6000.0,
             width_distribution="UNIFORM", width_min=0.0, width_max=6000.0,
             depth_variation_amplitude=1.1, depth_variation_frequency=0.04)
LENGTHS_M = (0.0015, 0.006)
BOWL_CENTRE_M = 0.029           # the bowl's middle, metres from its tip (shapes.SPOON_BOWL_M)
#: The three pictures: (lamp elevation, lamp azimuth, camera elevation, camera azimuth, camera distance, lens mm,
#: camera target) — degrees, metres; azimuth 0 towards +Y, 90 towards +X (the handle).
VIEWS = {
    "lamp": (40.0, 0.0, 55.0, 180.0, 0.42, 50.0, (0.0, 0.0, 0.005)),
    "handle": (30.0, 90.0, 28.0, 270.0, 0.40, 50.0, (0.01, 0.0, 0.008)),
    "bowl": (50.0, 20.0, 62.0, 200.0, 0.17, 60.0, (-0.066, 0.0, 0.004)),
}
EXPOSURE = -1.5

FIGURE = Figure(
    key="fig06_spoon", label="Fig. 6 (bottom)", title="Scratched spoon",
    paper="The bottom row of Fig. 6: a spoon worn by use, 100 000 scratches made with the editing tool and "
          "varying in depth along their length, rendered three times (69, 83 and 368 min): the concave bowl "
          "and the convex back of the handle each gather the glints around a light's reflection.",
    scratches="100 000 scratches, U_D[0, 6] µm, U_W[0, 6] µm, D[1.1, 0.04], rectangular: painted with the Spray "
              "brush (8 circling strokes in the bowl, 6 strokes along the handle) and the Pen (4 long "
              "scratches), the rest generated (random, 1.5–6 mm); silver, coherence diameter 30 µm",
    design="A 19 cm silver spoon (its outline modelled in code, a few coarse facets visible at the bowl's rim) on "
           "dark cloth in a dark studio with one small lamp (a 3 mm sphere 35 cm away). lamp: the spoon seen from "
           "the side, the lamp 40° high beyond it: the lamp's reflection is a bright streak on the middle of the "
           "handle and a highlight on the bowl's near rim; fine coloured speckle covers the bowl and the handle's "
           "end, the glints of scratches too short (1.5–6 mm) to be told apart at this size. handle: the lamp low "
           "from the handle's end, the camera on the other side looking along the spoon: the reflection runs the "
           "whole length of the handle, white with coloured speckle, and a highlight sits on the bowl's near rim. "
           "bowl: a close-up of the bowl, where the glints of the circling strokes draw a swirl of coloured arcs "
           "around the lamp's reflection in the bowl's bottom — the clearest picture of the three.",
    renders=(Render("lamp", "the spoon under a lamp: its reflection on the handle, coloured speckle over the bowl",
                    {"view": "lamp"}, resolution=(720, 480), samples=32, paper_minutes=69),
             Render("handle", "low light along the handle", {"view": "handle"}, resolution=(720, 480),
                    samples=32, paper_minutes=83),
             Render("bowl", "close-up of the bowl", {"view": "bowl"}, resolution=(600, 480), samples=32,
                    paper_minutes=368)),
)


def painted_strokes(rng: np.random.Generator):
    """The brush work: (kind, (x from the bowl's tip, t across) points, operator settings) per stroke."""
    strokes = []
    for _ in range(8):  # stirring and scraping: loops inside the bowl
        radius = rng.uniform(0.2, 0.8)
        start = rng.uniform(0.0, 2.0 * np.pi)
        a = np.linspace(start, start + rng.uniform(1.0, 2.0) * np.pi, 40)
        points = np.column_stack([BOWL_CENTRE_M + 0.024 * radius * np.cos(a), radius * np.sin(a)])
        strokes.append(("SPRAY", points, dict(radius=0.004, density=300.0, jitter=math.radians(15))))
    for _ in range(6):  # the drawer: along the handle
        t0 = rng.uniform(-0.6, 0.6)
        x = np.linspace(rng.uniform(0.065, 0.10), rng.uniform(0.14, 0.185), 16)
        points = np.column_stack([x, np.clip(t0 + 0.1 * rng.normal() * (x - x[0]) / 0.1, -0.8, 0.8)])
        strokes.append(("SPRAY", points, dict(radius=0.003, density=300.0, jitter=math.radians(8))))
    for _ in range(4):  # long single scratches
        x = np.linspace(rng.uniform(0.01, 0.05), rng.uniform(0.09, 0.17), 24)
        points = np.column_stack([x, np.clip(rng.uniform(-0.5, 0.5) + 0.2 * np.sin(x * 40.0), -0.9, 0.9)])
        strokes.append(("PEN", points, {}))
    return strokes


def build_scene(scene, *, view: str = "lamp", resolution=(720, 480), samples: int = 128, scale: float = 1.0,
                seed: int = 6):
    """The spoon on dark cloth, lit and seen as ``view`` says (a key of ``VIEWS``); returns the spoon's top.
    ``scale`` < 1 scratches less (tests)."""
    import bpy

    from ..addon import storage
    from . import shapes, staging

    if view not in VIEWS:
        raise ValueError(f"view must be one of {sorted(VIEWS)}, not {view!r}")
    silver = staging.material("Silver", (0.97, 0.96, 0.93), roughness=0.05, metallic=1.0)
    top, _ = shapes.spoon("Spoon", mat=silver, location=(0.0, 0.0, 0.0015))
    top.scratch_iridescence.base_material = "Ag"
    for index, (kind, points, settings) in enumerate(painted_strokes(np.random.default_rng(seed))):
        if kind == "SPRAY":
            settings = {**settings, "density": settings["density"] * scale, "length_min": LENGTHS_M[0],
                        "length_max": LENGTHS_M[1]}
        world = shapes.spoon_surface(points[:, 0], points[:, 1]) + np.array([0.0, 0.0, 0.0015])
        staging.operator(bpy.ops.scratch.paint_stroke, top, stroke=staging.stroke(world), brush_mode=kind,
                         seed=seed + index, **LOOKS, **settings)
    painted = storage.scratch_summary(top)["count"]
    staging.operator(bpy.ops.scratch.generate, top, count=max(1, round(TOTAL_SCRATCHES * scale) - painted),
                     seed=seed, mode="ADD", length_min=LENGTHS_M[0], length_max=LENGTHS_M[1], **LOOKS)

    cloth = staging.material("Dark cloth", (0.015, 0.015, 0.02), roughness=1.0)
    staging.plane("Cloth", 1.0, (0.0, 0.0, 0.0), cloth)
    lamp_elevation, lamp_azimuth, camera_elevation, camera_azimuth, distance, lens, target = VIEWS[view]
    staging.point_light(scene, "Lamp", staging.towards(lamp_elevation, lamp_azimuth, 0.35, target), power_w=20.0,
                        radius=0.0015)
    staging.constant_world(scene, (0.01, 0.01, 0.012))
    staging.camera(scene, staging.towards(camera_elevation, camera_azimuth, distance, target), target, lens_mm=lens)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return top
