"""The point model's window integral, cross sections and segment amplitude in numpy (float64, scipy's
Faddeeva function): the reference the footprint filter's kernels are averaged against."""
from __future__ import annotations

import numpy as np
from scipy.special import wofz

_SQRT2 = np.sqrt(2.0)


def _end_term(t, nu, sigma):
    s = np.where(t >= 0, -1.0, 1.0)
    z = (s * 2 * np.pi * nu * sigma ** 2 + 1j * np.abs(t)) / (_SQRT2 * sigma)
    return s * np.exp(-0.5 * (t / sigma) ** 2) * np.exp(-2j * np.pi * nu * t) * wofz(z)


def window_integral(t0, t1, nu, sigma):
    """``∫_{t0}^{t1} e^{-t²/2σ²} e^{-2πiνt} dt`` (docs/model.md §3.2), broadcasting."""
    t0, t1 = np.clip(t0, -8 * sigma, 8 * sigma), np.clip(t1, -8 * sigma, 8 * sigma)
    line = 2 * np.exp(-2 * np.pi ** 2 * sigma ** 2 * nu ** 2) * ((t1 >= 0) * 1.0 - (t0 >= 0) * 1.0)
    return np.sqrt(np.pi / 2) * sigma * (_end_term(t1, nu, sigma) - _end_term(t0, nu, sigma) + line)


def cross_section(nu, a, width, kappa, sigma, v_groove=False, coherent=True):
    """``A(ν; a⊥)`` of a flat-bottomed or V groove (docs/model.md §3.1)."""
    box = 1.0 if coherent else 0.0
    if not v_groove:
        return (np.exp(1j * kappa) - box) * window_integral(a - width / 2, a + width / 2, nu, sigma)
    s = kappa / (np.pi * width)
    tau = 2 * np.pi * s * a
    facets = np.exp(1j * kappa) * (np.exp(-1j * tau) * window_integral(a - width / 2, a, nu - s, sigma)
                                   + np.exp(1j * tau) * window_integral(a, a + width / 2, nu + s, sigma))
    return facets - box * window_integral(a - width / 2, a + width / 2, nu, sigma)


def mirror_lobe(xi2, sigma):
    return 2 * np.pi * sigma ** 2 * np.exp(-2 * np.pi ** 2 * sigma ** 2 * xi2)


class Segment:
    """A straight groove from ``start`` to ``end`` (µm, relative to the footprint's centre)."""

    def __init__(self, start, end, width, depth, v_groove=False):
        self.start, self.end = np.asarray(start, float), np.asarray(end, float)
        self.width, self.depth, self.v_groove = width, depth, v_groove
        e = self.end - self.start
        self.length = float(np.hypot(*e))
        self.d = e / self.length
        self.n = np.array([-self.d[1], self.d[0]])

    def amplitude(self, x0, xi, k_z, sigma, coherent=True):
        """``S(ξ; x0)`` for points ``x0`` (M, 2) and frequencies ``xi`` (K, 2): (M, K) complex."""
        a = self.start[None, :] - np.atleast_2d(x0)
        c, a_perp = (a @ self.d)[:, None], (a @ self.n)[:, None]
        along = window_integral(c, c + self.length, (xi @ self.d)[None, :], sigma)
        return along * cross_section((xi @ self.n)[None, :], a_perp, self.width, k_z * self.depth, sigma,
                                     self.v_groove, coherent)
