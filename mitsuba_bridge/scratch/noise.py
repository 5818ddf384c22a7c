"""1-D simplex noise and the variation of width and depth along a scratch (docs/model.md §7).

The supplement varies width and depth with "a simplex-noise function with 255
gradients, such that a frequency of 1/255 corresponds to exactly one oscillation
along the scratch".  Here that is::

    n(x)  = C * sum_{i in {floor(x), floor(x) + 1}} (1 - (x - i)^2)^4 * g[i mod 255] * (x - i)
    D(t)  = D0 * max(0, 1 + A_D * n(255 * f_D * t + o_D))          t in [0, 1]

with a fixed table ``g`` of 255 gradients, ``C = 256/81`` and ``o`` a per-scratch
offset in [0, 255) derived from the scratch's seed.  In one dimension a unit
gradient vector is +1 or -1, so the table holds 255 fixed pseudo-random signs.
Then ``|n| <= 1``: a cell between gradients of opposite sign peaks at exactly ±1
in its centre, a cell between equal signs swings within ±0.52.  The amplitude
therefore means what it says: ``D[1.1, 0.04]`` (amplitude 110 %) pinches the
depth to zero in about a quarter of the cells.  One unit
of ``x`` is one lattice cell, so ``255 * f`` cells, i.e. oscillations, fit along
the scratch.  The noise is periodic with period 255.

These numpy functions are the single definition used by the editor preview and
by the renderer (which evaluates them once per segment when it loads a set).
"""
from __future__ import annotations

import numpy as np

__all__ = ["GRADIENT_COUNT", "GRADIENTS", "simplex_noise", "noise_offset",
           "variation_factor", "width_depth_at"]

GRADIENT_COUNT = 255
_NORMALISATION = 256.0 / 81.0  # 1 / max |n| with gradients of magnitude 1

# Salts that make the width and depth noise of one scratch independent.
_SALT_WIDTH = np.uint32(0x68E31DA4)
_SALT_DEPTH = np.uint32(0xB5297A4D)


def hash_uint32(x) -> np.ndarray:
    """A well-mixed 32-bit integer hash ("lowbias32", C. Wellons); vectorised."""
    x = np.asarray(x, dtype=np.uint32).copy()
    with np.errstate(over="ignore"):
        x ^= x >> np.uint32(16)
        x *= np.uint32(0x7FEB352D)
        x ^= x >> np.uint32(15)
        x *= np.uint32(0x846CA68B)
        x ^= x >> np.uint32(16)
    return x


def _gradient_table() -> np.ndarray:
    bits = hash_uint32(np.arange(GRADIENT_COUNT, dtype=np.uint32)) >> np.uint32(31)
    table = np.where(bits == 1, 1.0, -1.0)
    table.setflags(write=False)
    return table


#: The 255 unit gradients (signs), fixed forever: changing them changes every rendered scratch.
GRADIENTS = _gradient_table()


def simplex_noise(x) -> np.ndarray:
    """1-D simplex noise in [-1, 1], zero at integers, period 255."""
    x = np.asarray(x, dtype=np.float64)
    cell = np.floor(x)
    d0 = x - cell
    d1 = d0 - 1.0
    i0 = np.mod(cell, GRADIENT_COUNT).astype(np.int64)
    i1 = np.where(i0 == GRADIENT_COUNT - 1, 0, i0 + 1)
    falloff0 = (1.0 - d0 * d0) ** 4
    falloff1 = (1.0 - d1 * d1) ** 4
    return _NORMALISATION * (falloff0 * GRADIENTS[i0] * d0 + falloff1 * GRADIENTS[i1] * d1)


def noise_offset(seed, which: str) -> np.ndarray:
    """Per-scratch noise offset in [0, 255) for ``which`` = ``"width"`` or ``"depth"``."""
    salt = {"width": _SALT_WIDTH, "depth": _SALT_DEPTH}[which]
    hashed = hash_uint32(np.asarray(seed, dtype=np.uint32) ^ salt)
    return hashed.astype(np.float64) * (GRADIENT_COUNT / 2.0**32)


def variation_factor(t, amplitude, frequency, offset) -> np.ndarray:
    """``max(0, 1 + amplitude * n(255 * frequency * t + offset))``, broadcasting."""
    t = np.asarray(t, dtype=np.float64)
    noise = simplex_noise(GRADIENT_COUNT * np.asarray(frequency) * t + np.asarray(offset))
    return np.maximum(0.0, 1.0 + np.asarray(amplitude) * noise)


def width_depth_at(scratches, scratch_index, t) -> tuple[np.ndarray, np.ndarray]:
    """Width and depth in metres of scratches ``scratch_index`` at arc-length parameters ``t``.

    Parameters
    ----------
    scratches : ScratchSet
    scratch_index : int array
        Which scratch each query belongs to.
    t : float array, same shape
        Arc-length parameter in [0, 1] along that scratch (0 at its first vertex).
    """
    k = np.asarray(scratch_index, dtype=np.int64)
    t = np.asarray(t, dtype=np.float64)
    width = scratches.width[k] * _factor(t, scratches.width_variation, scratches.seed, k, "width")
    depth = scratches.depth[k] * _factor(t, scratches.depth_variation, scratches.seed, k, "depth")
    return width, depth


def _factor(t, variation, seed, k, which):
    """:func:`variation_factor` of scratches ``k`` at ``t``, the noise evaluated only where the amplitude is
    not 0: elsewhere the factor is 1 exactly (max(0, 1 + 0·n) with |n| ≤ 1), so the result is the same bit
    for bit, and a set without variation (the CD's 3 million chords) skips the noise."""
    factor = np.ones(np.broadcast_shapes(t.shape, k.shape))
    varying = np.broadcast_to(variation[k, 0] != 0, factor.shape)
    if varying.any():
        k, t = np.broadcast_to(k, factor.shape)[varying], np.broadcast_to(t, factor.shape)[varying]
        factor[varying] = variation_factor(t, variation[k, 0], variation[k, 1], noise_offset(seed[k], which))
    return factor
