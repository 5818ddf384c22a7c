"""Random scratch sets drawn directly in UV space (flat parts, tests, benchmarks).

The Blender editor scatters scratches over a mesh's *surface*; this module is
its Blender-free counterpart for a flat, undistorted UV square such as a plate,
and is what the benchmarks and the BSDF tests use.  Everything is vectorised:
300 000 scratches of 8 vertices take well under a second.
"""
from __future__ import annotations

import numpy as np

from .distributions import Constant, Distribution
from .scratchset import Profile, ScratchSet

__all__ = ["random_scratches", "sample_parameters"]


def sample_parameters(rng: np.random.Generator, count: int, *, width: Distribution,
                      depth: Distribution, profile=Profile.RECTANGULAR,
                      width_variation=(0.0, 0.0), depth_variation=(0.0, 0.0)) -> dict:
    """Per-scratch parameter arrays for ``count`` scratches (the non-geometric fields).

    Width and depth are drawn from their distributions (metres); the variation
    tuples (amplitude, frequency) and the profile apply to every scratch; seeds
    are drawn uniformly from the uint32 range.
    """
    return dict(
        width=width.sample(rng, count),
        depth=depth.sample(rng, count),
        profile=np.full(count, int(profile), dtype=np.uint8),
        width_variation=np.tile(np.asarray(width_variation, dtype=np.float64), (count, 1)),
        depth_variation=np.tile(np.asarray(depth_variation, dtype=np.float64), (count, 1)),
        seed=rng.integers(0, 2**32, count, dtype=np.uint32),
    )


def random_scratches(count: int, *, seed: int = 0, width: Distribution = Constant(1e-6),
                     depth: Distribution = Constant(250e-9), length=(0.2, 0.6), vertices: int = 2,
                     angle: float | None = None, angle_spread: float = 0.0, curvature: float = 0.0,
                     region=((0.0, 0.0), (1.0, 1.0)), profile=Profile.RECTANGULAR,
                     width_variation=(0.0, 0.0), depth_variation=(0.0, 0.0)) -> ScratchSet:
    """``count`` random scratches in a UV rectangle.

    Parameters
    ----------
    seed:
        Seed of the ``numpy.random.Generator``; the same seed gives the same set.
    width, depth:
        Distributions in metres.
    length:
        (min, max) of the uniform scratch length, in UV units.
    vertices:
        Vertices per scratch (>= 2; more than 2 only matters with ``curvature``
        or for tests of polylines).
    angle, angle_spread:
        Direction in radians from the U axis; ``None`` draws it uniformly.  With
        an angle, directions are uniform in ``angle ± angle_spread``.
    curvature:
        Largest curvature (1 / UV units) of the arcs; 0 draws straight scratches.
    region:
        ((u_min, v_min), (u_max, v_max)).  Scratches are moved to lie inside it
        where their size allows.
    """
    if vertices < 2:
        raise ValueError("a scratch needs at least 2 vertices")
    rng = np.random.default_rng(seed)
    (u0, v0), (u1, v1) = np.asarray(region, dtype=np.float64)

    centre = rng.uniform((u0, v0), (u1, v1), (count, 2))
    scratch_length = rng.uniform(length[0], length[1], count)
    if angle is None:
        theta = rng.uniform(0.0, 2.0 * np.pi, count)
    else:
        theta = angle + rng.uniform(-angle_spread, angle_spread, count)
    kappa = rng.uniform(-curvature, curvature, count) if curvature > 0 else np.zeros(count)

    # Arc of curvature kappa through the centre, sampled at equal arc length:
    # integral of (cos, sin)(theta + kappa s) ds = s * (cos, sin)(theta + kappa s / 2) * sinc(kappa s / 2).
    # Computed in place: at 300 000 x 8 vertices every temporary costs 19 MB.
    chord = np.linspace(-0.5, 0.5, vertices)[None, :] * scratch_length[:, None]  # arc length s, (S, V)
    heading = np.multiply(0.5 * kappa[:, None], chord)  # kappa s / 2
    if curvature > 0:
        chord *= np.sinc(heading / np.pi)
    heading += theta[:, None]
    uv = np.empty((count, vertices, 2))
    for axis, trig in ((0, np.cos), (1, np.sin)):
        trig(heading, out=uv[..., axis])
        uv[..., axis] *= chord
        uv[..., axis] += centre[:, axis, None]
    del chord, heading

    # Shift scratches that stick out of the region back inside (where they fit).
    low, high = uv.min(axis=1), uv.max(axis=1)
    shift = np.maximum((u0, v0) - low, 0.0) + np.minimum((u1, v1) - high, 0.0)
    uv += shift[:, None, :]

    offsets = np.arange(count + 1, dtype=np.int64) * vertices
    params = sample_parameters(rng, count, width=width, depth=depth, profile=profile,
                               width_variation=width_variation, depth_variation=depth_variation)
    return ScratchSet(uv=uv.reshape(-1, 2), offsets=offsets, **params)
