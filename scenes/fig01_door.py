"""Fig. 1 (right) and Fig. 6 (top left): a metal door with 370 000 scratches, U_D[0, 6] µm, U_W[0, 6] µm.

The paper scratched its door with its editing tool, once without and once with
depth variation D[1.1, 0.04].  Here the door is modelled in code
(:func:`.shapes.door`: a leaf with two raised panels, a lever handle on a
round rose) and scratched as use scratches a door: the **Spray** brush along
replayed strokes where hands, keys and shoes meet it (arcs around the handle,
a band where the leaf is pushed, scuffs along the bottom), a few long **Pen**
scratches (something carried past), then general wear over the whole front
with the **Generate** operator, as many as make 370 000 in all.  Every
scratch draws its depth and width from U[0, 6] µm.
"""
from __future__ import annotations

import math

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "TOTAL_SCRATCHES", "LOOKS", "VARIATION", "painted_strokes", "DOOR_M",
           "HANDLE"]

DOOR_M = (0.86, 2.0)            # leaf width, height
HANDLE = (0.355, 1.05)          # the handle's rose: x from the leaf's middle, height (shapes.door)
TOTAL_SCRATCHES = 370_000
#: U_D[0, 6] µm, U_W[0, 6] µm (the operators take nanometres).
LOOKS = dict(depth_distribution="UNIFORM", depth_min=0.0, depth_max=6000.0,
             width_distribution="UNIFORM", width_min=0.0, width_max=6000.0)
#: Fig. 6 (top left): D[1.1, 0.04].
VARIATION = dict(depth_variation_amplitude=1.1, depth_variation_frequency=0.04)
CAMERA = (0.75, -2.3, 1.55)
LAMP_REFLECTION = (0.12, 1.3)   # where on the door (x, height) the lamp's reflection falls
LAMP_DISTANCE_M = 1.2           # the lamp's distance from the door
EXPOSURE = 0.5

FIGURE = Figure(
    key="fig01_door", label="Fig. 1 (right), Fig. 6 (top left)", title="Scratched door",
    paper="The paper's teaser shows, beside the dining table, a metal door worn by use, 370 000 scratches made "
          "with the editing tool (Fig. 1 right); Fig. 6 (top left) renders the same door with depth variation "
          "D[1.1, 0.04], which breaks each scratch's glint into dashes of changing colour.",
    scratches="370 000 scratches, U_D[0, 6] µm, U_W[0, 6] µm, rectangular, without and with D[1.1, 0.04]: "
              "painted with the Spray brush (12 arcs around the handle, 6 strokes where the leaf is pushed, 8 "
              "scuffs along the bottom) and the Pen (5 long scratches), the rest generated (random, 5–30 mm); "
              "aluminium front, coherence diameter 30 µm",
    design="A 0.86 × 2 m door with two raised panels and a lever handle, set in a dark wall, seen from 2.4 m at eye "
           "height and from the side of the handle. A small lamp (a 1.5 cm sphere, the white dot at the left: it "
           "hangs 1.2 m in front of the door, inside the view) puts its reflection on the upper panel above the "
           "handle. The glints of the scratches perpendicular to the half vector gather around it as a halo of "
           "coloured sparkle some 20 cm across, fading outwards; at this distance single scratches are below a "
           "pixel, so the rings the plates show stay a cloud of coloured dots, and the brush work around the handle "
           "does not stand out. Elsewhere the door mirrors the dim hall. The floor in front of the door is speckled "
           "with bright dots: lamp light that the door's metal mirrors onto the diffuse floor, which the path tracer"
           " finds only by chance at these samples per pixel (caustic noise, not scratches). With depth variation"
           " the halo looks the same, a little sparser.",
    renders=(Render("door", "370 000 scratches, generated and painted, around a lamp's reflection", {},
                    resolution=(540, 720), samples=48, paper_minutes=32),
             Render("variation", "the same scratches with depth variation D[1.1, 0.04] (Fig. 6 top left)",
                    {"variation": True}, resolution=(540, 720), samples=48, paper_minutes=33)),
)


def painted_strokes(rng: np.random.Generator, width_m: float = DOOR_M[0], height_m: float = DOOR_M[1]):
    """The brush work on the door's front: (kind, points (x, height), operator settings) per replayed stroke.

    ``x`` is measured from the leaf's middle; the points lie in the front's plane."""
    hx, hz = HANDLE
    strokes = []
    for _ in range(12):  # keys and rings around the handle: arcs about the rose
        radius = rng.uniform(0.035, 0.09)
        start = rng.uniform(0.0, 2.0 * np.pi)
        t = np.linspace(start, start + rng.uniform(0.5, 1.4) * np.pi, 32)
        points = np.column_stack([hx + radius * np.cos(t), hz + radius * np.sin(t)])
        strokes.append(("SPRAY", points, dict(radius=0.012, density=60.0, jitter=math.radians(25),
                                              length_min=0.004, length_max=0.02)))
    for _ in range(6):  # the push band: hands and bags along the lock side, roughly vertical
        x = rng.uniform(0.15, 0.40)
        z = rng.uniform(0.8, 1.3)
        t = np.linspace(0.0, 1.0, 12)
        points = np.column_stack([x + 0.04 * t * rng.normal(), z + rng.uniform(0.2, 0.45) * t])
        strokes.append(("SPRAY", points, dict(radius=0.04, density=80.0, jitter=math.radians(20),
                                              length_min=0.01, length_max=0.05)))
    for _ in range(8):  # shoe scuffs along the bottom, roughly horizontal
        x0 = rng.uniform(-0.4, 0.2)
        z = rng.uniform(0.04, 0.30)
        t = np.linspace(0.0, 1.0, 12)
        points = np.column_stack([x0 + rng.uniform(0.1, 0.25) * t, z + 0.02 * rng.normal() * t])
        strokes.append(("SPRAY", points, dict(radius=0.03, density=120.0, jitter=math.radians(10),
                                              length_min=0.01, length_max=0.06)))
    for _ in range(5):  # long single scratches: something carried past
        a = rng.uniform((-0.38, 0.3), (0.38, 1.8))
        direction = rng.uniform(-0.5, 0.5) + (0.0 if rng.random() < 0.7 else 0.5 * np.pi)
        length = rng.uniform(0.2, 0.6)
        t = np.linspace(0.0, length, 16)
        points = np.column_stack([a[0] + t * np.cos(direction), a[1] + t * np.sin(direction)])
        points = np.clip(points, (-0.42, 0.02), (0.42, 1.98))
        strokes.append(("PEN", points, {}))
    return strokes


def _on_front(points_xz, rise_of):
    """World points of (x, height) pairs on the door's front (``rise_of``: its relief towards -Y there)."""
    points_xz = np.asarray(points_xz, dtype=np.float64)
    return np.column_stack([points_xz[:, 0], -rise_of(points_xz), points_xz[:, 1]])


def _lamp_position():
    """Where the lamp hangs (``LAMP_DISTANCE_M`` from the door) for its reflection to fall at ``LAMP_REFLECTION``."""
    camera = np.array(CAMERA)
    reflection = np.array([LAMP_REFLECTION[0], 0.0, LAMP_REFLECTION[1]])
    ray = reflection - camera
    mirrored = np.array([ray[0], -ray[1], ray[2]])  # reflected by the door's plane y = 0
    return tuple(reflection + mirrored * (LAMP_DISTANCE_M / -mirrored[1]))


def build_scene(scene, *, variation: bool = False, resolution=(540, 720), samples: int = 192, scale: float = 1.0,
                seed: int = 5):
    """The door in its wall, the hall and the lamp; returns the door's front. ``scale`` < 1 scratches less
    (tests); ``variation`` adds D[1.1, 0.04] to every scratch (Fig. 6 top left)."""
    import bpy

    from ..addon import storage
    from . import shapes, staging

    metal = staging.material("Door aluminium", (0.91, 0.92, 0.92), roughness=0.05, metallic=1.0)
    handle = staging.material("Handle steel", (0.8, 0.8, 0.78), roughness=0.12, metallic=1.0)
    front, _ = shapes.door("Door", width_m=DOOR_M[0], height_m=DOOR_M[1], handle=HANDLE, mat=metal,
                           handle_mat=handle)
    front.scratch_iridescence.base_material = "Al"
    looks = {**LOOKS, **(VARIATION if variation else {})}
    relief = shapes.door_relief(DOOR_M[0], DOOR_M[1])
    for index, (kind, points, settings) in enumerate(painted_strokes(np.random.default_rng(seed))):
        if kind == "SPRAY":
            settings = {**settings, "density": settings["density"] * scale}
        staging.operator(bpy.ops.scratch.paint_stroke, front, stroke=staging.stroke(_on_front(points, relief)),
                         brush_mode=kind, seed=seed + index, **looks, **settings)
    painted = storage.scratch_summary(front)["count"]
    staging.operator(bpy.ops.scratch.generate, front, count=max(1, round(TOTAL_SCRATCHES * scale) - painted),
                     seed=seed, mode="ADD", length_min=0.005, length_max=0.03, **looks)

    wall = staging.material("Hall wall", (0.05, 0.06, 0.055), roughness=0.9)
    half = 0.5 * DOOR_M[0] + 0.02
    for name, size, centre in (("left", (1.5, 0.2, 2.6), (-half - 0.75, 0.1, 1.3)),
                               ("right", (1.5, 0.2, 2.6), (half + 0.75, 0.1, 1.3)),
                               ("top", (2 * half, 0.2, 0.58), (0.0, 0.1, DOOR_M[1] + 0.02 + 0.29))):
        shapes.box(f"Wall {name}", size, centre, wall)
    frame = staging.material("Door frame", (0.02, 0.02, 0.022), roughness=0.4)
    for name, size, centre in (("left", (0.05, 0.03, 2.07), (-half - 0.005, -0.005, 1.035)),
                               ("right", (0.05, 0.03, 2.07), (half + 0.005, -0.005, 1.035)),
                               ("top", (2 * half + 0.06, 0.03, 0.05), (0.0, -0.005, DOOR_M[1] + 0.035))):
        shapes.box(f"Frame {name}", size, centre, frame)
    floor = staging.material("Hall floor", (0.03, 0.022, 0.016), roughness=0.6)
    staging.plane("Floor", (6.0, 6.0), (0.0, -2.0, 0.0), floor)

    staging.point_light(scene, "Hall lamp", _lamp_position(), power_w=40.0, radius=0.015, colour=(1.0, 0.88, 0.7))
    staging.constant_world(scene, (0.012, 0.012, 0.014))
    staging.camera(scene, CAMERA, (0.05, 0.0, 1.0), lens_mm=28.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return front
