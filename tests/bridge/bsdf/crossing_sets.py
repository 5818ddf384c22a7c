"""Random crossing sets and their brute-force height-field planes, for tests/bridge/bsdf/heightfield/test_crossings.py.

Whole planes of spatial frequency ξ at one incidence: the true height field
(the deepest scratch owns a crossing) and the model's sum of transfer functions,
both from one global raster (``reference.raster_footprints`` and
``reference.windowed_dft``), and the plugin's ``eval`` at the same directions.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from scratch_iridescence.mitsuba_bridge.validation import probe
from scratch_iridescence.mitsuba_bridge.validation import reference as ref

VISIBLE = 0.98


def random_set(count, seed, spread_um, width_um, depth_um=(0.1, 0.5), length_um=200.0):
    """``count`` long rectangular scratches (ends far outside the window) through points within
    ±``spread_um`` of x0, random directions, W ∈ U[width_um], D ∈ U[depth_um]."""
    rng = np.random.default_rng(seed)
    scratches = []
    for _ in range(count):
        centre = rng.uniform(-spread_um, spread_um, 2)
        angle = rng.uniform(0, np.pi)
        d = 0.5 * length_um * np.array([np.cos(angle), np.sin(angle)])
        scratches.append(ref.Scratch(tuple(centre - d), tuple(centre + d), rng.uniform(*width_um),
                                     rng.uniform(*depth_um)))
    return scratches


def with_v_grooves(scratches, share, seed):
    """The same scratches, each a V-groove with probability ``share``."""
    rng = np.random.default_rng(seed)
    return [dataclasses.replace(s, profile=ref.TRI if rng.uniform() < share else ref.RECT) for s in scratches]


def overlap_shares(x, footprints, sigma):
    """Window-weighted shares of the scratched area where two or more, and three or more, scratches overlap."""
    n = len(x)
    weight = np.exp(-0.5 * (x / sigma) ** 2)
    unique, counts = np.unique(np.concatenate(footprints), return_counts=True)
    rows, cols = np.divmod(unique, n)
    w = weight[rows] * weight[cols]
    return float(np.sum(w[counts > 1]) / np.sum(w)), float(np.sum(w[counts > 2]) / np.sum(w))


class Raster:
    """One height-field raster of ``scratches`` over ±5σ."""

    def __init__(self, scratches, sigma, pitch_um):
        self.scratches, self.sigma = scratches, sigma
        self.x, self.footprints, self.deepest = ref.raster_footprints(scratches, pitch_um, 5 * sigma)
        self.share, self.triple_share = overlap_shares(self.x, self.footprints, sigma)

    def pair_overlaps(self):
        """``[(i, j, pixels)]`` of every overlapping pair of footprints."""
        if not hasattr(self, "_pairs"):
            self._pairs = []
            for i in range(len(self.scratches)):
                for j in range(i + 1, len(self.scratches)):
                    common = np.intersect1d(self.footprints[i], self.footprints[j], assume_unique=True)
                    if len(common):
                        self._pairs.append((i, j, common))
        return self._pairs

    def planes(self, wavelength_nm, theta_deg, samples, phi_deg=20.0, pairwise=False):
        """``(ω_i, wo rows, true f_r, summed f_r)`` over the visible, off-lobe part of a ξ grid, and with
        ``pairwise`` the f_r of the pairwise inclusion–exclusion (every overlap of two scratches
        given the shallower one's correction, triple overlaps not) of the same raster."""
        lam = wavelength_nm * 1e-3
        t, p = np.radians(theta_deg), np.radians(phi_deg)
        wi = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
        axis = np.linspace(-1.0, 1.0, samples) / lam
        xi_x, xi_y = axis + wi[0] / lam, axis + wi[1] / lam  # the visible disc: |λξ - ω_i,t| < 1
        gx, gy = np.meshgrid(xi_x, xi_y, indexing="xy")
        wo_x, wo_y = lam * gx - wi[0], lam * gy - wi[1]
        sin2 = wo_x ** 2 + wo_y ** 2
        lobe = 1.0 / (2 * np.sqrt(2) * np.pi * self.sigma)
        keep = (sin2 < VISIBLE) & (np.hypot(gx, gy) > 4 * lobe)
        wo_z = np.sqrt(np.clip(1 - sin2, 0, None))
        k_z = 2 * np.pi * (wi[2] + wo_z) / lam
        true = summed = ref.mirror_field(xi_x, xi_y, self.sigma).astype(complex)
        for s, own, covered in zip(self.scratches, self.deepest, self.footprints):
            transfer = np.exp(1j * k_z * s.depth) - 1.0
            true = true + transfer * ref.windowed_dft(own, self.x, self.sigma, xi_x, xi_y)
            summed = summed + transfer * ref.windowed_dft(covered, self.x, self.sigma, xi_x, xi_y)
        rows = np.column_stack([wo_x[keep], wo_y[keep], wo_z[keep]])
        result = (wi, rows, ref.brdf(true[keep], lam, self.sigma), ref.brdf(summed[keep], lam, self.sigma))
        if pairwise:
            field = summed
            for i, j, common in self.pair_overlaps():
                shallow = min(self.scratches[i].depth, self.scratches[j].depth)
                field = field - (np.exp(1j * k_z * shallow) - 1.0) * ref.windowed_dft(common, self.x, self.sigma,
                                                                                     xi_x, xi_y)
            result += (ref.brdf(field[keep], lam, self.sigma),)
        return result


def sloped_plane(scratches, sigma, wavelength_nm, theta_deg, samples, pitch_um, phi_deg=20.0):
    """``(ω_i, wo rows, true f_r)`` as :meth:`Raster.planes`, for any profiles: the height field (the
    deepest profile per point) summed directly per direction (``reference.field_global_raster``), so
    V-grooves crossing anything are exact to the raster's pitch; slower, hence coarser planes."""
    lam = wavelength_nm * 1e-3
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    wi = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
    axis = np.linspace(-1.0, 1.0, samples) / lam
    gx, gy = np.meshgrid(axis + wi[0] / lam, axis + wi[1] / lam, indexing="xy")
    xi = np.column_stack([gx.ravel(), gy.ravel()])
    wo, visible = ref.directions(xi, lam, wi)
    keep = visible & (np.hypot(xi[:, 0], xi[:, 1]) > 4.0 / (2 * np.sqrt(2) * np.pi * sigma))  # off the lobe
    xi, wo = xi[keep], wo[keep]
    field = ref.field_global_raster(scratches, xi, ref.kz_of(wo, wi, lam), sigma, pitch=pitch_um)
    return wi, wo, ref.brdf(field, lam, sigma)


def plugin_brdf(bsdf, wi, rows, wavelength_nm):
    return probe.eval_brdf(bsdf, wi, rows, (wavelength_nm, 550.0, 550.0, 550.0))[:, 0]


def relative_l2(got, expected):
    return float(np.sqrt(np.sum((got - expected) ** 2) / np.sum(expected ** 2)))
