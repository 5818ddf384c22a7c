"""Brute-force wave-field reference for the scratch BSDF (docs/model.md §8.1), numpy only (scipy for sparse sums).

Used by the BSDF tests (``tests/bridge/bsdf``) and by the numerical validation
(:mod:`mitsuba_bridge.validation`, the supplement's Fig. 15).

The windowed far field ``U(ξ) = Σ w(x) T(x) e^{-2πiξ·x} Δx²`` of an explicit,
rasterised height field, with ``T = exp(i k_z d(x))`` and the exact Gaussian
window (no factorisation, no complex error function, no complex frequency).
Lengths in µm, x0 = 0.

Three rasterisations of the same height field:

* :func:`field_scratch_frames` samples each scratch's footprint on a grid
  aligned with the scratch (pitch ~10 nm).  On that grid the window and the
  phase are products of a factor along and a factor across the scratch, so
  the 2-D sum is computed exactly as a product of two 1-D sums: fast enough
  for thousands of directions.  Valid for non-overlapping footprints, where
  ``T - 1 = Σ_k (T_k - 1)`` holds exactly.
* :func:`field_global_raster` rasterises the height field on one global grid
  (pixel centres, depth = deepest scratch at the pixel) and sums every scratch
  pixel directly: the literal brute force, used to check the first.
* :func:`raster_footprints` + :func:`windowed_dft`: the same global raster
  (rectangular profiles) summed for a whole grid of frequencies at once,
  separably through a sparse pixel mask; it tells the true height field
  (the deepest scratch at a crossing) from the model's sum of transfer
  functions.  This draws whole direction-cosine planes (the validation).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RECT, TRI = 0, 1


@dataclass(frozen=True)
class Scratch:
    """A straight scratch from ``a`` to ``b`` (µm, relative to x0)."""

    a: tuple[float, float]
    b: tuple[float, float]
    width: float
    depth: float
    profile: int = RECT

    def frame(self):
        a, b = np.asarray(self.a, float), np.asarray(self.b, float)
        length = np.hypot(*(b - a))
        d = (b - a) / length
        n = np.array([-d[1], d[0]])
        return a, length, d, n

    def profile_at(self, u):
        """Normalised depth at signed distance ``u`` from the centre line (0 outside)."""
        inside = np.abs(u) <= 0.5 * self.width
        shape = np.ones_like(u) if self.profile == RECT else 1.0 - 2.0 * np.abs(u) / self.width
        return np.where(inside, shape, 0.0)


def _samples(lo, hi, pitch):
    count = max(1, int(np.ceil((hi - lo) / pitch)))
    step = (hi - lo) / count
    return lo + (np.arange(count) + 0.5) * step, step


def flat_field(xi, sigma):
    """The window alone, summed as a product of two 1-D sums (±7σ, pitch σ/200)."""
    x, step = _samples(-7 * sigma, 7 * sigma, sigma / 200)
    window = np.exp(-0.5 * (x / sigma) ** 2) * step
    fx = np.exp(-2j * np.pi * np.outer(xi[:, 0], x)) @ window
    fy = np.exp(-2j * np.pi * np.outer(xi[:, 1], x)) @ window
    return fx * fy


def field_scratch_frames(scratches, xi, k_z, sigma, pitch=0.01):
    """U(ξ) with every scratch rasterised on its own aligned grid.

    ``xi`` (M, 2) in 1/µm, ``k_z`` (M,) in 1/µm (it depends on the direction).
    """
    total = flat_field(xi, sigma).astype(complex)
    for s in scratches:
        a, length, d, n = s.frame()
        c, a_perp = a @ d, a @ n
        # along: only where the window is not negligible
        lo, hi = max(0.0, -7 * sigma - c), min(length, 7 * sigma - c)
        if hi <= lo:
            continue
        t, dt = _samples(lo, hi, pitch)
        u, du = _samples(-0.5 * s.width, 0.5 * s.width, pitch)
        nu_par, nu_perp = xi @ d, xi @ n
        along = np.exp(-2j * np.pi * np.outer(nu_par, c + t)) @ (np.exp(-0.5 * ((c + t) / sigma) ** 2) * dt)
        depth = s.depth * s.profile_at(u)
        transfer = np.exp(1j * np.outer(k_z, depth)) - 1.0
        across = np.sum(np.exp(-2j * np.pi * np.outer(nu_perp, a_perp + u)) * transfer
                        * (np.exp(-0.5 * ((a_perp + u) / sigma) ** 2) * du), axis=1)
        total += along * across
    return total


def field_global_raster(scratches, xi, k_z, sigma, pitch=0.015, half_size=None, chunk=4096):
    """U(ξ) from one global height-field raster (pixel centres), summed directly."""
    half = 4.5 * sigma if half_size is None else half_size
    x, step = _samples(-half, half, pitch)
    gx, gy = np.meshgrid(x, x, indexing="xy")
    height = np.zeros_like(gx)
    for s in scratches:
        a, length, d, n = s.frame()
        rel_x, rel_y = gx - a[0], gy - a[1]
        t = rel_x * d[0] + rel_y * d[1]
        u = rel_x * n[0] + rel_y * n[1]
        on = (t >= 0) & (t <= length)
        height = np.maximum(height, np.where(on, s.depth * s.profile_at(u), 0.0))
    mask = height > 0
    px, py, ph = gx[mask], gy[mask], height[mask]
    weight = np.exp(-0.5 * (px * px + py * py) / sigma ** 2) * step * step

    # the flat part over the same square, as a product of 1-D sums
    window = np.exp(-0.5 * (x / sigma) ** 2) * step
    total = (np.exp(-2j * np.pi * np.outer(xi[:, 0], x)) @ window) * \
            (np.exp(-2j * np.pi * np.outer(xi[:, 1], x)) @ window)
    for start in range(0, len(px), chunk):
        sl = slice(start, start + chunk)
        phase = np.exp(-2j * np.pi * (np.outer(xi[:, 0], px[sl]) + np.outer(xi[:, 1], py[sl])))
        transfer = np.exp(1j * np.outer(k_z, ph[sl])) - 1.0
        total += np.sum(phase * transfer * weight[sl], axis=1)
    return total


def brdf(field, wavelength, sigma):
    """f_r = |U|² / (λ² π σ²) (perfect mirror base, F = 1)."""
    return np.abs(field) ** 2 / (wavelength ** 2 * np.pi * sigma ** 2)


def directions(xi, wavelength, wi):
    """Outgoing directions of spatial frequencies ``xi`` (rows), and which are valid."""
    wo_t = wavelength * xi - np.asarray(wi)[:2]
    sin2 = np.sum(wo_t ** 2, axis=1)
    valid = sin2 < 0.98
    wo = np.column_stack([wo_t, np.sqrt(np.clip(1 - sin2, 0, None))])
    return wo, valid


def kz_of(wo, wi, wavelength):
    return 2 * np.pi * (wi[2] + wo[:, 2]) / wavelength


# ------------------------------------------------------------------------------
# The analytic models of docs/model.md §3.3 that the plugin improves on, for comparison
def _phi_difference(t0, t1, nu, sigma):
    """Φ(t1; ν) - Φ(t0; ν) through scipy's Faddeeva function (numpy, exact)."""
    from scipy.special import wofz

    def end(t):
        s = np.where(t >= 0, -1.0, 1.0)
        b = 2 * np.pi * nu * sigma ** 2
        w = wofz((s * b + 1j * np.abs(t)) / (np.sqrt(2) * sigma))
        g = np.exp(-0.5 * (t / sigma) ** 2 - 2j * np.pi * nu * t)
        return s * g * w + 2 * np.exp(-2 * np.pi ** 2 * sigma ** 2 * nu ** 2) * (t >= 0)

    return np.sqrt(np.pi / 2) * sigma * (end(t1) - end(t0))


def _cross_section_model(s, nu, kappa):
    """G(ν) of docs/model.md §3.1 (ν may be complex)."""
    w = s.width
    if s.profile == RECT:
        return (np.exp(1j * kappa) - 1) * w * np.sinc(w * nu)
    half = np.exp(0.5j * kappa) * 0.5 * w
    return half * (np.exp(0.5j * np.pi * nu * w) * np.sinc(kappa / (2 * np.pi) - nu * w / 2)
                   + np.exp(-0.5j * np.pi * nu * w) * np.sinc(kappa / (2 * np.pi) + nu * w / 2)) \
        - w * np.sinc(w * nu)


def field_separable_model(scratches, xi, k_z, sigma, complex_shift):
    """U(ξ) of docs/model.md §3.3: the window frozen across each scratch (plain, ``complex_shift=False``)
    or linearised across it (the complex-frequency correction, docs/model.md §3.3)."""
    total = 2 * np.pi * sigma ** 2 * np.exp(-2 * np.pi ** 2 * sigma ** 2 * np.sum(xi ** 2, axis=1)) + 0j
    for s in scratches:
        a, length, d, n = s.frame()
        c, a_perp = a @ d, a @ n
        nu_par, nu_perp = xi @ d, xi @ n
        shift = a_perp / (2 * np.pi * sigma ** 2) if complex_shift else 0.0
        total += (np.exp(-2j * np.pi * nu_perp * a_perp) * _phi_difference(c, c + length, nu_par, sigma)
                  * np.exp(-0.5 * (a_perp / sigma) ** 2) * _cross_section_model(s, nu_perp - 1j * shift, k_z * s.depth))
    return total


# ------------------------------------------------------------------------------
# Whole direction-cosine planes at once: one raster, separable windowed DFTs
def raster_footprints(scratches, pitch, half_size):
    """Rasterise rectangular scratches on one pixel-centre grid over ±``half_size`` µm.

    Returns ``(x, footprints, deepest)``: the grid's coordinates (N,), and per
    scratch the flat pixel indices (row · N + column, row = y) it covers and
    those where it is the deepest scratch (its depth is the height field's
    there; at a crossing the deeper scratch owns the pixel).  The transfer
    function of the true height field is then ``1 + Σ_k (e^{i k_z D_k} − 1)
    χ[deepest_k]``; the model's sum of transfer functions uses ``footprints``.
    """
    if any(s.profile != RECT for s in scratches):
        raise ValueError("raster_footprints handles rectangular profiles (one depth per scratch)")
    x, _ = _samples(-half_size, half_size, pitch)
    n = len(x)
    depth = np.zeros((n, n), dtype=np.float32)
    owner = np.full((n, n), -1, dtype=np.int16)
    footprints = []
    for k, s in enumerate(scratches):
        a, length, d, nrm = s.frame()
        corners = np.array([a + sa * length * d + sn * 0.5 * s.width * nrm for sa in (0, 1) for sn in (-1, 1)])
        lo = np.clip(np.searchsorted(x, corners.min(axis=0) - pitch), 0, n)
        hi = np.clip(np.searchsorted(x, corners.max(axis=0) + pitch), 0, n)
        gx, gy = np.meshgrid(x[lo[0]:hi[0]] - a[0], x[lo[1]:hi[1]] - a[1], indexing="xy")
        t = gx * d[0] + gy * d[1]
        u = gx * nrm[0] + gy * nrm[1]
        inside = (t >= 0) & (t <= length) & (np.abs(u) <= 0.5 * s.width)
        rows, cols = np.nonzero(inside)
        rows, cols = rows + lo[1], cols + lo[0]
        footprints.append(rows * n + cols)
        deeper = s.depth > depth[rows, cols]
        depth[rows[deeper], cols[deeper]] = s.depth
        owner[rows[deeper], cols[deeper]] = k
    flat_owner = owner.ravel()
    deepest = [p[flat_owner[p] == k] for k, p in enumerate(footprints)]
    return x, footprints, deepest


def windowed_dft(pixels, x, sigma, xi_x, xi_y):
    """Σ_pixels w(x) e^{-2πi ξ·x} Δx² over the grid ξ = (xi_x[j], xi_y[i]) → (len(xi_y), len(xi_x)).

    ``pixels`` are flat indices (row · N + column) of the grid ``x`` (pixel
    centres, pitch Δx); the Gaussian window and the phase separate, so the sum
    is two matrix products with the sparse pixel mask in between.
    """
    from scipy import sparse

    n = len(x)
    pitch = x[1] - x[0]
    weight = np.exp(-0.5 * (x / sigma) ** 2) * pitch
    along_x = weight[:, None] * np.exp(-2j * np.pi * np.outer(x, xi_x))  # (N, Mx)
    along_y = weight[None, :] * np.exp(-2j * np.pi * np.outer(xi_y, x))  # (My, N)
    rows, cols = np.divmod(np.asarray(pixels, dtype=np.int64), n)
    used, row_index = np.unique(rows, return_inverse=True)
    mask = sparse.csr_matrix((np.ones(len(cols)), (row_index, cols)), shape=(len(used), n))
    return along_y[:, used] @ (mask @ along_x)


def mirror_field(xi_x, xi_y, sigma):
    """U0 = 2πσ² exp(-2π²σ²|ξ|²), the unscratched window's field, on the grid (len(xi_y), len(xi_x))."""
    r2 = xi_x[None, :] ** 2 + xi_y[:, None] ** 2
    return 2 * np.pi * sigma ** 2 * np.exp(-2 * np.pi ** 2 * sigma ** 2 * r2)
