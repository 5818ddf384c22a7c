"""The footprint's reach capped where pieces are dense (``filtered/reach.py``, docs/model.md §11.8).

A dense random set (2 000 grooves 6–20 µm long, spread over a 360 µm square: one every 8 µm on
average, so that a coherence window (σ = 2 µm) holds a few and a footprint of 30σ several thousand)
against the sparse cases of ``test_filtered_bsdf.py``:

* the pieces one evaluation visits (the search's own count, ``keep_search``) stay near the budget
  where the uncapped search visits thousands;
* the sparse cases' footprints are not touched (bit for bit), so every earlier test still tests the
  same footprint;
* the capped evaluation is still the point BRDF averaged over the (capped) footprint, as
  ``test_filtered_bsdf.test01`` checks for the uncapped one, and a zero footprint the point plugin's.
"""
from __future__ import annotations

import dataclasses

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf.filtered.footprint import footprint_of
from scratch_iridescence.mitsuba_bridge.bsdf.filtered.model import MAX_RADIUS_SIGMAS, REACH_STDS
from scratch_iridescence.mitsuba_bridge.bsdf.filtered.reach import MAX_EXPECTED_PIECES, expected_pieces
from scratch_iridescence.mitsuba_bridge.bsdf.lookup import jacobian
from scratch_iridescence.mitsuba_bridge.validation import reference as ref
import shading
from test_filtered_bsdf import CASES, CTX, SIGMA_UM, WAVELENGTHS, eval_at, filtered_bsdf, footprint_average

HALF_SIDE_UM = 180.0


def dense_set(count=2000, seed=4):
    """``count`` grooves of random direction, 6–20 µm long, 0.5–1.5 µm wide, centres uniform in the square."""
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-HALF_SIDE_UM, HALF_SIDE_UM, (count, 2))
    angle = rng.uniform(0.0, np.pi, count)
    half = 0.5 * rng.uniform(6.0, 20.0, count)[:, None] * np.stack([np.cos(angle), np.sin(angle)], -1)
    return [ref.Scratch(tuple(c - h), tuple(c + h), float(w), 0.2, int(p))
            for c, h, w, p in zip(centre, half, rng.uniform(0.5, 1.5, count), rng.integers(0, 2, count))]


@pytest.fixture(scope="module")
def dense():
    return filtered_bsdf(dense_set(), MAX_RADIUS_SIGMAS * SIGMA_UM)


def visited(model, si, wo):
    """Pieces each lane's filtered evaluation visits (numpy)."""
    _, _, (_, count, _) = model.evaluate(si, wo, keep_search=True)
    return np.asarray(count)


def lanes(count, seed, spread_um=HALF_SIDE_UM - 40.0, incidence=35.0):
    """``(si, wo)``: ``count`` shading points uniform inside the dense square, seen at ``incidence``."""
    rng = np.random.default_rng(seed)
    uv = shading.to_uv(rng.uniform(-spread_um, spread_um, (count, 2)))
    wi = shading.direction(incidence, 25.0)
    si = shading.interaction(count, wi, WAVELENGTHS, uv=(uv[:, 0], uv[:, 1]))
    return si, shading.vector(np.tile([-wi[0], -wi[1], wi[2]], (count, 1)))


def first(si, count):
    """The first ``count`` lanes of ``si``."""
    return dr.gather(type(si), si, dr.arange(mi.UInt32, count))


def test01_a_dense_set_visits_about_the_budget_where_the_uncapped_search_visits_thousands(dense):
    """The capped search's count per lane: mean at most the budget, none above twice it (the expectation is a
    density model, E(R) of the module docs, not a hard bound); the uncapped search, the same lanes: > 10× it."""
    si, wo = lanes(512, seed=1)
    capped = visited(dense.model, si, wo)
    uncapped = visited(dataclasses.replace(dense.model, piece_density=None), first(si, 32), first(wo, 32))
    assert capped.mean() <= MAX_EXPECTED_PIECES, capped.mean()
    assert capped.max() <= 2 * MAX_EXPECTED_PIECES, capped.max()
    assert np.median(uncapped) > 10 * MAX_EXPECTED_PIECES, np.median(uncapped)
    # the cap shrinks a footprint only as far as needed: about the budget is still visited
    assert capped.mean() >= 0.25 * MAX_EXPECTED_PIECES, capped.mean()


def test02_the_expected_count_follows_the_visited_one(dense):
    """E(R) of the densities against the pieces a search of reach R visits, R from 10 to 200 µm: within a factor
    of 2.5 on average (the model counts a box's lines, not an ellipse's, and each piece's cells with their margin)."""
    si, wo = lanes(128, seed=2, incidence=0.0)
    model = dataclasses.replace(dense.model, piece_density=None)
    jac = jacobian(si, model.micrometres_per_unit)
    for reach in (10.0, 20.0, 60.0, 200.0):
        # a footprint whose reach (REACH_STDS √(λ + σ²), at normal incidence λ = r²) is `reach`
        radius = float(np.sqrt(max((reach / REACH_STDS) ** 2 - SIGMA_UM ** 2, 0.0)))
        found = visited(dataclasses.replace(model, footprint_width=mi.Float(radius * 1e-3)), si, wo)
        expected = np.asarray(expected_pieces(model.grid, dense.model.piece_density, jac, mi.Float(reach)))
        ratio = expected.mean() / max(found.mean(), 1.0)
        assert 1.0 / 2.5 <= ratio <= 2.5, (reach, expected.mean(), found.mean())


@pytest.mark.parametrize("name", list(CASES))
def test03_sparse_footprints_are_not_capped(name):
    """The sparse cases of test_filtered_bsdf, radius 30σ: the footprint is footprint_of's, bit for bit."""
    bsdf = filtered_bsdf(CASES[name], 30.0 * SIGMA_UM)
    si, _ = lanes(64, seed=3, spread_um=20.0, incidence=50.0)
    model = bsdf.model
    capped = model.footprint(si)
    plain = footprint_of(si, model.footprint_angle, model.footprint_width, model.micrometres_per_unit,
                         MAX_RADIUS_SIGMAS * model.sigma)
    for a, b in zip(capped, plain):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test04_the_capped_brdf_is_the_point_brdf_averaged_over_the_capped_footprint():
    """At x0 in the dense set, 32σ asked: the filtered f_r (scratches' part) within 2 % of the point plugin's
    average over the footprint the cap left (grid quadrature, as test_filtered_bsdf.test01).  Incoherent
    superposition: what is checked is the footprint the cap hands on (the sum of the pieces' own terms over
    it); the coherent pair terms are test_filtered_bsdf's and test_kernels' (on this set of short grooves
    crossing and ending inside each other's windows they miss 15 % of it, with or without the cap)."""
    scratches = dense_set()
    bsdf = filtered_bsdf(scratches, MAX_RADIUS_SIGMAS * SIGMA_UM, coherent=False)
    wi = shading.direction(20.0, 25.0)
    rng = np.random.default_rng(6)
    theta, phi = np.radians(rng.uniform(5.0, 60.0, 48)), rng.uniform(0.0, 2 * np.pi, 48)
    wo = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
    footprint = bsdf.model.footprint(shading.interaction(1, wi, WAVELENGTHS))
    cov = np.array([[footprint.xx[0], footprint.xy[0]], [footprint.xy[0], footprint.yy[0]]], dtype=np.float64)
    radius = float(np.sqrt(np.linalg.eigvalsh(cov)[0]))
    assert 1.0 * SIGMA_UM < radius < 0.5 * MAX_RADIUS_SIGMAS * SIGMA_UM, radius  # capped, not to a point
    mirror = eval_at(shading.load_bsdf(None, sigma_um=SIGMA_UM, coherent=False), wi, wo)
    expected = footprint_average(shading.load_bsdf(scratches, sigma_um=SIGMA_UM, coherent=False), wi, wo, cov) \
        - mirror
    got = eval_at(bsdf, wi, wo) - mirror
    error = np.sqrt(np.mean((got - expected) ** 2) / np.mean(expected ** 2))
    assert error <= 0.02, error


def test05_a_zero_footprint_in_a_dense_set_is_the_point_plugin_bit_for_bit():
    scratches = dense_set()
    point, filtered = shading.load_bsdf(scratches, sigma_um=SIGMA_UM), filtered_bsdf(scratches, 0.0)
    si, wo = lanes(1024, seed=7)
    np.testing.assert_array_equal(np.asarray(point.eval(CTX, si, wo)), np.asarray(filtered.eval(CTX, si, wo)))
    np.testing.assert_array_equal(np.asarray(point.pdf(CTX, si, wo)), np.asarray(filtered.pdf(CTX, si, wo)))


def test06_a_lane_whose_footprint_would_lose_its_periodic_familys_closed_form_takes_the_point_model():
    """test_periodic's grating (81 tracks 1.2 µm apart) on cells of 1/4 UV, lanes across it: where the point
    window lies in the family but the footprint's reach does not (a band's edge inside it), the footprint is
    zero and f_r the point plugin's bit for bit; everywhere else a lane in the family keeps its closed form."""
    from scratch_iridescence.mitsuba_bridge.bsdf.periodic import find_family
    import test_periodic

    scratches = test_periodic.grating()
    options = dict(sigma_um=test_periodic.SIGMA, cell_size=0.25)
    filtered = shading.load_bsdf(scratches, footprint_filter=True, footprint_angle=0.0, footprint_width=6e-3,
                                 **options)
    point = shading.load_bsdf(scratches, **options)
    y = np.linspace(-60.0, 60.0, 161)
    uv = shading.to_uv(np.stack([np.zeros_like(y), y], -1))
    wi = shading.direction(30.0, 25.0)
    si = shading.interaction(len(y), wi, WAVELENGTHS, uv=(uv[:, 0], uv[:, 1]))
    model = filtered.model
    jac = jacobian(si, model.micrometres_per_unit)
    footprint = model.footprint(si)
    in_window = np.asarray(find_family(model.grid, jac, model.sigma, mi.Bool(True)).eligible)
    in_reach = np.asarray(model._footprint_family(jac, footprint, model._reach(footprint), mi.Bool(True)).eligible)
    zero = np.asarray(footprint.largest_variance) == 0.0
    assert np.all(~in_window | in_reach | zero)
    snapped = in_window & zero
    assert 0 < snapped.sum() < in_window.sum()
    wo = shading.vector(np.tile([-wi[0], -wi[1], wi[2]], (len(y), 1)))
    values = (np.asarray(b.eval(CTX, si, wo))[:, snapped] for b in (point, filtered))
    np.testing.assert_array_equal(*values)
