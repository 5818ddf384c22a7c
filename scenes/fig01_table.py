"""Fig. 1 (middle): a dining table with 300 000 scratches, U_D[0, 6] µm, U_W[0, 6] µm.

The paper scratched this table with its editing tool.  Here, as an artist
would: the **Spray** brush along replayed strokes where use leaves marks —
circular wiping arcs around the places where plates are put down and turned,
short straight drags where cutlery slides — and a few long single **Pen**
scratches (a knife, a dragged bowl); then general wear everywhere with the
**Generate** operator, as many random scratches as make 300 000 in all.  Every scratch, generated
or painted, draws its depth and width from U[0, 6] µm.
"""
from __future__ import annotations

import math

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "TOTAL_SCRATCHES", "LOOKS", "painted_strokes", "window_environment"]

TABLE_M = (1.6, 0.9)
TOTAL_SCRATCHES = 300_000
#: U_D[0, 6] µm, U_W[0, 6] µm (the operators take nanometres).
LOOKS = dict(depth_distribution="UNIFORM", depth_min=0.0, depth_max=6000.0,
             width_distribution="UNIFORM", width_min=0.0, width_max=6000.0)
PLATES = ((-0.38, -0.12), (0.36, 0.08), (-0.05, 0.24))  # where plates stand (table centre at 0)
CAMERA = (-0.22, -0.62, 0.52)   # a diner's eye, leaning over the table
CAMERA_TARGET = (0.02, 0.08, 0.0)
LAMP_REFLECTION = (0.02, 0.02)  # where on the table the pendant lamp's reflection falls
LAMP_HEIGHT_M = 0.65
EXPOSURE = 0.0

FIGURE = Figure(
    key="fig01_table", label="Fig. 1 (middle)", title="Dining table",
    paper="The paper's teaser: a dining table whose worn top shows the colourful sparkle of 300 000 "
          "microscopic scratches around the reflections of the lights, scratched by hand with the paper's "
          "editing tool.",
    scratches="300 000 scratches, U_D[0, 6] µm, U_W[0, 6] µm, rectangular, no variation: 200 000 generated "
              "(random, 5–30 mm) and 100 000 painted (Spray brush: 36 wiping arcs around three plates, 12 "
              "cutlery drags; Pen: 6 long scratches); aluminium top, coherence diameter 30 µm",
    design="A 1.6 × 0.9 m aluminium table top in a dim room whose environment (made in code) has a window "
           "behind the table; a pendant lamp hangs where its reflection falls between the plates, seen from "
           "a seated diner's eye height. The glints of scratches perpendicular to the lamp's half vector form "
           "coloured rings around its reflection, and the wiping arcs around the plates stand out as denser, "
           "aligned sparkle where they cross those rings (beside the right-hand plate and in front of the left "
           "one). The window's reflection is a bright mirror image in which the much fainter glints are lost; "
           "the window is dim, so that the exposure can show the sparkle around the lamp.",
    renders=(Render("table", "300 000 scratches, generated and painted, under a pendant lamp and a window", {},
                    resolution=(960, 600), samples=384, paper_minutes=93),
             Render("worn", "beyond the paper: the same scratches with crossings as one height field (the deeper "
                            "groove wins where two cross) and the bounded depth phase (no groove reflects more "
                            "than falls on it; U[0, 6] µm grooves reach albedo 1.4 under the paper's phase). The "
                            "sparkle around the lamp is fainter and sparser (mean radiance of the ring below the "
                            "lamp −2 %: most of the image is the mirror reflection, which does not change); 14× "
                            "slower per sample, hence 64 spp and more noise",
                    {"crossings": "height_field", "depth_phase": "bounded"}, resolution=(960, 600), samples=64)),
)


def painted_strokes(rng: np.random.Generator, plates=PLATES, height: float = 0.0):
    """The brush work: (kind, points, operator settings) for every replayed stroke."""
    strokes = []
    for cx, cy in plates:
        for _ in range(10):  # wiping arcs: plates put down and turned
            radius = rng.uniform(0.10, 0.17)
            start = rng.uniform(0.0, 2.0 * np.pi)
            sweep = rng.uniform(0.6, 1.6) * np.pi
            t = np.linspace(start, start + sweep, 48)
            points = np.column_stack([cx + radius * np.cos(t), cy + radius * np.sin(t), np.full_like(t, height)])
            strokes.append(("SPRAY", points, dict(radius=0.012, density=100.0, jitter=math.radians(6),
                                                  length_min=0.01, length_max=0.04, bend=0.0)))
        for _ in range(4):  # cutlery dragged beside the plate
            angle = rng.uniform(0.0, 2.0 * np.pi)
            a = np.array([cx, cy]) + 0.2 * np.array([np.cos(angle), np.sin(angle)])
            direction = rng.uniform(0.0, 2.0 * np.pi)
            b = a + rng.uniform(0.08, 0.2) * np.array([np.cos(direction), np.sin(direction)])
            points = np.column_stack([np.linspace(a[0], b[0], 12), np.linspace(a[1], b[1], 12), np.full(12, height)])
            strokes.append(("SPRAY", points, dict(radius=0.01, density=60.0, jitter=math.radians(3),
                                                  length_min=0.01, length_max=0.04, bend=0.0)))
    for _ in range(6):  # long single scratches
        a = rng.uniform((-0.7, -0.38), (0.7, 0.38))
        direction = rng.uniform(0.0, 2.0 * np.pi)
        length = rng.uniform(0.15, 0.4)
        t = np.linspace(0.0, length, 16)
        points = np.column_stack([a[0] + t * np.cos(direction), a[1] + t * np.sin(direction), np.full_like(t, height)])
        points[:, :2] = np.clip(points[:, :2], (-0.79, -0.44), (0.79, 0.44))
        strokes.append(("PEN", points, {}))
    return strokes


def window_environment(width: int = 1024, height: int = 512) -> np.ndarray:
    """A dim room with a bright window towards +Y: an equirectangular image (row 0 up) in Blender's mapping."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    # Blender: u = 0.5 - atan2(y, x) / 2π, v = 0.5 + elevation / π (row 0 is v = 1, straight up).
    azimuth, elevation = np.meshgrid((0.5 - u) * 2.0 * np.pi, (0.5 - v) * np.pi)
    facing = np.angle(np.exp(1j * (azimuth - 0.5 * np.pi)))  # 0 towards +Y
    room = np.where(elevation > 0, 0.03 + 0.02 * np.sin(elevation), 0.015)[..., None] * np.array([1.0, 0.93, 0.85])
    window = (np.abs(facing) < math.radians(28)) & (elevation > math.radians(4)) & (elevation < math.radians(38))
    mullion = (np.abs(facing) < math.radians(0.8)) | (np.abs(elevation - math.radians(21)) < math.radians(0.8))
    sky = np.array([0.8, 0.9, 1.1]) * 0.6
    return np.where((window & ~mullion)[..., None], sky, room).astype(np.float32)


def _lamp_position(camera=CAMERA, lamp_reflection=LAMP_REFLECTION, lamp_height_m=LAMP_HEIGHT_M):
    """Where the pendant lamp hangs (``lamp_height_m`` above the table) for its reflection to fall at
    ``lamp_reflection`` as the ``camera`` sees it."""
    camera = np.array(camera)
    reflection = np.array([*lamp_reflection, 0.0])
    ray = reflection - camera
    mirrored = np.array([ray[0], ray[1], -ray[2]])
    return tuple(reflection + mirrored * (lamp_height_m / mirrored[2]))


def build_scene(scene, *, resolution=(960, 600), samples: int = 384, scale: float = 1.0, seed: int = 1,
                crossings: str = "additive", depth_phase: str = "kirchhoff", depth_variation=(0.0, 0.0),
                camera=CAMERA, camera_target=CAMERA_TARGET, lens_mm: float = 30.0, lamp_reflection=LAMP_REFLECTION,
                lamp_height_m: float = LAMP_HEIGHT_M, exposure: float = EXPOSURE):
    """The table, plates, lamp and room; returns the table top. ``scale`` < 1 scratches less (tests);
    ``crossings`` and ``depth_phase``: the top's scratch rendering options (docs/bsdf.md);
    ``depth_variation``: (amplitude, frequency) of every scratch's depth noise (the paper's D[1.1, 0.04]
    in Figs. 6 and 11; none in Fig. 1); the camera and the lamp's reflection (``scenes/fig11_table.py``
    moves them), the defaults Fig. 1's."""
    import bpy

    from . import staging

    from ..addon import storage

    top = staging.metal_plate("Table top", TABLE_M, metal="Al", height_m=0.0)
    top.scratch_iridescence.crossings, top.scratch_iridescence.depth_phase = crossings, depth_phase
    looks = dict(LOOKS)
    if depth_variation[0] > 0:
        looks.update(depth_variation_amplitude=depth_variation[0], depth_variation_frequency=depth_variation[1])
    for index, (kind, points, settings) in enumerate(painted_strokes(np.random.default_rng(seed))):
        if kind == "SPRAY":
            settings = {**settings, "density": settings["density"] * scale}
        staging.operator(bpy.ops.scratch.paint_stroke, top, stroke=staging.stroke(points), brush_mode=kind,
                         seed=seed + index, **looks, **settings)
    # General wear everywhere else: as many random scratches as make the total the paper's 300 000.
    painted = storage.scratch_summary(top)["count"]
    staging.operator(bpy.ops.scratch.generate, top, count=max(1, round(TOTAL_SCRATCHES * scale) - painted),
                     seed=seed, mode="ADD", length_min=0.005, length_max=0.03, **looks)

    porcelain = staging.material("Porcelain", (0.85, 0.85, 0.82), roughness=0.15)
    for index, (x, y) in enumerate(PLATES):
        bpy.ops.mesh.primitive_cylinder_add(vertices=96, radius=0.12, depth=0.016, location=(x, y, 0.008))
        plate = bpy.context.active_object
        plate.name = f"Plate {index + 1}"
        plate.data.materials.append(porcelain)

    staging.point_light(scene, "Pendant lamp", _lamp_position(camera, lamp_reflection, lamp_height_m), power_w=60.0,
                        radius=0.01, colour=(1.0, 0.85, 0.65))
    staging.environment_world(scene, "Room with window", window_environment())
    staging.camera(scene, camera, camera_target, lens_mm=lens_mm)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=exposure)
    return top
