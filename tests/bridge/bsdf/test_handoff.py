"""The window search that ``eval_pdf`` hands on to the ``sample`` call after it (bsdf/handoff.py).

Taken, it must change nothing but the time: the same samples, weights and pdfs bit for bit, in
traced calls and inside Mitsuba's path tracer; it must be refused whenever the two calls do not
search the very same window, and evaluated calls keep nothing.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf import handoff
from scratch_iridescence.mitsuba_bridge.validation import reference as ref
import shading
from test_render import small_scene

WAVELENGTHS = (520.0, 410.0, 680.0, 600.0)
COUNT = 20000


def fan_bsdf(**settings):
    """Seven scratches through one point: windows near it hold all seven, farther out fewer, far out none."""
    scratches = [ref.Scratch((-20 * np.cos(t), -20 * np.sin(t)), (20 * np.cos(t), 20 * np.sin(t)), 0.3, 0.2,
                             ref.TRI if k % 2 else ref.RECT)
                 for k, t in enumerate(np.linspace(0.1, 3.0, 7))]
    return shading.load_bsdf(scratches, sigma_um=0.5, **settings)


def grating_bsdf():
    """V-grooves at a 0.45 µm pitch: the windows lie in a periodic family (its closed form, no search)."""
    scratches = [ref.Scratch((-30, y), (30, y), 0.3, 0.15, ref.TRI) for y in np.arange(-9.0, 9.01, 0.45)]
    return shading.load_bsdf(scratches, sigma_um=0.5, cell_size=1.0 / 16.0)


def lanes(seed):
    """Shading points up to 15 µm from the fan's centre, a light direction (a third of them below the
    surface: the search must not depend on it) and the sampler's numbers."""
    rng = np.random.default_rng(seed)
    uv = shading.to_uv(rng.uniform(-15.0, 15.0, (COUNT, 2)))
    si = shading.interaction(COUNT, shading.direction(35.0, 25.0), WAVELENGTHS, uv=(uv[:, 0], uv[:, 1]))
    theta = np.radians(rng.uniform(0.0, 130.0, COUNT))
    phi = rng.uniform(0.0, 2.0 * np.pi, COUNT)
    light = mi.Vector3f(*(shading.floats(x) for x in (np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                                                       np.cos(theta))))
    u = shading.floats(rng.random(COUNT))
    u2 = mi.Point2f(shading.floats(rng.random(COUNT)), shading.floats(rng.random(COUNT)))
    return si, light, u, u2


def arrays(*values):
    return [np.asarray(v) for v in values]


SAMPLE_TYPES = (mi.Vector3f, mi.Float, mi.UInt32, mi.Spectrum)
EVAL_TYPES = (mi.Spectrum, mi.Float)


def traced(function, si, types):
    """``function()``'s arrays, traced as a render traces the BSDF: in a symbolic region (a branch that
    every lane takes), where ``eval_pdf`` leaves its search; evaluated calls keep none."""
    every = dr.isfinite(si.uv.x)
    result = dr.if_stmt((), every, lambda: tuple(t(x) for t, x in zip(types, function())),
                        lambda: tuple(dr.zeros(t, dr.width(si.uv)) for t in types), mode="symbolic",
                        label="test_handoff")
    return arrays(*result)


def sampled(bsdf, ctx, si, u, u2):
    bs, weight = bsdf.sample(ctx, si, u, u2)
    return bs.wo, bs.pdf, bs.sampled_type, weight


# (the height field's case compiles its own kernels, ~45 s on a cold cache on a 2-core Intel Xeon: under the
# slow marker, which CI runs too)
@pytest.mark.parametrize("make", [fan_bsdf, lambda: fan_bsdf(coherent=False), grating_bsdf,
                                  pytest.param(lambda: fan_bsdf(crossings="height_field"), marks=pytest.mark.slow)],
                         ids=["coherent", "incoherent", "periodic", "height_field"])
def test01_sample_after_eval_pdf_takes_its_search_and_draws_the_same_bits(make):
    bsdf = make()
    ctx = mi.BSDFContext()
    si, light, u, u2 = lanes(3)
    handoff.clear()
    fresh = traced(lambda: sampled(bsdf, ctx, si, u, u2), si, SAMPLE_TYPES)  # nothing left: it searches
    plain = traced(lambda: bsdf.model.evaluate(si, light), si, EVAL_TYPES)

    before = handoff.statistics()
    both = traced(lambda: bsdf.eval_pdf(ctx, si, light) + sampled(bsdf, ctx, si, u, u2), si,
                  EVAL_TYPES + SAMPLE_TYPES)
    after = handoff.statistics()
    assert after["taken"] == before["taken"] + 1 and after["refused"] == before["refused"]
    for mine, theirs in zip(both[2:], fresh):
        np.testing.assert_array_equal(mine, theirs)
    # eval_pdf itself: what it always returned, though it searched below-horizon lights' windows too
    for mine, theirs in zip(both[:2], plain):
        np.testing.assert_array_equal(mine, theirs)
    assert fresh[1].max() > 0


def test02_the_fan_has_windows_of_every_kind():
    """test01's lanes hold no piece, a few (replayed from the search) and more than are kept (searched again)."""
    from scratch_iridescence.mitsuba_bridge.bsdf.lookup import for_each_segment, jacobian
    from scratch_iridescence.mitsuba_bridge.bsdf.model import REPLAY_PIECES

    model = fan_bsdf().model
    si = lanes(3)[0]
    pieces = np.asarray(for_each_segment(model.grid, jacobian(si, model.micrometres_per_unit), 4 * model.sigma,
                                         (dr.zeros(mi.UInt32, COUNT),), lambda s, p, state: (state[0] + 1,),
                                         mi.Bool(True))[0])
    assert (pieces == 0).any() and ((pieces > 0) & (pieces <= REPLAY_PIECES)).any() and (pieces > REPLAY_PIECES).any()


def test03_another_point_mask_or_lobe_searches_again():
    bsdf = fan_bsdf(diffuse_reflectance=0.2)
    ctx = mi.BSDFContext()
    si, light, u, u2 = lanes(5)
    handoff.clear()
    fresh = traced(lambda: sampled(bsdf, ctx, si, u, u2), si, SAMPLE_TYPES)

    other = lanes(5)[0]  # the same point in new variables
    diffuse_only = mi.BSDFContext()
    diffuse_only.component = 1
    half = mi.Bool(np.arange(COUNT) % 2 == 0)

    for eval_args in [(ctx, other, light),  # another point (new variables)
                      (ctx, si, light, half),  # another mask
                      (diffuse_only, si, light)]:  # other lobes
        before = handoff.statistics()
        result = traced(lambda: bsdf.eval_pdf(*eval_args) + sampled(bsdf, ctx, si, u, u2), si,
                        EVAL_TYPES + SAMPLE_TYPES)
        after = handoff.statistics()
        assert after["refused"] == before["refused"] + 1 and after["taken"] == before["taken"]
        for mine, theirs in zip(result[2:], fresh):
            np.testing.assert_array_equal(mine, theirs)
    # a sample without an eval_pdf before it finds the slot empty (the last sample emptied it)
    before = handoff.statistics()
    traced(lambda: sampled(bsdf, ctx, si, u, u2), si, SAMPLE_TYPES)
    assert handoff.statistics() == before


def test05_evaluated_calls_leave_nothing():
    """Outside a traced region ``eval_pdf`` keeps no search (it would hold arrays of every lane)."""
    bsdf = fan_bsdf()
    ctx = mi.BSDFContext()
    si, light, u, u2 = lanes(7)
    before = handoff.statistics()
    bsdf.eval_pdf(ctx, si, light)
    bsdf.sample(ctx, si, u, u2)
    assert handoff.statistics() == before


@pytest.mark.parametrize("settings", [{}, {"coherent": False}], ids=["coherent", "incoherent"])
def test04_the_path_tracer_hands_searches_on_and_renders_the_same_bits(settings, monkeypatch):
    """Mitsuba's ``path`` calls eval_pdf towards the light, then sample, at every vertex: the render
    takes the searches, and its image equals, bit for bit, one whose samples all search again."""
    scene = small_scene(settings, 24)

    before = handoff.statistics()
    handed = np.asarray(mi.render(scene, spp=8, seed=2))
    assert handoff.statistics()["taken"] > before["taken"]
    monkeypatch.setattr(handoff, "take", lambda *arguments: None)
    searched = np.asarray(mi.render(scene, spp=8, seed=2))
    assert handed.tobytes() == searched.tobytes() and np.abs(handed).max() > 0
