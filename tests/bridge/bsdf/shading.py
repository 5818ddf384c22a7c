"""Hand-built shading points and scratch sets for the BSDF tests (needs an active variant).

The shared part lives in :mod:`scratch_iridescence.mitsuba_bridge.bsdf.probe` (the numerical
validation uses it too); this adds what only tests need.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

# Re-exported: the tests call them as shading.<name>.
from scratch_iridescence.mitsuba_bridge.validation.probe import (  # noqa: F401
    UNIT_SCALE, X0_UV, eval_brdf, floats, interaction, load_bsdf, scratch_set, spectrum_rows, to_uv, vector)


def direction(theta_deg, phi_deg=0.0):
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])


def direction_pairs(rng, count):
    """``(wi, wo)``: ``count`` random pairs of directions, cos θ uniform in [0.05, 1] (reciprocity tests)."""
    theta = np.degrees(np.arccos(rng.uniform(0.05, 1.0, (2, count))))
    phi = rng.uniform(0, 360, (2, count))
    wi = np.array([direction(t, p) for t, p in zip(theta[0], phi[0])])
    wo = np.array([direction(t, p) for t, p in zip(theta[1], phi[1])])
    return wi, wo


def uniform_interaction(count, wi, wavelengths_nm=(550, 600, 450, 650), uv=X0_UV):
    """Like :func:`interaction`, built from scalars only (any width, e.g. inside a chi² adapter)."""
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.uv = mi.Point2f(float(uv[0]), float(uv[1]))
    si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
    si.wi = mi.Vector3f(*map(float, wi))
    si.wavelengths = mi.Spectrum(*map(float, wavelengths_nm))
    return si
