"""The footprint filter's kernels (docs/model.md §11) against numerical averages of the point model.

The references are quadratures in numpy (float64, scipy's Faddeeva function) of the point model's
window integral and cross sections (:mod:`point_numpy`) over the footprint: a segment's amplitude is
a product of a factor along it and one across it, so its footprint averages are two-dimensional
integrals of products of one-dimensional functions, summed on fine grids (0.25 µm or 1/20 of a
standard deviation).  Frequencies stay on and around the diffraction lines (|4πσν∥| <= 8, where the
moments regime applies); the ends' asymptotic tails beyond are checked for a bounded error only.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf.filtered import along, footprint as fp, mean_field, pairs, single
from scratch_iridescence.mitsuba_bridge.bsdf.maths.segment import SegmentGeometry

import point_numpy as pn

SIGMA = 5.0
LINE = 2.0 * math.pi * SIGMA ** 2  # E|Φ|² of an infinite line at ν∥ = 0: the along factor's scale
K_Z = 4.0 * math.pi / 0.55  # normal incidence, 550 nm


def geometry(segment: pn.Segment) -> SegmentGeometry:
    a = segment.start
    return SegmentGeometry(c=mi.Float(a @ segment.d), length=mi.Float(segment.length), a_perp=mi.Float(a @ segment.n),
                           dx=mi.Float(segment.d[0]), dy=mi.Float(segment.d[1]), width=mi.Float(segment.width),
                           depth=mi.Float(segment.depth), triangular=mi.Bool(segment.v_groove))


def footprint(cov) -> fp.Footprint:
    return fp.Footprint(mi.Float(cov[0][0]), mi.Float(cov[0][1]), mi.Float(cov[1][1]))


def gaussian_grid(std, extent=6.0, step_um=0.25, max_points=2001):
    """Nodes and weights (summing to 1) of a uniform grid over N(0, std²)."""
    if std == 0.0:
        return np.zeros(1), np.ones(1)
    count = int(min(max_points, max(41, 2 * extent * std / step_um + 1)))
    x = np.linspace(-extent * std, extent * std, count)
    w = np.exp(-0.5 * (x / std) ** 2)
    return x, w / w.sum()


def along_reference(t0, t1, nu, mean, variance):
    x, w = gaussian_grid(math.sqrt(variance))
    tau = mean + x
    return (w[:, None] * np.abs(pn.window_integral(t0 - tau[:, None], t1 - tau[:, None], nu[None, :], SIGMA)) ** 2).sum(0)


def segment_frame_grid(segment, cov):
    """``(tau, u, weights)``: a grid over the footprint's coordinates along and across the segment."""
    d, n = segment.d, segment.n
    c = np.asarray(cov, float)
    var_t, var_u, cov_tu = d @ c @ d, n @ c @ n, d @ c @ n
    u, wu = gaussian_grid(math.sqrt(var_u), step_um=0.25, max_points=801)
    slope = cov_tu / var_u if var_u > 0 else 0.0
    conditional = max(var_t - slope * cov_tu, 0.0)
    z, wz = gaussian_grid(math.sqrt(conditional), step_um=0.25, max_points=801)
    tau = slope * u[:, None] + z[None, :]
    return tau, u, wu[:, None] * wz[None, :]


# ------------------------------------------------------------------------------------------- along
ALONG_CASES = [(-3.0, 60.0), (-4.0, 6.0), (-30.0, 2.0), (-1.0, 1.5), (0.5, 40.0), (-500.0, 500.0), (12.0, 30.0),
               (-1000.0, -5.0), (15.0, 200.0), (-9.0, 9.0)]
ALONG_STDS = [0.0, 0.3, 0.6, 1.0, 1.5, 2.0, 5.0, 20.0]


def test01_along_factor_equals_its_footprint_average():
    """Every regime (moments, half-range nodes, envelope nodes, the point itself) within 0.3 % of the
    larger of the segment's own peak and 1 % of an infinite line's; tails within 2·10⁻³ of the line."""
    cases = [(t0, t1, (s * SIGMA) ** 2, mean) for t0, t1 in ALONG_CASES for s in ALONG_STDS for mean in (0.0, 7.0)]
    t0, t1, variance, mean = (mi.Float([c[i] for c in cases]) for i in range(4))
    core = np.array([0.0, 0.01, 0.02, 0.04, 0.07, 0.1, 0.12])  # |4πσν| <= 7.5
    tails = np.array([0.15, 0.2, 0.5])
    nus = np.concatenate([core, tails])
    got = np.array([np.asarray(along.along_intensity(t0, t1, mi.Spectrum(nu), mi.Float(SIGMA), mean, variance))[0]
                    for nu in nus]).T
    for (a, b, v, m), values in zip(cases, got):
        expected = along_reference(a, b, nus, m, v)
        scale = max(expected[:len(core)].max(), 0.01 * LINE)
        assert np.abs(values[:len(core)] - expected[:len(core)]).max() <= 3e-3 * scale, (a, b, v, m)
        assert np.abs(values[len(core):] - expected[len(core):]).max() <= 2e-3 * LINE, (a, b, v, m)


def test02_the_along_factor_of_a_zero_footprint_is_the_point_value():
    """Within 0.3 % of the segment's peak (the quadrature's nodes; the plugin itself takes the point model
    where the footprint is a point: test_filtered_bsdf.py checks that bit for bit)."""
    nus = np.array([0.0, 0.03, 0.1])
    for t0, t1 in ALONG_CASES:
        got = [np.asarray(along.along_intensity(mi.Float(t0), mi.Float(t1), mi.Spectrum(nu), mi.Float(SIGMA),
                                                mi.Float(0.0), mi.Float(0.0)))[0, 0] for nu in nus]
        point = np.abs(pn.window_integral(np.float64(t0), np.float64(t1), nus, SIGMA)) ** 2
        np.testing.assert_allclose(got, point, rtol=0.0, atol=3e-3 * point[0] + 1e-6 * LINE, err_msg=str((t0, t1)))


# --------------------------------------------------------------------------- a segment's intensity
SEGMENTS = {
    "long rect": pn.Segment((-300, 3), (300, 3), 4.0, 0.25),
    "V ending near the centre": pn.Segment((-300, -8), (40, 20), 3.0, 0.3, v_groove=True),
    "short rect": pn.Segment((-2, 1), (12, -4), 2.0, 0.2),
    "wide rect": pn.Segment((-300, 0), (300, 0), 9.0, 0.5),
    "wide V": pn.Segment((-300, -2), (300, 4), 7.0, 0.6, v_groove=True),
}
COVARIANCES = {"isotropic 2 µm": [[4.0, 0.0], [0.0, 4.0]], "isotropic 5 µm": [[25.0, 0.0], [0.0, 25.0]],
               "sheared": [[100.0, 60.0], [60.0, 80.0]], "long across": [[400.0, 0.0], [0.0, 2500.0]],
               "oblique 50 µm": [[2500.0, -1500.0], [-1500.0, 1600.0]]}


def directions(segment):
    """Frequencies across the segment's line and along it beside the mirror lobe (1/µm)."""
    t = np.linspace(-0.6, 0.6, 25)
    return np.concatenate([np.outer(t, segment.n) + 0.004 * segment.d,
                           np.outer(np.linspace(-0.06, 0.06, 13), segment.d) + 0.2 * segment.n])


def filtered(function, segment, cov, xi, *extra):
    values = [function(geometry(segment), footprint(cov), mi.Spectrum(x[0]), mi.Spectrum(x[1]), mi.Spectrum(K_Z),
                       mi.Float(SIGMA), *extra) for x in xi]
    return np.array([np.asarray(v.re)[0, 0] + 1j * np.asarray(v.im)[0, 0] if hasattr(v, "re")
                     else np.asarray(v)[0, 0] for v in values])


#: the footprints whose grids take longest (up to 1.5 min a case on the shared 2-core machine): `make test-slow`
SLOW_COVARIANCES = ("long across", "oblique 50 µm")


@pytest.mark.parametrize("name", list(SEGMENTS))
@pytest.mark.parametrize("cov_name", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW_COVARIANCES else c
                                      for c in COVARIANCES])
def test03_a_segments_intensity_equals_its_footprint_average(name, cov_name):
    segment, cov = SEGMENTS[name], COVARIANCES[cov_name]
    xi = directions(segment)
    tau, u, weights = segment_frame_grid(segment, cov)
    c, a_perp = segment.start @ segment.d, segment.start @ segment.n
    along_values = np.abs(pn.window_integral(c - tau[..., None], c + segment.length - tau[..., None],
                                             (xi @ segment.d)[None, None, :], SIGMA)) ** 2
    across = np.abs(pn.cross_section((xi @ segment.n)[None, :], a_perp - u[:, None], segment.width,
                                     K_Z * segment.depth, SIGMA, segment.v_groove)) ** 2
    expected = np.einsum("ij,ijk,ik->k", weights, along_values, across)
    got = filtered(single.segment_intensity, segment, cov, xi, True)
    error = np.sqrt(np.mean((got - expected) ** 2) / np.mean(expected ** 2))
    assert error < 0.01, error


@pytest.mark.parametrize("name", ["long rect", "V ending near the centre", "short rect"])
@pytest.mark.parametrize("cov_name", ["isotropic 2 µm", "sheared",
                                      pytest.param("oblique 50 µm", marks=pytest.mark.slow)])
def test04_the_mean_amplitude_equals_its_footprint_average(name, cov_name):
    segment, cov = SEGMENTS[name], COVARIANCES[cov_name]
    g = np.linspace(-0.05, 0.05, 9)
    xi = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    tau, u, weights = segment_frame_grid(segment, cov)
    c, a_perp = segment.start @ segment.d, segment.start @ segment.n
    along_values = pn.window_integral(c - tau[..., None], c + segment.length - tau[..., None],
                                      (xi @ segment.d)[None, None, :], SIGMA)
    across = pn.cross_section((xi @ segment.n)[None, :], a_perp - u[:, None], segment.width, K_Z * segment.depth,
                              SIGMA, segment.v_groove)
    expected = np.einsum("ij,ijk,ik->k", weights, along_values, across)
    got = filtered(mean_field.mean_amplitude, segment, cov, xi)
    error = np.sqrt(np.mean(np.abs(got - expected) ** 2) / np.mean(np.abs(expected) ** 2))
    assert error < 0.005, error


# ------------------------------------------------------------------------------------------- pairs
def pair_average(first, second, cov, xi, real=False):
    """``E[S_1 S_2*]`` by a 2-D grid over the footprint, refined where both lines come close."""
    ev, vectors = np.linalg.eigh(np.asarray(cov, float))
    x1, w1 = gaussian_grid(math.sqrt(ev[0]), extent=5.5, step_um=0.3, max_points=321)
    x2, w2 = gaussian_grid(math.sqrt(ev[1]), extent=5.5, step_um=0.3, max_points=321)
    points = np.stack(np.meshgrid(x1, x2, indexing="ij"), -1).reshape(-1, 2) @ vectors.T
    weights = np.outer(w1, w2).ravel()
    total = 0
    for i in range(0, len(points), 20000):
        chunk = points[i:i + 20000]
        product = first.amplitude(chunk, xi, K_Z, SIGMA) * np.conj(second.amplitude(chunk, xi, K_Z, SIGMA))
        total = total + (weights[i:i + 20000, None] * (product.real if real else product)).sum(0)
    return total


@pytest.mark.parametrize("angle", [90.0, 30.0])
@pytest.mark.parametrize("std", [0.5, pytest.param(2.0, marks=pytest.mark.slow),  # ~10 s a case: test-slow
                                 pytest.param(5.0, marks=pytest.mark.slow)])
def test05_crossing_pairs_follow_their_footprint_average(angle, std):
    """The closed form (and the nodes of narrow footprints) against the average; the pair term itself
    is a few per cent of the intensity at these footprints, the closed form within 10 % of the term."""
    theta = math.radians(angle)
    first = pn.Segment((-400, 2), (400, 2), 4.0, 0.25)
    second = pn.Segment((-400 * math.cos(theta) + 3, -400 * math.sin(theta)),
                        (400 * math.cos(theta) + 3, 400 * math.sin(theta)), 3.0, 0.3, v_groove=True)
    g = np.linspace(-0.06, 0.06, 7)
    xi = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    cov = (std * SIGMA) ** 2 * np.array([[1.0, 0.3], [0.3, 0.7]])
    expected = pair_average(first, second, cov, xi)
    function = pairs.point_pair if std * SIGMA < pairs.POINT_PAIRS_BELOW * SIGMA else pairs.crossing_pair
    got = filtered(function, first, cov, xi) if False else np.array([
        (lambda v: np.asarray(v.re)[0, 0] + 1j * np.asarray(v.im)[0, 0])(
            function(geometry(first), geometry(second), footprint(cov), mi.Spectrum(x[0]), mi.Spectrum(x[1]),
                     mi.Spectrum(K_Z), mi.Float(SIGMA))) for x in xi])
    error = np.sqrt(np.mean(np.abs(got - expected) ** 2) / np.mean(np.abs(expected) ** 2))
    assert error < (0.02 if function is pairs.point_pair else 0.1), error


def test06_parallel_pairs_factorise_exactly():
    first = pn.Segment((-400, 0), (400, 0), 3.0, 0.25)
    second = pn.Segment((-400, 4), (400, 4), 2.0, 0.3, v_groove=True)
    t = np.linspace(-0.5, 0.5, 11)
    xi = np.concatenate([np.outer(t, first.n) + 0.003 * first.d, np.outer(np.linspace(-0.05, 0.05, 5), first.d)])
    for std in (0.3, 3.0):
        cov = (std * SIGMA) ** 2 * np.array([[1.0, 0.2], [0.2, 0.6]])
        expected = pair_average(first, second, cov, xi, real=True)
        got = np.array([np.asarray(pairs.parallel_pair(geometry(first), geometry(second), footprint(cov),
                                                       mi.Spectrum(x[0]), mi.Spectrum(x[1]), mi.Spectrum(K_Z),
                                                       mi.Float(SIGMA)))[0, 0] for x in xi])
        error = np.sqrt(np.mean((got - expected) ** 2) / np.mean(expected ** 2))
        assert error < 0.005, (std, error)
