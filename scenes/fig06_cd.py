"""Fig. 6 (top right): a CD, rendered with coherent and with incoherent superposition.

The supplement's CD: 3 128 400 straight scratch segments, D = 120 nm,
W = 1 µm, on concentric tracks of pitch 1.6 µm (Stam's parameters, about 21
tracks inside one coherence area).  Here every track between radii 23 and
58 mm is one closed polyline of 143 chords, 21 875 tracks in all: 3 128 125
segments.  Concentric polygons with the same angular division stay parallel
at the track pitch, as the tracks must be; each chord deviates from the
circle by up to 14 µm, which changes nothing in a coherence area.

The editor's generator scatters random scratches and its brush follows a hand,
so the tracks are computed with numpy, written as a scratch file (format v1)
and put on the disc with the add-on's own **Import Scratches** operator, as a
user with a track file would.  That also validates the file and checks that
every track lies inside the disc's UV map.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "cd_tracks"]

DISC_RADIUS_M = 0.060        # a 120 mm disc; one UV unit = 0.12 m
HOLE_RADIUS_M = 0.0075
METAL_INNER_M = 0.022        # the aluminium layer starts here (inside: clear polycarbonate)
TRACKS_M = (0.023, 0.058)    # program area
PITCH_M = 1.6e-6
CHORDS_PER_TRACK = 143
WIDTH_M, DEPTH_M = 1e-6, 120e-9
STRIP_SIZE_M = (0.03, 0.006)  # long across the lit diameter (a wider fan), narrow along it (pure colours)
STRIP_POWER_W = 0.6
EXPOSURE = -4.0

FIGURE = Figure(
    key="fig06_cd", label="Fig. 6 (top right)", title="Compact disc",
    paper="A CD rendered with the scratch model: the tracks act as a diffraction grating and split a light "
          "into rainbow-coloured grating orders that fan out from its reflection. 3 128 400 scratches, "
          "the most the paper renders, and its slowest scene (1029 min).",
    scratches="21 875 concentric tracks × 143 chords = 3 128 125 segments (paper: 3 128 400), "
              "D = 120 nm, W = 1 µm, rectangular, pitch 1.6 µm, radii 23–58 mm; coherence diameter 30 µm "
              "(≈ 19 tracks per coherence area)",
    design="The disc lies on a dark cloth, seen from 21 cm at 45° with a 35 mm lens; a small strip light "
           "(3 × 0.6 cm) hangs 15 cm from the disc on the far side, both close enough that directions change a "
           "lot across the disc. The light's reflection (order 0) falls on the hub; everywhere the half vector's "
           "tangential part h points nearly radially, so the grating equation h·n = mλ/P (P = 1.6 µm) selects a "
           "wavelength by distance from the centre: over the far half h·n runs from 0.2 to 0.5 and the first "
           "order draws rainbow rings from violet (inside) to red (outside), the second order starting at the "
           "rim and on the near side. The strip is narrow in the radial direction, so the colours stay pure. "
           "Incoherently the tracks add intensities: no orders, only one track's broad envelope, a pale haze "
           "over the same region.",
    renders=(
        Render("coherent", "coherent (the model): the tracks interfere, rainbow grating orders",
               {"coherent": True}, resolution=(720, 540), samples=128, paper_minutes=1029),
        Render("incoherent", "incoherent: the same disc adding intensities, the orders vanish",
               {"coherent": False}, resolution=(720, 540), samples=128, paper_minutes=1029),
    ),
)


def cd_tracks(radii_m=TRACKS_M, pitch_m: float = PITCH_M, chords: int = CHORDS_PER_TRACK):
    """The CD's tracks as a ScratchSet in the disc's UV map (closed polygons around (0.5, 0.5))."""
    from ..mitsuba_bridge.scratch import ScratchSet

    count = int(round((radii_m[1] - radii_m[0]) / pitch_m))
    radii = (radii_m[0] + pitch_m * np.arange(count)) / (2 * DISC_RADIUS_M)  # UV units
    angle = np.linspace(0.0, 2.0 * np.pi, chords + 1)
    angle[-1] = 0.0  # close each track exactly
    uv = np.empty((count, chords + 1, 2))
    uv[..., 0] = 0.5 + radii[:, None] * np.cos(angle)[None, :]
    uv[..., 1] = 0.5 + radii[:, None] * np.sin(angle)[None, :]
    return ScratchSet(
        uv=uv.reshape(-1, 2), offsets=np.arange(count + 1, dtype=np.int64) * (chords + 1),
        width=np.full(count, WIDTH_M), depth=np.full(count, DEPTH_M), profile=np.zeros(count, np.uint8),
        width_variation=np.zeros((count, 2)), depth_variation=np.zeros((count, 2)),
        seed=np.arange(count, dtype=np.uint32))


def build_scene(scene, *, coherent: bool = True, resolution=(720, 540), samples: int = 64,
                track_radii_m=TRACKS_M, workdir: str | Path | None = None):
    """The CD on a dark cloth under a strip light; returns the disc.

    ``track_radii_m`` narrows the program area (tests); ``workdir`` is where the
    track file is written before it is imported (a temporary folder by default).
    """
    from . import staging

    metal = staging.material("CD aluminium", (0.91, 0.92, 0.92), roughness=0.05, metallic=1.0)
    cd = staging.disc("CD", DISC_RADIUS_M, (0.0, 0.0, 0.0012), metal, hole=METAL_INNER_M)
    cd.scratch_iridescence.base_material = "Al"
    cd.scratch_iridescence.coherent = coherent
    staging.import_scratches(cd, cd_tracks(track_radii_m), "cd_tracks.npz", workdir)
    staging.cd_surroundings(METAL_INNER_M, HOLE_RADIUS_M, 0.0012)

    staging.area_light(scene, "Strip light", (0.0, 0.10, 0.12), (0.0, 0.0, 0.0), power_w=STRIP_POWER_W,
                       size=STRIP_SIZE_M)
    staging.constant_world(scene, (0.08, 0.08, 0.08))
    staging.camera(scene, (0.0, -0.15, 0.15), (0.0, 0.004, 0.0), lens_mm=35.0)
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return cd
