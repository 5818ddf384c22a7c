"""The pure Dr.Jit maths of the BSDF against scipy: Faddeeva, window integrals, profile transforms, Fresnel."""
from __future__ import annotations

import math

import mitsuba as mi
import numpy as np
import pytest
from scipy import integrate
from scipy.special import wofz

from scratch_iridescence.mitsuba_bridge.bsdf import fresnel
from scratch_iridescence.mitsuba_bridge.bsdf.maths import profiles
from scratch_iridescence.mitsuba_bridge.bsdf.maths.complexmath import Cx
from scratch_iridescence.mitsuba_bridge.bsdf.maths.faddeeva import (DEFAULT_TERMS, faddeeva, real_polynomial_at,
                                                                weideman_coefficients)
from scratch_iridescence.mitsuba_bridge.bsdf.maths.window import window_integral

# docs/model.md §3.2 prints these (N = 16, Horner order).
MODEL_COEFFICIENTS = [
    9.9393225361232851e-07, 3.9812875751276274e-06, -5.5842334110358388e-06, -2.7346404624397707e-05,
    2.1709867932311022e-05, 2.1071056396538515e-04, 8.7031584284602594e-05, -1.5276597401220064e-03,
    -3.8810151890227669e-03, 3.6825673170917811e-03, 5.1822402431611445e-02, 1.9124172674669468e-01,
    4.6929090090360354e-01, 8.8644783020505447e-01, 1.3622408222719584e+00, 1.7483958860819617e+00]


def numpy_complex(z: Cx) -> np.ndarray:
    return np.asarray(z.re, dtype=np.float64) + 1j * np.asarray(z.im, dtype=np.float64)


def floats(values) -> mi.Float:
    return mi.Float(np.asarray(values, dtype=np.float32).ravel())


def test01_weideman_coefficients_reproduce_model_table():
    scale, coefficients = weideman_coefficients(16)
    assert scale == pytest.approx(3.363585661014858, rel=1e-14)
    np.testing.assert_allclose(coefficients, MODEL_COEFFICIENTS, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("terms, tolerance", [(DEFAULT_TERMS, 1e-5), (16, 2e-6)])
def test02_faddeeva_matches_scipy_wofz(terms, tolerance):
    x = np.linspace(-600, 600, 1201)
    y = np.concatenate([[0.0], np.logspace(-5, np.log10(8.0), 40), [20.0, 100.0]])
    z = (x[None, :] + 1j * y[:, None]).ravel()
    got = numpy_complex(faddeeva(Cx(floats(z.real), floats(z.imag)), terms))
    expected = wofz(z.astype(np.complex64).astype(np.complex128))  # the float32 inputs
    relative = np.abs(got - expected) / np.abs(expected)
    assert relative.max() < tolerance, z[np.argmax(relative)]


def test03_faddeeva_is_finite_for_extreme_arguments():
    x = np.array([0.0, 1e-30, 1e6, -1e6, 3e37, -3e37, 5.0])
    y = np.array([0.0, 0.0, 0.0, 1e6, 0.0, 3e37, 1e-38])
    w = numpy_complex(faddeeva(Cx(floats(x), floats(y))))
    assert np.all(np.isfinite(w))
    assert np.all(np.abs(w) <= 1.0 + 1e-5)  # |w| <= 1 in the upper half plane


@pytest.mark.parametrize("degree", [2, 3, 7, 12, 15])
def test03b_real_polynomial_at_a_complex_point_matches_numpy(degree):
    """The Faddeeva polynomial's real recurrence (docs/model.md §3.2) against numpy's complex Horner,
    in the closed unit disk (where the Faddeeva function evaluates it), unit circle included."""
    rng = np.random.default_rng(30 + degree)
    radius = np.concatenate([np.sqrt(rng.uniform(0.0, 1.0, 2000)), np.ones(200)])
    z = (radius * np.exp(1j * rng.uniform(-np.pi, np.pi, radius.size))).astype(np.complex64)
    coefficients = rng.normal(0.0, 1.0, degree + 1)
    got = numpy_complex(real_polynomial_at(tuple(coefficients), Cx(floats(z.real), floats(z.imag))))
    expected = np.polyval(coefficients, z.astype(np.complex128))
    # float32 rounding of a degree-15 sum of terms at most Σ|a_k| in size
    np.testing.assert_allclose(got, expected, rtol=0, atol=5e-7 * degree * np.abs(coefficients).sum())


def window_integral_by_quadrature(t0, t1, nu, sigma):
    def part(f):
        return integrate.quad(lambda t: np.exp(-0.5 * (t / sigma) ** 2) * f(2 * np.pi * nu * t), t0, t1,
                              limit=400, epsabs=1e-12)[0]
    return part(np.cos) - 1j * part(np.sin)


def test04_window_integral_matches_quadrature():
    rng = np.random.default_rng(4)
    sigma = 2.0
    cases = [(-50.0, 50.0, 0.3), (0.0, 3.0, 1.7), (-5.0, -0.5, -2.2), (1.0, 9.0, 0.0), (-20.0, 1.2, 4.5),
             (7.9, 8.5, 0.1), (-0.2, 0.3, 12.0)]
    cases += [tuple(sorted(rng.uniform(-10, 10, 2))) + (rng.uniform(-5, 5),) for _ in range(12)]
    t0, t1, nu = (np.array(c) for c in zip(*cases))
    got = numpy_complex(window_integral(floats(t0), floats(t1), floats(nu), sigma))
    expected = np.array([window_integral_by_quadrature(*c, sigma) for c in cases])
    # absolute error relative to the window's full integral σ√(2π)
    np.testing.assert_allclose(got, expected, atol=2e-5 * sigma * math.sqrt(2 * math.pi), rtol=0)


def profile_by_quadrature(kind, a_perp, width, nu, kappa, sigma, coherent):
    def depth(x):
        u = x - a_perp
        return 1.0 if kind == "rect" else 1.0 - 2.0 * abs(u) / width

    def integrand(x):
        transfer = np.exp(1j * kappa * depth(x)) - (1.0 if coherent else 0.0)
        return np.exp(-0.5 * (x / sigma) ** 2) * transfer * np.exp(-2j * np.pi * nu * x)

    lo, hi = a_perp - 0.5 * width, a_perp + 0.5 * width
    re = integrate.quad(lambda x: integrand(x).real, lo, hi, points=[a_perp], limit=400, epsabs=1e-13)[0]
    im = integrate.quad(lambda x: integrand(x).imag, lo, hi, points=[a_perp], limit=400, epsabs=1e-13)[0]
    return re + 1j * im


@pytest.mark.parametrize("kind", ["rect", "tri"])
@pytest.mark.parametrize("coherent", [True, False])
def test05_cross_section_transforms_match_quadrature(kind, coherent):
    sigma = 2.0
    cases = [(0.0, 1.0, 0.0, 1.5), (0.0, 1.0, 0.9, 3.0), (2.5, 2.0, -1.3, 0.8), (-4.0, 4.0, 0.25, 6.0),
             (1.0, 0.2, 3.7, 0.4), (0.3, 6.0, -0.6, 10.0), (7.0, 1.5, 1.1, 2.0)]
    a, w, nu, kappa = (np.array(c) for c in zip(*cases))
    function = profiles.rectangular if kind == "rect" else profiles.triangular
    got = numpy_complex(function(floats(a), floats(w), floats(nu), floats(kappa), sigma, coherent))
    expected = np.array([profile_by_quadrature(kind, *c, sigma, coherent) for c in cases])
    np.testing.assert_allclose(got, expected, atol=3e-5 * w.max(), rtol=0)


@pytest.mark.parametrize("kind", ["rect", "tri"])
def test06_energy_factors_match_quadrature(kind):
    kappa = np.array([1e-4, 0.01, 0.2, 0.29, 0.31, 1.0, math.pi, 5.0, 20.0])
    function = profiles.energy_rectangular if kind == "rect" else profiles.energy_triangular
    got = np.asarray(function(floats(kappa)))
    shape = (lambda u: 1.0) if kind == "rect" else (lambda u: 1.0 - 2.0 * abs(u))
    expected = [integrate.quad(lambda u: abs(np.exp(1j * k * shape(u)) - 1) ** 2, -0.5, 0.5, points=[0])[0]
                for k in kappa]
    np.testing.assert_allclose(got, expected, rtol=2e-4, atol=1e-12)


def test07_conductor_fresnel_matches_mitsuba_per_wavelength():
    rng = np.random.default_rng(7)
    cos_theta = rng.uniform(0.01, 1.0, 200)
    eta, k = rng.uniform(0.1, 3.0, (4, 200)), rng.uniform(0.0, 8.0, (4, 200))
    got = np.asarray(fresnel.fresnel_conductor(floats(cos_theta), mi.Spectrum(*map(floats, eta)),
                                               mi.Spectrum(*map(floats, k))))
    for channel in range(4):
        expected = mi.fresnel_conductor(floats(cos_theta), mi.Complex2f(floats(eta[channel]), floats(k[channel])))
        np.testing.assert_allclose(got[channel], np.asarray(expected), rtol=2e-5, atol=1e-6)


def test08_named_materials_load_mitsubas_spectra_and_unknown_names_are_refused():
    eta, k = fresnel.material_textures("Au")
    si = mi.SurfaceInteraction3f()
    si.wavelengths = mi.Spectrum(450, 550, 650, 750)
    eta_values = np.asarray(eta.eval(si)).ravel()
    assert eta_values[0] > 1.0 > eta_values[2]  # gold: high index in the blue, low in the red
    with pytest.raises(ValueError, match="unknown material 'Unobtainium'.*Al"):
        fresnel.material_textures("Unobtainium")


@pytest.mark.parametrize("name", ["Al", "Au", "Cu"])
def test09_conductor_table_reads_what_the_material_textures_read(name):
    """The one-gather table (fresnel.ConductorSpectra) returns the textures' values, 0 outside their grid."""
    import drjit as dr

    eta, k = fresnel.material_textures(name)
    assert fresnel.ConductorSpectra.matches(eta, k)
    table = fresnel.ConductorSpectra.of(eta, k)
    wavelengths = np.random.default_rng(9).uniform(250.0, 950.0, (4, 3000)).astype(np.float32)
    wavelengths[:, :4] = [[299.0, 885.0, 360.0, 830.0]] * 4  # the grids' ends and the visible range's
    si = dr.zeros(mi.SurfaceInteraction3f, wavelengths.shape[1])
    si.wavelengths = mi.Spectrum(*map(floats, wavelengths))
    got_eta, got_k = (np.asarray(x) for x in table.eval(si.wavelengths))
    want_eta, want_k = np.asarray(eta.eval(si)), np.asarray(k.eval(si))
    assert np.count_nonzero(want_eta == 0) > 100  # some wavelengths lie outside the grid
    np.testing.assert_allclose(got_eta, want_eta, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(got_k, want_k, rtol=1e-6, atol=1e-6)


def test10_conductor_table_only_for_regular_spectra_and_keeps_gradients():
    import drjit as dr

    uniform = mi.load_dict({"type": "uniform", "value": 1.5})
    irregular = mi.load_dict({"type": "irregular", "wavelengths": "400, 700", "values": "1, 2"})
    eta, k = fresnel.material_textures("Au")
    assert not fresnel.ConductorSpectra.matches(uniform, uniform)
    assert not fresnel.ConductorSpectra.matches(irregular, irregular)
    values = mi.traverse(eta)["values"]
    dr.enable_grad(values)
    params = mi.traverse(eta)
    params["values"] = values
    params.update()
    table = fresnel.ConductorSpectra.of(eta, k)
    got, _ = table.eval(mi.Spectrum(500.5, 500.5, 500.5, 500.5))
    dr.backward(dr.sum(got[0]))
    grad = np.asarray(dr.grad(mi.traverse(eta)["values"]))
    node = int(round(500.5 - 299.0))  # the grid starts at 299 nm, one node per nanometre
    np.testing.assert_allclose(grad[node - 1:node + 1], [0.5, 0.5], rtol=1e-6)
    assert np.count_nonzero(grad) == 2
