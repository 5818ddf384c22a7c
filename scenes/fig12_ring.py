"""Fig. 12 (left): a worn finger ring with 547 381 scratches of D = 500 nm, W = 1 µm.

The largest scratch count the paper puts on a curved, closed mesh, scratched
with its editing tool.  Here the ring is modelled in code (:func:`.shapes.ring`:
a band of rounded-rectangular cross-section, 17 mm inside, 6 mm wide, 2 mm
thick) and scratched as an artist would: the **Spray** brush along replayed
strokes around the band (the fine, aligned wear of a ring turned on a finger
and rubbed against things), then the **Generate** operator for random wear
everywhere, as many as make the paper's 547 381 in all.  A scratch that crosses
one of the ring's two UV seams (around the ring and around the band's
cross-section, the latter on the finger's side) is stored as one piece per
side, so the file holds a few per cent more polylines than scratches put on.
"""
from __future__ import annotations

import math

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "TOTAL_SCRATCHES", "LOOKS", "RING", "spray_strokes"]

TOTAL_SCRATCHES = 547_381
#: D = 500 nm, W = 1 µm (the operators take nanometres), rectangular, no variation.
LOOKS = dict(depth_distribution="GAUSSIAN", depth_mean=500.0, depth_std=0.0,
             width_distribution="GAUSSIAN", width_mean=1000.0, width_std=0.0)
#: Inner radius, width, thickness (metres) and the mesh's quads around and across the band.
RING = dict(radius_m=0.0085, width_m=0.006, thickness_m=0.002, segments=192, sections=48)
LENGTHS_M = (0.0004, 0.0016)
#: The spray strokes: circles around the band on its outer face (v = 0.5 its centre line, ±0.09 about 2.2 mm
#: from it towards the edges; shapes.ring_surface).
STROKE_V = (0.41, 0.455, 0.5, 0.545, 0.59)
STROKE_TURNS = 2            # each stroke goes this many times around
SPRAY = dict(radius=0.001, density=120.0, jitter=math.radians(12))
#: (elevation, azimuth) in degrees of the lamp and the camera, seen from the ring (azimuth 0: +Y, 90: +X)
LAMP_DEG, CAMERA_DEG = (35.0, 160.0), (30.0, 180.0)
EXPOSURE = -2.0

FIGURE = Figure(
    key="fig12_ring", label="Fig. 12 (left)", title="Worn ring",
    paper="The supplement's densest curved object: a ring carrying 547 381 scratches of D = 500 nm and "
          "W = 1 µm, made with the paper's editing tool and rendered at 1 MP with only 3 wavelengths per "
          "sample (23 min). We have not seen the figure itself; a ring this densely scratched shows "
          "diffraction sparkle all over its polished band wherever a light is near its mirror direction.",
    scratches="547 381 scratches put on (Spray brush: 5 strokes twice around the band's outer face, ±12° "
              "around the stroke; Generate: random directions for the rest), 0.4–1.6 mm long, D = 500 nm, "
              "W = 1 µm, rectangular, no variation; gold, coherence diameter 30 µm; stored as one piece per "
              "side of a UV seam",
    design="A gold ring of 17 mm inner diameter lying on dark velvet, seen from 12 cm at 35° with a 100 mm macro "
           "lens, lit by one small lamp on the far side (a 3 mm sphere 35 cm away, 40° high) and a dim room. The "
           "lamp's reflection is an orange highlight on the inside of the band's far side and another on the front "
           "of its near side; around them the whole band carries a mottled iridescent sheen, green beside gold and "
           "orange, the 1 µm grooves diffracting far from the mirror direction. Single scratches and the sprayed "
           "streaks along the circumference are far below a pixel at this size and do not stand out. The velvet "
           "around and inside the ring is speckled with coloured dots: light the ring mirrors onto the diffuse "
           "cloth, found by chance at these samples per pixel (caustic noise). The paper renders 3 wavelengths per "
           "sample; we render 4 (hero wavelength sampling) — the benchmark table compares per wavelength sample.",
    renders=(Render("lamp", "547 381 scratches on a gold ring around a lamp's reflection", {},
                    resolution=(600, 450), samples=12, paper_minutes=23, paper_megapixels=1.0,
                    paper_wavelengths=3),),
)


def spray_strokes(ring=RING, stroke_v=STROKE_V, turns: int = STROKE_TURNS, points_per_turn: int = 96):
    """World-space stroke points (metres) on the band's outer face, one circle per value of the cross-section
    parameter v (:func:`.shapes.ring_surface`), ``turns`` times around (the ring's middle at z = 0)."""
    from .shapes import ring_surface

    strokes = []
    for index, v in enumerate(stroke_v):
        u = index / len(stroke_v) + np.linspace(0.0, turns, turns * points_per_turn + 1)
        strokes.append(ring_surface(u, v, ring["radius_m"], ring["width_m"], ring["thickness_m"]))
    return strokes


def build_scene(scene, *, resolution=(600, 450), samples: int = 48, scale: float = 1.0, seed: int = 3):
    """The ring on velvet under a lamp; returns the ring. ``scale`` < 1 scratches less (tests)."""
    import bpy

    from ..addon import storage
    from . import shapes, staging

    gold = staging.material("Polished gold", (1.0, 0.77, 0.34), roughness=0.05, metallic=1.0)
    lift = 0.5 * RING["width_m"]  # the ring lies on its side on the velvet
    ring = shapes.ring("Ring", RING["radius_m"], RING["width_m"], RING["thickness_m"], segments=RING["segments"],
                       sections=RING["sections"], mat=gold)
    ring.scratch_iridescence.base_material = "Au"
    for index, points in enumerate(spray_strokes()):
        staging.operator(bpy.ops.scratch.paint_stroke, ring, stroke=staging.stroke(points), brush_mode="SPRAY",
                         seed=seed + index, length_min=LENGTHS_M[0], length_max=LENGTHS_M[1],
                         **{**SPRAY, "density": SPRAY["density"] * scale}, **LOOKS)
    painted = storage.scratch_summary(ring)["count"]
    staging.operator(bpy.ops.scratch.generate, ring, count=max(1, round(TOTAL_SCRATCHES * scale) - painted),
                     seed=seed, mode="ADD", length_min=LENGTHS_M[0], length_max=LENGTHS_M[1], **LOOKS)
    ring.location.z = lift  # after the strokes, which are given with the ring's middle at z = 0

    velvet = staging.material("Velvet", (0.012, 0.010, 0.014), roughness=1.0)
    staging.plane("Velvet", 0.5, (0.0, 0.0, 0.0), velvet)
    staging.point_light(scene, "Lamp", staging.towards(LAMP_DEG[0], LAMP_DEG[1], 0.35, (0.0, 0.0, lift)),
                        power_w=20.0, radius=0.0015)
    staging.constant_world(scene, (0.02, 0.018, 0.016))
    staging.camera(scene, staging.towards(CAMERA_DEG[0], CAMERA_DEG[1], 0.12, (0.0, 0.0, lift)), (0.0, 0.0, lift),
                   lens_mm=100.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return ring
