"""The footprint-filtered plugin (``footprint_filter=True``, docs/model.md §11) against the point plugin.

The reference is the definition itself: the point plugin's f_r averaged over shading points spread
as the footprint's Gaussian, Σ = r² (I + ω_t ω_tᵀ / ω_z²) (module ``filtered.footprint``), on a
uniform grid in the footprint's eigenbasis (±4 standard deviations, steps of at most σ: the point
BRDF varies with the shading point on the scale of the window σ, so the grid's sum is a quadrature
of the average, deterministic, to far better than the tolerance).  Compared is the scratches' part
of f_r (the unscratched plate's mirror lobe, the same in both, subtracted), at frequencies across
each scratch's diffraction line and beside it, for the four wavelengths of the ray.

The test surface (:mod:`shading`): 1 UV unit = 1 mm, ``footprint_width`` in scene units (mm) sets
the radius r; a hand-built interaction has ``si.t = ∞``, so ``footprint_angle`` plays no part.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.validation import reference as ref
import shading

SIGMA_UM = 2.0
WAVELENGTHS = (550.0, 600.0, 450.0, 650.0)
CTX = mi.BSDFContext()

CASES = {
    "one rectangular groove": [ref.Scratch((-150, 1.0), (150, 2.5), 2.0, 0.25)],
    "a V-groove ending inside": [ref.Scratch((-150, -3.0), (4.0, 2.0), 1.5, 0.3, ref.TRI)],
    "a crossing pair": [ref.Scratch((-150, 0.5), (150, 0.5), 2.0, 0.25),
                        ref.Scratch((-40, -120), (30, 120), 1.5, 0.3, ref.TRI)],
    "a parallel pair": [ref.Scratch((-150, 0.0), (150, 0.0), 1.5, 0.25),
                        ref.Scratch((-150, 3.0), (150, 3.0), 1.5, 0.2, ref.TRI)],
}
#: footprint radii in σ: about the window, several windows, far wider (30σ: crossing pairs left out, §11.5)
RADII_SIGMAS = (1.0, 4.0, 12.0, 30.0)
INCIDENCES_DEG = (20.0, 50.0)  #: (50°: under the slow marker, `make test-slow`)


def footprint_covariance(radius_um, wi):
    """Σ of ``filtered.footprint.footprint_of`` (µm², local frame; the stretch capped at 8)."""
    cos_i = max(abs(wi[2]), 1.0 / 8.0)
    w_t = np.asarray(wi[:2])
    return radius_um ** 2 * (np.eye(2) + np.outer(w_t, w_t) / cos_i ** 2)


def footprint_grid(cov, step_um=0.75 * SIGMA_UM, extent=4.0, max_side=401):
    """``(points µm (K, 2), weights (K,))``: a uniform grid over N(0, cov) in its eigenbasis, weights summing to 1."""
    values, vectors = np.linalg.eigh(np.asarray(cov, dtype=np.float64))
    axes = []
    for std in np.sqrt(np.maximum(values, 0.0)):
        count = int(min(max_side, max(21, 2 * extent * std / step_um + 1)))
        x = np.linspace(-extent * std, extent * std, count)
        axes.append((x, np.exp(-0.5 * (x / std) ** 2)))
    (x1, w1), (x2, w2) = axes
    points = np.stack(np.meshgrid(x1, x2, indexing="ij"), -1).reshape(-1, 2) @ vectors.T
    weights = np.outer(w1, w2).ravel()
    return points, weights / weights.sum()


def directions(scratches, wi, wavelength_um=WAVELENGTHS[0] * 1e-3):
    """Outgoing directions on each scratch's diffraction line (across it) and just beside it (along it)."""
    rows = []
    for s in scratches:
        d = np.subtract(s.b, s.a) / np.hypot(*np.subtract(s.b, s.a))
        n = np.array([-d[1], d[0]])
        for across in np.linspace(-0.45, 0.45, 13):
            for along in (0.0, 0.02):
                xi = across * n + along * d
                out = wavelength_um * xi - np.asarray(wi[:2])
                rows.append([out[0], out[1], math.sqrt(max(1.0 - out @ out, 0.0))])
    rows = np.asarray(rows)
    return rows[rows[:, 2] > 0.05]


def eval_at(bsdf, wi, wo_rows, uv=shading.X0_UV):
    """f_r cos θ_o (count, 4) for ``wo_rows`` at shading points ``uv`` (one per row, or one for all)."""
    si = shading.interaction(len(wo_rows), wi, WAVELENGTHS, uv=uv)
    return shading.spectrum_rows(bsdf.eval(CTX, si, shading.vector(wo_rows))).astype(np.float64)


def footprint_average(point, wi, wo_rows, cov, chunk=1_500_000):
    """The point plugin's f_r cos θ_o averaged over the footprint (the grid of :func:`footprint_grid`)."""
    points, weights = footprint_grid(cov)
    uv = shading.to_uv(points)
    total = np.zeros((len(wo_rows), 4))
    per_chunk = max(1, chunk // len(wo_rows))
    for start in range(0, len(points), per_chunk):
        part = slice(start, start + per_chunk)
        k = len(points[part])
        lanes_uv = (np.repeat(uv[part, 0], len(wo_rows)), np.repeat(uv[part, 1], len(wo_rows)))
        values = eval_at(point, wi, np.tile(wo_rows, (k, 1)), uv=lanes_uv).reshape(k, len(wo_rows), 4)
        total += np.einsum("k,kjc->jc", weights[part], values)
    return total


def filtered_bsdf(scratches, radius_um, **kwargs):
    return shading.load_bsdf(scratches, sigma_um=SIGMA_UM, footprint_filter=True, footprint_angle=0.0,
                             footprint_width=radius_um * 1e-3, **kwargs)


@pytest.mark.parametrize("incidence", [INCIDENCES_DEG[0]] + [pytest.param(i, marks=pytest.mark.slow)
                                                               for i in INCIDENCES_DEG[1:]])
@pytest.mark.parametrize("radius_sigmas", RADII_SIGMAS)
@pytest.mark.parametrize("name", list(CASES))
def test01_the_filtered_brdf_is_the_point_brdf_averaged_over_the_footprint(name, radius_sigmas, incidence):
    """The scratches' part of f_r within 2 % (relative RMS over the directions and wavelengths)."""
    scratches = CASES[name]
    wi = shading.direction(incidence, 25.0)
    wo = directions(scratches, wi)
    radius = radius_sigmas * SIGMA_UM
    mirror = eval_at(shading.load_bsdf(None, sigma_um=SIGMA_UM), wi, wo)
    expected = footprint_average(shading.load_bsdf(scratches, sigma_um=SIGMA_UM), wi, wo,
                                 footprint_covariance(radius, wi)) - mirror
    got = eval_at(filtered_bsdf(scratches, radius), wi, wo) - mirror
    error = np.sqrt(np.mean((got - expected) ** 2) / np.mean(expected ** 2))
    assert error <= 0.02, error


def test02_a_zero_footprint_is_the_point_plugin_bit_for_bit():
    """``footprint_width = 0`` (and ``footprint_angle = 0``): eval, pdf and sample equal the point plugin's."""
    scratches = CASES["a crossing pair"] + CASES["a V-groove ending inside"]
    point = shading.load_bsdf(scratches, sigma_um=SIGMA_UM)
    filtered = filtered_bsdf(scratches, 0.0)
    rng = np.random.default_rng(5)
    count = 4096
    uv = shading.to_uv(rng.uniform(-6.0, 6.0, (count, 2)))
    si = shading.interaction(count, shading.direction(35.0, 25.0), WAVELENGTHS, uv=(uv[:, 0], uv[:, 1]))
    u1 = shading.floats(rng.random(count))
    u2 = mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count)))
    for bsdf_a, bsdf_b in ((point, filtered),):
        bs_a, w_a = bsdf_a.sample(CTX, si, u1, u2)
        bs_b, w_b = bsdf_b.sample(CTX, si, u1, u2)
        np.testing.assert_array_equal(np.asarray(bs_a.wo), np.asarray(bs_b.wo))
        np.testing.assert_array_equal(np.asarray(bs_a.pdf), np.asarray(bs_b.pdf))
        np.testing.assert_array_equal(np.asarray(w_a), np.asarray(w_b))
        np.testing.assert_array_equal(np.asarray(bsdf_a.eval(CTX, si, bs_a.wo)), np.asarray(bsdf_b.eval(CTX, si, bs_a.wo)))
        np.testing.assert_array_equal(np.asarray(bsdf_a.pdf(CTX, si, bs_a.wo)), np.asarray(bsdf_b.pdf(CTX, si, bs_a.wo)))


@pytest.mark.parametrize("incidence", (20.0, 50.0))
def test03_the_albedo_is_the_footprint_average_of_the_point_albedo(incidence):
    """By linearity the filtered BRDF's albedo is the footprint's mean of the point albedo (docs/model.md
    §11.5): both estimated from sample weights (fixed seeds), within four standard errors of their difference,
    and at most 1 where the point model's is."""
    scratches = CASES["a crossing pair"]
    radius = 6.0 * SIGMA_UM
    wi = shading.direction(incidence, 25.0)
    rng = np.random.default_rng(9)
    count = 200_000

    def weights(bsdf, uv):
        si = shading.interaction(count, wi, WAVELENGTHS, uv=uv)
        _, w = bsdf.sample(CTX, si, shading.floats(rng.random(count)),
                           mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
        return np.asarray(w, dtype=np.float64)[0]  # the hero wavelength's weight: f cos / p for the sampled λ

    filtered = weights(filtered_bsdf(scratches, radius), shading.X0_UV)
    positions = rng.multivariate_normal(np.zeros(2), footprint_covariance(radius, wi), count)
    uv = shading.to_uv(positions)
    point = weights(shading.load_bsdf(scratches, sigma_um=SIGMA_UM), (uv[:, 0], uv[:, 1]))
    standard_error = math.sqrt(filtered.var() / count + point.var() / count)
    assert abs(filtered.mean() - point.mean()) <= 4.0 * standard_error, (filtered.mean(), point.mean())
    assert filtered.mean() <= 1.0 + 4.0 * filtered.std() / math.sqrt(count)


CHI2_CASES = {
    "one groove, footprint 4σ": (CASES["one rectangular groove"], 4.0, 0.5),
    "crossing pair, footprint 12σ": (CASES["a crossing pair"], 12.0, 0.5),
    "V ending inside, footprint 1σ": (CASES["a V-groove ending inside"], 1.0, 0.5),
}


@pytest.mark.parametrize("name", list(CHI2_CASES))
def test04_chi2_filtered_sampling_matches_its_pdf(name):
    """mitsuba.chi2 of ``sample`` against ``pdf`` (σ = 0.5 µm: lobes several histogram cells wide, as in
    test_sampling.py); then weight = eval / pdf on the samples."""
    scratches, radius_sigmas, sigma = CHI2_CASES[name]
    # the scratches in units of this σ (the cases are drawn for SIGMA_UM)
    scale = sigma / SIGMA_UM
    scratches = [ref.Scratch(tuple(np.multiply(s.a, scale)), tuple(np.multiply(s.b, scale)), s.width * scale,
                             s.depth, s.profile) for s in scratches]
    bsdf = shading.load_bsdf(scratches, sigma_um=sigma, footprint_filter=True, footprint_angle=0.0,
                             footprint_width=radius_sigmas * sigma * 1e-3)
    wi = shading.direction(35.0, 25.0)

    def sample_func(sample):
        si = shading.uniform_interaction(dr.width(sample), wi, WAVELENGTHS)
        bs, _ = bsdf.sample(CTX, si, sample[0], mi.Point2f(sample[1], sample[2]))
        return bs.wo, dr.select(bs.pdf > 0, 1.0, 0.0)

    def pdf_func(wo):
        return bsdf.pdf(CTX, shading.uniform_interaction(dr.width(wo), wi, WAVELENGTHS), wo)

    test = mi.chi2.ChiSquareTest(domain=mi.chi2.SphericalDomain(), sample_func=sample_func, pdf_func=pdf_func,
                                 sample_dim=3, sample_count=500_000, res=101, ires=4, seed=3)
    assert test.run(0.01, test_count=len(CHI2_CASES), quiet=True), test.messages

    count = 20000
    rng = np.random.default_rng(2)
    si = shading.interaction(count, wi, WAVELENGTHS)
    bs, weight = bsdf.sample(CTX, si, shading.floats(rng.random(count)),
                             mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
    value, pdf = bsdf.eval_pdf(CTX, si, bs.wo)
    weight, value, pdf, bs_pdf = (np.asarray(x, dtype=np.float64) for x in (weight, value, pdf, bs.pdf))
    valid = bs_pdf > 0
    assert valid.mean() > 0.5
    np.testing.assert_allclose(bs_pdf[valid], pdf[valid], rtol=1e-4)
    np.testing.assert_allclose(weight[:, valid], value[:, valid] / pdf[valid], rtol=1e-4, atol=1e-7)
