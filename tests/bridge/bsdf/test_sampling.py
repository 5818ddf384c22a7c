"""Importance sampling: chi² of ``sample`` against ``pdf`` (mitsuba.chi2), and weight = eval / pdf.

Coherence windows are small here (σ = 0.5 to 1 µm) so that the mirror lobe and
the scratch lines are several histogram cells wide; the four wavelengths of
each ray differ, so the test also checks that sampling density and pdf both
follow the first (hero) wavelength.  Incidences stay 20° or more from the
normal: the (φ, cos θ) histogram cells around the pole are too coarse for the
trapezoid integration of a lobe a few degrees wide (a mirror-only lobe at 10°
fails with ``ires=4`` and still with ``ires=10``, samples and pdf being
consistent to 1e-6 in ξ-space).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.validation import reference as ref
import shading

WAVELENGTHS = (520.0, 410.0, 680.0, 600.0)

#: "kinked_grating" is centred on (KINK_UM, KINK_UM) µm from x0: the middle of a 62.5 µm grid cell.
KINK_UM = 31.25

CONFIGS = {
    "mirror_only": ([], 0.5, 30.0, {}),
    "rect_offset": ([ref.Scratch((-20, 0.4), (20, 0.4), 1.0, 0.3)], 0.5, 40.0, {}),
    "deep_v_groove": ([ref.Scratch((-20, -0.2), (20, 0.3), 1.0, 0.45, ref.TRI)], 0.5, 20.0, {}),
    "grating": ([ref.Scratch((-20, y), (20, y), 1.0, 0.12) for y in np.arange(-4.0, 4.01, 1.6)], 1.0, 35.0, {}),
    "ends_and_diffuse_base": ([ref.Scratch((-0.5, -0.3), (1.0, 0.6), 0.8, 0.2),
                               ref.Scratch((0.2, -1.0), (0.4, 3.0), 0.6, 0.25, ref.TRI)], 0.5, 50.0,
                              {"diffuse_reflectance": 0.3, "material": "Cu"}),
    # a run of tracks summed in closed form (periodic family, docs/model.md §3.5): V-grooves, σ >= pitch
    "periodic_grating": ([ref.Scratch((-30, y), (30, y), 0.3, 0.15, ref.TRI) for y in np.arange(-9.0, 9.01, 0.45)],
                         0.5, 35.0, {"cell_size": 1.0 / 16.0}),
    # the same V-grooves turning by 8° on a line through the shading point (a CD's kink): two runs, each cut
    # by its half-plane; the point lies mid-cell (SHADING_UV), where its window stays inside one grid cell
    "kinked_grating": ([piece for y in KINK_UM + np.arange(-9.0, 9.01, 0.45) for piece in (
        ref.Scratch((KINK_UM - 30 * np.cos(0.07), y - 30 * np.sin(0.07)), (KINK_UM, y), 0.3, 0.15, ref.TRI),
        ref.Scratch((KINK_UM, y), (KINK_UM + 30 * np.cos(0.07), y - 30 * np.sin(0.07)), 0.3, 0.15, ref.TRI))],
                       0.5, 35.0, {"cell_size": 1.0 / 16.0}),
    "incoherent": ([ref.Scratch((-20, y), (20, y), 0.7, 0.2) for y in (-0.8, 0.5)], 0.5, 35.0, {"coherent": False}),
    # the incoherent mode's closed form at the same kink (flat bottoms; docs/model.md §3.5)
    "incoherent_kinked_grating": ([piece for y in KINK_UM + np.arange(-9.0, 9.01, 0.45) for piece in (
        ref.Scratch((KINK_UM - 30 * np.cos(0.07), y - 30 * np.sin(0.07)), (KINK_UM, y), 0.3, 0.15),
        ref.Scratch((KINK_UM, y), (KINK_UM + 30 * np.cos(0.07), y - 30 * np.sin(0.07)), 0.3, 0.15))],
                                  0.5, 35.0, {"cell_size": 1.0 / 16.0, "coherent": False}),
    # the normalisation of depth_phase="bounded" is at work (Kirchhoff albedo > 1 at 40°)
    "deep_bounded": ([ref.Scratch((-20, 0.2), (20, 0.2), 1.0, 1.0)], 0.5, 40.0, {"depth_phase": "bounded"}),
}


#: Where a config's shading point lies, if not at x0 (UV; the test surface has 1 mm per UV unit).
SHADING_UV = {name: (shading.X0_UV[0] + KINK_UM * 1e-3, shading.X0_UV[1] + KINK_UM * 1e-3)
              for name in ("kinked_grating", "incoherent_kinked_grating")}


def make(name):
    scratches, sigma, theta, extra = CONFIGS[name]
    return shading.load_bsdf(scratches or None, sigma_um=sigma, **extra), shading.direction(theta, 25.0)


@pytest.mark.parametrize("name", list(CONFIGS))
def test01_chi2_sample_matches_pdf(name):
    bsdf, wi = make(name)
    ctx = mi.BSDFContext()

    def sample_func(sample):
        si = shading.uniform_interaction(dr.width(sample), wi, WAVELENGTHS, uv=SHADING_UV.get(name, shading.X0_UV))
        bs, weight = bsdf.sample(ctx, si, sample[0], mi.Point2f(sample[1], sample[2]))
        # A sample counts where it has a density, not where its weight is non-zero: far out on a
        # scratch line without ends in the window, f_r underflows float32 (e^{-2π²σ²ν∥²}) while the
        # Cauchy part of the sampler still reaches it; dropping those samples would punch holes in
        # the histogram that the pdf does not have.
        return bs.wo, dr.select(bs.pdf > 0, 1.0, 0.0)

    def pdf_func(wo):
        si = shading.uniform_interaction(dr.width(wo), wi, WAVELENGTHS, uv=SHADING_UV.get(name, shading.X0_UV))
        return bsdf.pdf(ctx, si, wo)

    test = mi.chi2.ChiSquareTest(domain=mi.chi2.SphericalDomain(), sample_func=sample_func, pdf_func=pdf_func,
                                 sample_dim=3, sample_count=1_000_000, res=101, ires=4, seed=3)
    assert test.run(0.01, test_count=len(CONFIGS), quiet=True), test.messages


@pytest.mark.parametrize("name", list(CONFIGS))
def test02_weight_is_eval_over_pdf_and_pdfs_agree(name):
    bsdf, wi = make(name)
    ctx = mi.BSDFContext()
    count = 20000
    rng = np.random.default_rng(2)
    si = shading.interaction(count, wi, WAVELENGTHS, uv=SHADING_UV.get(name, shading.X0_UV))
    u = shading.floats(rng.random(count))
    bs, weight = bsdf.sample(ctx, si, u, mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    only_value, only_pdf = bsdf.eval(ctx, si, bs.wo), bsdf.pdf(ctx, si, bs.wo)
    weight, value, pdf, bs_pdf = (np.asarray(x, dtype=np.float64) for x in (weight, value, pdf, bs.pdf))
    valid = bs_pdf > 0
    assert valid.mean() > 0.5
    assert np.all(weight[:, ~valid] == 0)
    np.testing.assert_allclose(bs_pdf[valid], pdf[valid], rtol=1e-4)
    np.testing.assert_allclose(weight[:, valid], value[:, valid] / pdf[valid], rtol=1e-4, atol=1e-7)
    np.testing.assert_array_equal(np.asarray(only_value), value.astype(np.float32))
    np.testing.assert_array_equal(np.asarray(only_pdf), pdf.astype(np.float32))
    wo_z = np.asarray(bs.wo)[2]
    assert np.all(wo_z[valid] > 0)
    diffuse = (np.asarray(bs.sampled_type) & int(mi.BSDFFlags.DiffuseReflection)) != 0
    assert diffuse.any() == ("diffuse_reflectance" in CONFIGS[name][3])


def test03_estimated_albedo_of_a_flat_mirror_is_one():
    """Mean sample weight is the directional albedo (1 for a perfect mirror, exact sampling)."""
    bsdf = shading.load_bsdf(None, sigma_um=5.0)
    count = 50000
    rng = np.random.default_rng(8)
    for theta in (0.0, 30.0, 60.0):
        si = shading.interaction(count, shading.direction(theta), WAVELENGTHS)
        _, weight = bsdf.sample(mi.BSDFContext(), si, shading.floats(rng.random(count)),
                                mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
        w = np.asarray(weight)
        assert w[0].mean() == pytest.approx(1.0, abs=0.01)  # hero wavelength: weight exactly 1
        assert np.all(np.abs(w.mean(axis=1) - 1.0) < 0.05)  # other wavelengths: f(λ_j)/p(λ_0), unbiased


def test04_sample_skips_the_second_search_only_where_the_window_is_empty():
    """``sample`` evaluates its direction without searching again where its first pass found no piece:
    with shading points of which about half see pieces, its weight and pdf still equal eval / pdf."""
    scratches = [ref.Scratch((-20, 0.4), (20, 0.4), 1.0, 0.3), ref.Scratch((0.3, -20), (0.6, 20), 0.8, 0.25, ref.TRI)]
    bsdf = shading.load_bsdf(scratches, sigma_um=0.5)
    mirror = shading.load_bsdf(None, sigma_um=0.5)
    ctx = mi.BSDFContext()
    count = 20000
    rng = np.random.default_rng(4)
    # x0 up to 8 µm away from the crossing: the window (radius 4σ = 2 µm) holds 0, 1 or 2 pieces
    uv = shading.to_uv(rng.uniform(-8.0, 8.0, (count, 2)))
    si = shading.interaction(count, shading.direction(35.0, 25.0), WAVELENGTHS, uv=(uv[:, 0], uv[:, 1]))
    u = shading.floats(rng.random(count))
    u2 = mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count)))
    bs, weight = bsdf.sample(ctx, si, u, u2)
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    bare = np.asarray(mirror.eval(ctx, si, bs.wo), dtype=np.float64)
    weight, value, pdf, bs_pdf = (np.asarray(x, dtype=np.float64) for x in (weight, value, pdf, bs.pdf))
    valid = bs_pdf > 0
    scratched = np.any(value != bare, axis=0)
    assert 0.2 < scratched.mean() < 0.8  # both kinds of lanes
    np.testing.assert_allclose(bs_pdf[valid], pdf[valid], rtol=1e-4)
    np.testing.assert_allclose(weight[:, valid], value[:, valid] / pdf[valid], rtol=1e-4, atol=1e-7)


def test05_sample_replays_the_pieces_of_its_first_pass_bit_for_bit():
    """``sample`` keeps the first ``REPLAY_PIECES`` pieces its first pass finds and evaluates its direction
    by replaying them in that order: value and pdf equal a fresh evaluation's exactly, on lanes whose
    windows hold from 0 to 7 pieces (more than it keeps: those search again)."""
    from scratch_iridescence.mitsuba_bridge.bsdf.model import REPLAY_PIECES

    # a fan of 7 scratches through the origin: the window (2 µm) holds all 7 near it, fewer farther out
    scratches = [ref.Scratch((-20 * np.cos(t), -20 * np.sin(t)), (20 * np.cos(t), 20 * np.sin(t)), 0.3, 0.2,
                             ref.TRI if k % 2 else ref.RECT)
                 for k, t in enumerate(np.linspace(0.1, 3.0, 7))]
    model = shading.load_bsdf(scratches, sigma_um=0.5).model
    count = 20000
    rng = np.random.default_rng(11)
    uv = shading.to_uv(rng.uniform(-15.0, 15.0, (count, 2)))
    si = shading.interaction(count, shading.direction(35.0, 25.0), WAVELENGTHS, uv=(uv[:, 0], uv[:, 1]))
    wo, pdf, value, _ = model.sample(si, shading.floats(rng.random(count)),
                                     mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
    fresh_value, fresh_pdf = model.evaluate(si, wo)
    np.testing.assert_array_equal(np.asarray(value), np.asarray(fresh_value))
    np.testing.assert_array_equal(np.asarray(pdf), np.asarray(fresh_pdf))
    # lanes of every kind: no piece, some replayed, more than kept (searched again)
    from scratch_iridescence.mitsuba_bridge.bsdf.lookup import for_each_segment, jacobian
    pieces = np.asarray(for_each_segment(model.grid, jacobian(si, model.micrometres_per_unit), 4 * model.sigma,
                                         (dr.zeros(mi.UInt32, count),), lambda s, p, state: (state[0] + 1,),
                                         mi.Bool(True))[0])
    assert (pieces == 0).any() and ((pieces > 0) & (pieces <= REPLAY_PIECES)).any() and (pieces > REPLAY_PIECES).any()
