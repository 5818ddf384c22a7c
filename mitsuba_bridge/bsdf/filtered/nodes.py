"""Gauss–Hermite nodes for footprint averages of localised point values (docs/model.md §11.2).

A point value that falls off like ``e^{-(τ - c)²/ε²}`` around ``c`` (a groove seen by windows
across it, a short segment seen by windows along it) is averaged over a footprint ``τ ~ N(μ, v)``
by Gauss–Hermite nodes of the **product** of the footprint and that envelope, a Gaussian of
variance ``v ε²/(ε² + 2v) <= ε²/2``: the nodes stay where the value lives whatever the footprint,
from the point value itself (``v = 0``: every node at μ, weights summing to 1) to a footprint
much wider than the window (``v → ∞``: nodes spread over ``ε/√2`` around ``c``).
"""
from __future__ import annotations

import drjit as dr
import numpy as np

__all__ = ["hermite_rule", "envelope_nodes", "footprint_nodes"]


def hermite_rule(count: int):
    """Probabilists' Gauss–Hermite nodes and weights (summing to 1) as Python floats."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(count)
    return [float(z) for z in nodes], [float(w) for w in weights / weights.sum()]


def envelope_nodes(centre, mean, variance, envelope2, count: int):
    """``[(position, weight)]`` with ``E_{τ~N(mean, variance)} f(τ) ≈ Σ weight f(position)``.

    ``f`` is assumed to fall off like ``e^{-(τ - centre)²/envelope2}``; each weight already holds
    the footprint's overlap with that envelope and the envelope's inverse at the node.  All
    arguments are Dr.Jit arrays (or floats) of one shape; ``variance = 0`` gives one point value.
    """
    spread = envelope2 + 2.0 * variance
    inv_spread = dr.rcp(spread)
    node_mean = (envelope2 * mean + 2.0 * variance * centre) * inv_spread
    node_std = dr.sqrt(variance * envelope2 * inv_spread)
    scale = dr.sqrt(envelope2 * inv_spread)
    offset2 = dr.square(centre - mean) * inv_spread
    inv_envelope2 = dr.rcp(envelope2)
    result = []
    for z, w in zip(*hermite_rule(count)):
        position = dr.fma(node_std, z, node_mean)
        weight = (w * scale) * dr.exp(dr.square(position - centre) * inv_envelope2 - offset2)
        result.append((position, weight))
    return result


def footprint_nodes(mean, variance, count: int):
    """``[(position, weight)]`` of plain Gauss–Hermite over the footprint ``N(mean, variance)``."""
    spread = dr.sqrt(variance)
    return [(dr.fma(spread, z, mean), w) for z, w in zip(*hermite_rule(count))]
