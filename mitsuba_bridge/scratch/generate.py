"""Random scratch sets drawn directly in UV space (flat parts, tests, benchmarks).

The Blender editor scatters scratches over a mesh's *surface*; this module is
its Blender-free counterpart for a flat, undistorted UV square such as a plate,
and is what the benchmarks and the BSDF tests use.  Everything is vectorised:
300 000 scratches of 8 vertices take well under a second.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import ParameterError
from .distributions import Constant, Distribution, Gaussian, Uniform
from .scratchset import (MAX_SCRATCH_SIZE_M, MAX_VARIATION_AMPLITUDE, MAX_VARIATION_FREQUENCY, Profile,
                         ScratchSet)

__all__ = ["random_scratches", "sample_parameters", "check_looks", "estimate_generate_bytes", "MAX_SCRATCH_SIZE_M",
           "MAX_VARIATION_AMPLITUDE", "MAX_VARIATION_FREQUENCY"]

#: The format's bounds (:mod:`.scratchset`), which the generators also check before drawing anything: a
#: distribution's upper bound (a Gaussian's mean + 3 std) must stay within MAX_SCRATCH_SIZE_M.
#: Peak memory of :func:`random_scratches` and saving the set, per scratch and per vertex (bytes, with margin):
#: ``tracemalloc`` measured 317 B per scratch at 8 vertices, 191 at 2 and 1 065 at 32 (100 000 and 50 000
#: scratches, generated and saved, numpy 2).
_BYTES_PER_SCRATCH, _BYTES_PER_VERTEX = 200, 40


def estimate_generate_bytes(count: int, vertices: int) -> int:
    """Peak memory (bytes) of generating ``count`` scratches of ``vertices`` vertices and saving them."""
    return int(count) * (_BYTES_PER_SCRATCH + _BYTES_PER_VERTEX * int(vertices))


def _largest(distribution: Distribution) -> float:
    """The largest value a width or depth distribution practically draws (metres)."""
    if isinstance(distribution, Uniform):
        return float(distribution.upper)
    if isinstance(distribution, Gaussian):
        return float(distribution.mean + 3.0 * distribution.std)
    if isinstance(distribution, Constant):
        return float(distribution.value)
    raise TypeError(f"not a distribution: {distribution!r}")


def check_looks(*, width: Distribution, depth: Distribution, width_variation=(0.0, 0.0),
                depth_variation=(0.0, 0.0)) -> None:
    """Refuse parameters no scratch can have, before anything is drawn.

    Raises ``ValueError`` naming the parameter: a width or depth distribution
    reaching beyond :data:`MAX_SCRATCH_SIZE_M`, or a variation whose amplitude
    or frequency is not a number in [0, :data:`MAX_VARIATION_AMPLITUDE`] or
    [0, :data:`MAX_VARIATION_FREQUENCY`].  (The distributions themselves refuse
    NaN, infinities and the absence of positive values.)
    """
    for name, distribution in (("width", width), ("depth", depth)):
        largest = _largest(distribution)
        if not largest <= MAX_SCRATCH_SIZE_M:
            raise ParameterError(f"{name} {distribution} (metres) reaches {largest:.3g} m, beyond "
                             f"{MAX_SCRATCH_SIZE_M:g} m: scratches are microscopic (micrometres wide, "
                             "nanometres deep)")
    for name, variation in (("width variation", width_variation), ("depth variation", depth_variation)):
        values = np.asarray(variation, dtype=np.float64)
        if values.shape != (2,):
            raise ParameterError(f"{name}: expected (amplitude, frequency), got {variation!r}")
        amplitude, frequency = float(values[0]), float(values[1])
        if not 0.0 <= amplitude <= MAX_VARIATION_AMPLITUDE:
            raise ParameterError(f"{name}: amplitude {amplitude:g} must lie in [0, {MAX_VARIATION_AMPLITUDE:g}]")
        if not 0.0 <= frequency <= MAX_VARIATION_FREQUENCY:
            raise ParameterError(f"{name}: frequency {frequency:g} must lie in [0, {MAX_VARIATION_FREQUENCY:g}] "
                             "(1 is 255 oscillations along a scratch)")


def sample_parameters(rng: np.random.Generator, count: int, *, width: Distribution,
                      depth: Distribution, profile=Profile.RECTANGULAR,
                      width_variation=(0.0, 0.0), depth_variation=(0.0, 0.0)) -> dict:
    """Per-scratch parameter arrays for ``count`` scratches (the non-geometric fields).

    Width and depth are drawn from their distributions (metres); the variation
    tuples (amplitude, frequency) and the profile apply to every scratch; seeds
    are drawn uniformly from the uint32 range.  Impossible parameters raise
    ``ValueError`` before anything is drawn (:func:`check_looks`).  A draw in a
    Gaussian's tail beyond the format's :data:`MAX_SCRATCH_SIZE_M` is clipped to it.
    """
    check_looks(width=width, depth=depth, width_variation=width_variation, depth_variation=depth_variation)
    return dict(
        width=np.minimum(width.sample(rng, count), MAX_SCRATCH_SIZE_M),
        depth=np.minimum(depth.sample(rng, count), MAX_SCRATCH_SIZE_M),
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
    _check_request(count, length, vertices, angle, angle_spread, curvature, region)
    check_looks(width=width, depth=depth, width_variation=width_variation, depth_variation=depth_variation)
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


def _check_request(count, length, vertices, angle, angle_spread, curvature, region) -> None:
    """``ValueError`` naming the first impossible argument of :func:`random_scratches`."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise ParameterError(f"count must be a whole number >= 0; got {count!r}")
    if isinstance(vertices, bool) or not isinstance(vertices, (int, np.integer)) or vertices < 2:
        raise ParameterError(f"a scratch needs at least 2 vertices; got {vertices!r}")
    low, high = (float(x) for x in length)
    if not (math.isfinite(high) and 0.0 < low <= high):
        raise ParameterError(f"lengths must satisfy 0 < min <= max and be finite (UV units); got {low:g}, {high:g}")
    if angle is not None and not math.isfinite(angle):
        raise ParameterError(f"angle must be finite (radians); got {angle:g}")
    if not (math.isfinite(angle_spread) and angle_spread >= 0.0):
        raise ParameterError(f"angle spread must be finite and >= 0 (radians); got {angle_spread:g}")
    if not (math.isfinite(curvature) and curvature >= 0.0):
        raise ParameterError(f"curvature must be finite and >= 0 (1 / UV units); got {curvature:g}")
    corners = np.asarray(region, dtype=np.float64)
    if corners.shape != (2, 2) or not np.all(np.isfinite(corners)) or np.any(corners[1] < corners[0]):
        raise ParameterError(f"region must be ((u_min, v_min), (u_max, v_max)) with finite bounds; got {region!r}")
