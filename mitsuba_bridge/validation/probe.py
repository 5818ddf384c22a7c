"""One shading point on a flat test surface: evaluate the BSDF for scratches given in micrometres.

Used by the BSDF tests and the numerical validation (:mod:`..validation`);
needs an active spectral variant.  The test surface is flat with ``dp/du =
x``, ``dp/dv = y`` and ``unit_scale = UNIT_SCALE`` (1 UV unit = 1 mm), the
shading point at UV (0.5, 0.5): a scratch given in micrometres around the
shading point (a :class:`.reference.Scratch`) lands at ``uv = 0.5 + x_µm / 1000``.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..scratch import Profile, ScratchSet
from ..bsdf import plugin_dict

__all__ = ["UNIT_SCALE", "X0_UV", "to_uv", "scratch_set", "load_bsdf", "floats", "interaction", "vector",
           "spectrum_rows", "eval_brdf"]

UNIT_SCALE = 1e-3
X0_UV = (0.5, 0.5)


def to_uv(points_um, jacobian=None):
    """UV of points given in µm around x0 on the test surface (``jacobian``: dp/du, dp/dv columns)."""
    points = np.asarray(points_um, dtype=np.float64) * (1e-6 / UNIT_SCALE)
    if jacobian is not None:
        points = np.linalg.solve(np.asarray(jacobian, dtype=np.float64), points.T).T
    return np.asarray(X0_UV) + points


def scratch_set(scratches, jacobian=None) -> ScratchSet:
    """ScratchSet of reference.Scratch objects (µm around x0)."""
    return ScratchSet.from_polylines(
        [to_uv([s.a, s.b], jacobian) for s in scratches],
        width=[s.width * 1e-6 for s in scratches], depth=[s.depth * 1e-6 for s in scratches],
        profile=[Profile.TRIANGULAR if s.profile == 1 else Profile.RECTANGULAR for s in scratches])


def load_bsdf(scratches=None, *, sigma_um=2.0, material="none", unit_scale=UNIT_SCALE, **kwargs):
    """A scratch_diffraction BSDF for the test surface (scratches in µm around x0, or a ScratchSet)."""
    if scratches is not None and not isinstance(scratches, ScratchSet):
        scratches = scratch_set(scratches)
    return mi.load_dict(plugin_dict(
        scratches, coherence_diameter=6 * sigma_um * 1e-6, unit_scale=unit_scale, material=material,
        **kwargs))


def floats(values) -> mi.Float:
    """A Dr.Jit-owned (so always equally aligned) copy of ``values``.

    Arrays built straight from numpy may alias numpy's memory, whose alignment
    changes the generated code: a kernel-cache test would see spurious misses.
    """
    array = mi.Float(np.ascontiguousarray(values, dtype=np.float32).ravel()) + dr.opaque(mi.Float, 0.0)
    dr.eval(array)
    return array


def interaction(count, wi, wavelengths_nm=(550, 600, 450, 650), uv=X0_UV):
    """A SurfaceInteraction3f of ``count`` lanes on the test surface."""
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.uv = mi.Point2f(*(floats(np.broadcast_to(np.asarray(c, np.float32), count)) for c in uv))
    si.dp_du = mi.Vector3f(1, 0, 0)
    si.dp_dv = mi.Vector3f(0, 1, 0)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
    si.wi = vector(np.broadcast_to(np.asarray(wi, np.float64), (count, 3)))
    wl = np.broadcast_to(np.asarray(wavelengths_nm, np.float64), (count, 4))
    si.wavelengths = mi.Spectrum(*(floats(wl[:, i]) for i in range(4)))
    return si


def vector(rows):
    rows = np.asarray(rows, dtype=np.float64)
    return mi.Vector3f(*(floats(rows[:, i]) for i in range(3)))


def spectrum_rows(value) -> np.ndarray:
    """(count, 4) numpy array of a Spectrum."""
    return np.asarray(value).T.reshape(-1, 4) if np.asarray(value).ndim == 2 else np.asarray(value)


def eval_brdf(bsdf, wi, wo_rows, wavelengths_nm=(550, 600, 450, 650)):
    """f_r (not times cos θ_o) for every row of ``wo_rows``; (count, 4) per wavelength."""
    wo_rows = np.asarray(wo_rows, dtype=np.float64)
    si = interaction(len(wo_rows), wi, wavelengths_nm)
    value = bsdf.eval(mi.BSDFContext(), si, vector(wo_rows))
    return spectrum_rows(value) / wo_rows[:, 2:3]

