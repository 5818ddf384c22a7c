"""Fig. 8 (b, d): a CD whose every coherence area holds the same periodic ensemble of Stam's tracks.

The supplement's "BRDF*": an ensemble of parallel scratches inside one
circular coherence area, with Stam's depth, width and track separation, the
same at every point of the disc; only view and light change.  It counts
n = 2·3σ/(Δ_track + W_scratch) + 1 ≈ 21 scratches in the area (σ = δ_c/6).

Here the ensemble is tiled by its own period across the disc: the disc's UV
map is polar (u = angle / 2π, v = radial fraction, :func:`.shapes.annulus_grid`),
and every track is one straight line of constant v, a whole circle on the
disc.  A coherence window anywhere on the disc then sees the same run of
parallel tracks at the same spacing along its own tangent, up to a shift
across them, which only changes a phase: Stam's ensemble, everywhere,
without the polygonal chords of Fig. 6's CD.  The scratch BSDF sums such runs
in closed form (periodic families, docs/model.md §3.5).

Parameters: W = 1 µm and D = 120 nm (the supplement's CD, after Stam), and the
separation that the supplement's own count fixes: with δ_c = 30 µm (σ = 5 µm)
n = 21 needs Δ_track + W = 2·3σ/(n − 1) = 1.5 µm, a pitch of 1.5 µm (a CD's
standard 1.6 µm would give n = 19.75).  We do not have Stam's paper to check
his numbers against.

The tracks are written as a scratch file (format v1) and put on the disc with
the add-on's **Import Scratches** operator, as for Fig. 6.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .figure import Figure, Render

__all__ = ["FIGURE", "build_scene", "ensemble_tracks", "tracks_per_coherence_area", "PITCH_M", "WIDTH_M",
           "DEPTH_M", "COHERENCE_DIAMETER_M"]

DISC_RADIUS_M = 0.060
HOLE_RADIUS_M = 0.0075
METAL_INNER_M = 0.022        # the aluminium layer: the polar annulus from here to the rim
TRACKS_M = (0.023, 0.058)    # program area
COHERENCE_DIAMETER_M = 30e-6
WIDTH_M, DEPTH_M = 1e-6, 120e-9
#: Δ_track + W: the pitch the supplement's count n ≈ 21 fixes (module docstring).
PITCH_M = 1.5e-6
EXPOSURE = -4.0

FIGURE = Figure(
    key="fig08_cd", label="Fig. 8 (b, d)", title="CD from Stam's periodic ensemble",
    paper="Fig. 8 renders a CD with a BRDF built from one coherence area of Stam's periodic track ensemble "
          "(about 21 parallel scratches), the same at every point of the disc; (b) and (d) change only view "
          "and light. The grating orders draw rainbow bands across the disc.",
    scratches="23 333 circular tracks, one straight UV line each on the disc's polar UV map (one segment per "
              "track, cut by the BSDF into 64 pieces of 1/64 UV), W = 1 µm, D = 120 nm, rectangular, pitch "
              "1.5 µm, radii 23–58 mm: 21 tracks in every coherence area of δ_c = 30 µm",
    design="(b): the Fig. 6 set-up (the disc on a dark cloth seen from 21 cm at 45°, a small strip light hanging 15 "
           "cm beyond it) — the first order draws rainbow arcs from violet inside to red outside over the far half, "
           "where the half vector's tangential part runs radially across the tracks, then blue and violet again at "
           "the rim's two ends (the second order). On the near half the tangential parts towards the lamp and the "
           "camera nearly cancel: it stays dark up to a violet patch at the near rim, where |h·n| first reaches λ/P;"
           " the boundary between the halves is a sharp line across the disc through the hub. The picture is the "
           "Fig. 6 CD's (its 21 875 tracks at 1.6 µm give 19 per coherence area), as the ensemble's pitch is nearly "
           "the same. (d): looking straight down from 30 cm (60 mm lens) with a round lamp (5 cm) 7 cm beside the "
           "lens: its reflection lies on one side of the hub, white with an orange fringe; on the other side, along "
           "the line through the lamp's foot, the tangential half vector h ≈ (l − 2x)/H runs radially and h·n = mλ/P"
           " lights a spoke: the first order from yellow-green near the hub to red, then the second order's violet "
           "and blue towards the rim.",
    renders=(
        Render("b", "(b) the strip light beyond the disc: rainbow arcs of the first order", {"view": "strip"},
               resolution=(720, 540), samples=32, paper_minutes=200),
        Render("d", "(d) from above, a round lamp beside the lens: its reflection, and a rainbow spoke opposite",
               {"view": "above"}, resolution=(600, 600), samples=32, paper_minutes=204),
    ),
)


def tracks_per_coherence_area(pitch_m: float = PITCH_M, width_m: float = WIDTH_M,
                              coherence_diameter_m: float = COHERENCE_DIAMETER_M) -> float:
    """The supplement's count n = 2·3σ/(Δ_track + W) + 1, σ = δ_c/6, with Δ_track + W the pitch."""
    sigma = coherence_diameter_m / 6.0
    return 2.0 * 3.0 * sigma / pitch_m + 1.0


def ensemble_tracks(radii_m=TRACKS_M, pitch_m: float = PITCH_M):
    """The tracks as a ScratchSet on the polar UV map: one line u ∈ [0, 1] at constant v per track."""
    from ..mitsuba_bridge.scratch import ScratchSet

    count = int(round((radii_m[1] - radii_m[0]) / pitch_m))
    radius = radii_m[0] + pitch_m * np.arange(count)
    v = (radius - METAL_INNER_M) / (DISC_RADIUS_M - METAL_INNER_M)
    uv = np.empty((count, 2, 2))
    uv[:, 0, 0], uv[:, 1, 0] = 0.0, 1.0
    uv[:, :, 1] = v[:, None]
    return ScratchSet(
        uv=uv.reshape(-1, 2), offsets=np.arange(count + 1, dtype=np.int64) * 2,
        width=np.full(count, WIDTH_M), depth=np.full(count, DEPTH_M), profile=np.zeros(count, np.uint8),
        width_variation=np.zeros((count, 2)), depth_variation=np.zeros((count, 2)),
        seed=np.arange(count, dtype=np.uint32))


def build_scene(scene, *, view: str = "strip", resolution=(720, 540), samples: int = 128,
                track_radii_m=TRACKS_M, workdir: str | Path | None = None):
    """The CD on a dark cloth, lit and seen as ``view`` says ("strip": (b), "above": (d)); returns the disc.

    ``track_radii_m`` narrows the program area (tests); ``workdir`` is where the
    track file is written before it is imported (a temporary folder by default).
    """
    from . import shapes, staging

    metal = staging.material("CD aluminium", (0.91, 0.92, 0.92), roughness=0.05, metallic=1.0)
    cd = shapes.polar_annulus("CD", METAL_INNER_M, DISC_RADIUS_M, segments=720, rings=8, mat=metal,
                              location=(0.0, 0.0, 0.0012))
    cd.scratch_iridescence.base_material = "Al"
    cd.scratch_iridescence.coherence_diameter_um = COHERENCE_DIAMETER_M * 1e6
    staging.import_scratches(cd, ensemble_tracks(track_radii_m), "cd_ensemble.npz", workdir)
    staging.cd_surroundings(METAL_INNER_M, HOLE_RADIUS_M, 0.0012)
    staging.constant_world(scene, (0.08, 0.08, 0.08))
    if view == "strip":
        staging.area_light(scene, "Strip light", (0.0, 0.10, 0.12), (0.0, 0.0, 0.0), power_w=0.6,
                           size=(0.03, 0.006))
        staging.camera(scene, (0.0, -0.15, 0.15), (0.0, 0.004, 0.0), lens_mm=35.0)
    elif view == "above":
        staging.area_light(scene, "Round lamp", (0.07, 0.0, 0.30), (0.07, 0.0, 0.0), power_w=2.0, size=0.05,
                           shape="DISK")
        staging.camera(scene, (0.0, 0.0, 0.30), (0.0, 0.0, 0.0), lens_mm=60.0)
    else:
        raise ValueError(f"view must be 'strip' or 'above', not {view!r}")
    staging.render_settings(scene, resolution=resolution, samples=samples, max_depth=3, exposure=EXPOSURE)
    return cd
