"""``crossings = "height_field"``: crossing pairs and the parallelogram correction (docs/model.md §3.4).

Against the brute-force height field of one global raster (the deeper scratch
owns a crossing): pairs of crossing scratches are exact to the raster's
precision; with triple and higher overlaps the pair terms alone are exact to
the pairwise inclusion–exclusion of the same raster, and the terms of order
3–5 (triples.py, polygon.py) bring the dense sets to the height field.
"""
from __future__ import annotations

import dataclasses

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf.maths import polygon
from scratch_iridescence.mitsuba_bridge.bsdf.tables import crossings, grid as tables
from scratch_iridescence.mitsuba_bridge.validation import probe
from scratch_iridescence.mitsuba_bridge.validation import reference as ref
from scratch_iridescence.mitsuba_bridge.scratch import Profile, ScratchSet
import crossing_sets as cs
import shading

TOLERANCE = 0.05
WAVELENGTHS_NM = (450.0, 550.0, 650.0)
INCIDENCES_DEG = (0.0, 40.0, 70.0)


def pairs_of(scratches, **kwargs):
    t = tables.build_tables(probe.scratch_set(scratches) if isinstance(scratches, list) else scratches,
                            crossings=True, **kwargs)
    partner = t.crossing_partner[:t.crossing_count]
    owner = np.repeat(np.arange(t.piece_count), np.diff(t.crossing_start.astype(np.int64)))
    return t, list(zip(owner.tolist(), partner.tolist()))


# ------------------------------------------------------------------ tables
def test01_a_crossing_is_listed_once_under_its_lower_piece():
    t, pairs = pairs_of([ref.Scratch((-30, 0.5), (30, 0.5), 1.0, 0.25), ref.Scratch((-1, -30), (3, 30), 1.5, 0.4)])
    assert t.piece_count > 2  # the scratches are cut at 1/64 UV: the crossing lies on one piece of each
    assert len(pairs) == 1 and pairs[0][0] < pairs[0][1]
    a = t.segments[:, 0:2].astype(np.float64) + t.segments[:, 2:4]
    for piece in pairs[0]:  # both listed pieces hold the crossing point near x0 = UV (0.5, 0.5)
        e = t.segments[piece, 4:6].astype(np.float64)
        s = np.clip(np.dot(np.asarray(probe.X0_UV) - a[piece], e) / np.dot(e, e), 0, 1)
        assert np.hypot(*(a[piece] + s * e - probe.X0_UV)) < 5e-3  # within 5 µm


def test02_polyline_vertices_and_parallel_tracks_give_no_pair():
    # a polyline crossing a straight scratch exactly at its vertex: one pair, not two
    kinked = ScratchSet.from_polylines([probe.to_uv([(-20, -20), (0, 0), (20, -20)]), probe.to_uv([(0, -20), (0, 20)])],
                                       width=[1e-6, 1e-6], depth=[2e-7, 3e-7])
    assert len(pairs_of(kinked)[1]) == 1
    # the kink of one polyline alone is no crossing
    assert pairs_of(ScratchSet.from_polylines([probe.to_uv([(-20, -20), (0, 0), (20, -20)])], width=[1e-6],
                                              depth=[2e-7]))[1] == []
    # a grating: cells of parallel pieces are skipped, and nothing crosses
    grating = [ref.Scratch((-30, y), (30, y), 1.0, 0.12) for y in np.arange(-12, 12.01, 1.6)]
    assert pairs_of(grating)[1] == []
    # nearly parallel pieces (|sin θ| < MIN_SINE) keep the additive model; V-grooves cross like the others
    sliver = [ref.Scratch((-30, 0), (30, 0), 1.0, 0.2), ref.Scratch((-30, -0.1), (30, 0.1), 1.0, 0.3)]
    assert abs(np.sin(np.arctan2(0.2, 60))) < crossings.MIN_SINE and pairs_of(sliver)[1] == []
    v_groove = [ref.Scratch((-30, 0.3), (30, 0.3), 1.0, 0.2, ref.TRI), ref.Scratch((0.3, -30), (0.3, 30), 1.0, 0.3)]
    assert len(pairs_of(v_groove)[1]) == 1
    # the additive model builds no list
    assert tables.build_tables(probe.scratch_set(sliver[:1] + v_groove[1:])).crossing_count == 0


def test02c_the_grid_search_finds_every_crossing_pair_of_all_pieces_and_no_other():
    """The candidates come from the lookup grid's cells (each cell's pairs once); against testing every
    pair of pieces (crossing inside both, |sin θ| ≥ MIN_SINE, not neighbours on a polyline)."""
    rng = np.random.default_rng(12)
    points = rng.uniform(0.3, 0.7, (40, 3, 2))  # polylines of two pieces, cut further at 1/64 UV
    scratches = ScratchSet.from_polylines(list(points), width=np.full(40, 1e-6), depth=np.full(40, 2e-7))
    t, a, b = tables.build_sorted(scratches, 0.0, True)
    listed = {tuple(pair) for pair in crossings.pairs_of(t.crossing_start, t.crossing_partner)}
    e = b - a
    expected = set()
    for i in range(len(a)):
        for j in range(i + 1, len(a)):
            cross = e[i, 0] * e[j, 1] - e[i, 1] * e[j, 0]
            if abs(cross) < crossings.MIN_SINE * np.hypot(*e[i]) * np.hypot(*e[j]):
                continue
            gap = a[j] - a[i]
            s_i, s_j = (gap[0] * e[j, 1] - gap[1] * e[j, 0]) / cross, (gap[0] * e[i, 1] - gap[1] * e[i, 0]) / cross
            ends = min(s_i, 1 - s_i) < 1e-9 and min(s_j, 1 - s_j) < 1e-9
            if 0 <= s_i < 1 and 0 <= s_j < 1 and not ends:
                expected.add((i, j))
    assert len(expected) > 200 and listed == expected


def test02b_a_set_crossing_itself_too_often_is_refused_with_one_clear_error(monkeypatch):
    """Beyond crossings.MAX_PAIRS (lowered here from 5e7 to 3) the build stops with TooManyCrossings instead of
    exhausting the memory; through the plugin the message reaches the user."""
    grid = [ref.Scratch((-30, y), (30, y), 1.0, 0.2) for y in (-2.1, 0.3, 2.2)] + \
        [ref.Scratch((x, -30), (x, 30), 1.0, 0.3) for x in (-1.9, 0.2, 2.3)]
    assert len(pairs_of(grid)[1]) == 9
    monkeypatch.setattr(crossings, "MAX_PAIRS", 3)
    with pytest.raises(crossings.TooManyCrossings, match="cross each other more than 3 times"):
        pairs_of(grid)
    with pytest.raises(Exception, match="cross each other more than 3 times.*crossings = 'additive'"):
        probe.load_bsdf(grid, crossings="height_field")
    assert "additive" in str(probe.load_bsdf(grid))  # the additive model lists nothing


def test03_the_options_are_checked():
    with pytest.raises(Exception, match="crossings"):
        probe.load_bsdf([], crossings="deepest")
    assert "crossings=height_field (1 pairs)" in str(probe.load_bsdf(
        [ref.Scratch((-30, 0.5), (30, 0.5), 1.0, 0.25), ref.Scratch((-1, -30), (3, 30), 1.5, 0.4)],
        crossings="height_field"))


# ------------------------------------------------------- against the raster
def errors(scratches, sigma, pitch, combos, samples=81):
    """{(λ, θ): (additive vs truth, height field vs truth, pair terms alone vs the pairwise raster,
    pair terms alone vs truth)}: the last two measure the correction before its overlaps of three and more."""
    raster = cs.Raster(scratches, sigma, pitch)
    additive = probe.load_bsdf(scratches, sigma_um=sigma)
    height_field = probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field")
    pairs_only = probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field")
    pairs_only.model = dataclasses.replace(pairs_only.model, triples=False)
    out = {}
    for wavelength_nm, theta in combos:
        wi, rows, true, _summed, pairwise = raster.planes(wavelength_nm, theta, samples, pairwise=True)
        a = cs.plugin_brdf(additive, wi, rows, wavelength_nm)
        h = cs.plugin_brdf(height_field, wi, rows, wavelength_nm)
        p = cs.plugin_brdf(pairs_only, wi, rows, wavelength_nm)
        out[(wavelength_nm, theta)] = (cs.relative_l2(a, true), cs.relative_l2(h, true), cs.relative_l2(p, pairwise),
                                       cs.relative_l2(p, true))
    return raster, out


TWO = [ref.Scratch((-30, 0.5), (30, 0.5), 1.0, 0.25), ref.Scratch((-1, -30), (3, 30), 1.5, 0.4)]


def test04_two_crossing_scratches_match_the_height_field():
    raster, out = errors(TWO, 2.0, 0.02, [(550.0, 40.0)])
    additive, height_field = out[(550.0, 40.0)][:2]
    assert raster.share > 0.1 and raster.triple_share == 0.0
    assert additive > 0.3  # the paper's model counts the crossing twice
    assert height_field < 0.01


# (a set of both profiles: its kernels take ~30 s to compile on a cold cache; under the slow marker)
@pytest.mark.slow
def test05_reciprocal_and_invariant_under_the_uv_map():
    scratches = TWO + [ref.Scratch((-20, -3), (20, 4), 0.8, 0.15), ref.Scratch((-3, -20), (1, 20), 1.2, 0.3, ref.TRI)]
    rng = np.random.default_rng(5)
    count = 4000
    wi, wo = shading.direction_pairs(rng, count)
    bsdf = shading.load_bsdf(scratches, sigma_um=2.0, material="Cu", crossings="height_field")
    forward, backward = shading.eval_brdf(bsdf, wi, wo), shading.eval_brdf(bsdf, wo, wi)
    np.testing.assert_allclose(forward, backward, rtol=2e-3, atol=1e-6 * forward.max())

    # the parallelogram is built in metres: a sheared UV map changes nothing
    wi1 = shading.direction(35, 20)
    wo1 = np.array([shading.direction(a, b) for a, b in [(10, 200), (50, 100), (5, 5), (30, 270)]])
    base = shading.eval_brdf(bsdf, wi1, wo1)
    jacobian = np.array([[1.7, 0.6], [0.2, 0.8]])
    sheared = shading.load_bsdf(shading.scratch_set(scratches, jacobian), sigma_um=2.0, material="Cu",
                                crossings="height_field")
    si = shading.interaction(len(wo1), wi1)
    si.dp_du = mi.Vector3f(float(jacobian[0, 0]), float(jacobian[1, 0]), 0)
    si.dp_dv = mi.Vector3f(float(jacobian[0, 1]), float(jacobian[1, 1]), 0)
    value = shading.spectrum_rows(sheared.eval(mi.BSDFContext(), si, shading.vector(wo1))) / wo1[:, 2:3]
    np.testing.assert_allclose(value, base, rtol=2e-3)


def test05b_sampling_weights_are_eval_over_pdf():
    """Sampling is the additive model's (the correction only changes eval): weights stay eval / pdf."""
    bsdf = shading.load_bsdf(TWO + [ref.Scratch((-20, -3), (20, 4), 0.8, 0.15)], sigma_um=2.0, material="Al",
                             crossings="height_field")
    count = 4096
    rng = np.random.default_rng(55)
    si = shading.interaction(count, shading.direction(35, 10))
    bs, weight = bsdf.sample(mi.BSDFContext(), si, shading.floats(rng.random(count)),
                             mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
    value, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, bs.wo)
    weight, value, pdf = (shading.spectrum_rows(x) for x in (weight, value, np.asarray(pdf)))
    valid = np.asarray(bs.pdf) > 0
    assert valid.mean() > 0.9
    np.testing.assert_allclose(np.asarray(bs.pdf)[valid], pdf[valid], rtol=1e-4)
    np.testing.assert_allclose(weight[valid], value[valid] / pdf[valid, None], rtol=1e-3,
                               atol=1e-6 * np.abs(weight).max())


def test06_another_crossing_count_reuses_the_compiled_kernels():
    """Crossing counts and lists are data: two sets evaluate through kernels of the same hashes."""
    wo = np.array([shading.direction(30, 40 + k) for k in range(64)])
    si, wo_vector = shading.interaction(len(wo), shading.direction(20)), shading.vector(wo)

    def kernels(scratches):
        bsdf = shading.load_bsdf(scratches, sigma_um=2.0, crossings="height_field")
        dr.eval(si, wo_vector)
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            dr.eval(bsdf.eval(mi.BSDFContext(), si, wo_vector))
            return sorted(k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT)

    first = kernels(TWO)
    assert first and kernels(cs.random_set(10, 2, 8.0, (0.5, 1.5))) == first


DIRECTION_20 = np.array([np.cos(np.radians(20.0)), np.sin(np.radians(20.0))])
#: (name, scratches, σ µm): pairs and sparse sets without triple overlaps, crossing shares 5–40 %
VALIDATED = [
    ("two, 15 %", cs.random_set(2, 1, 1.0, (1.0, 3.0)), 5.0),
    ("two at 20°, 42 %", [ref.Scratch((-60, 0.8), (60, -0.4), 4.0, 0.3),
                          ref.Scratch(tuple(-60 * DIRECTION_20 + (0.5, 0)), tuple(60 * DIRECTION_20 + (0.5, 0)), 3.0,
                                      0.45)], 5.0),
    ("ten, 4 %", cs.random_set(10, 4, 25.0, (0.5, 1.5)), 5.0),
    ("ten, 10 %", cs.random_set(10, 3, 25.0, (0.5, 1.5)), 5.0),
    ("ten, 12 %", cs.random_set(10, 4, 20.0, (1.0, 3.0)), 5.0),
]
ALL_COMBOS = [(lam, theta) for lam in WAVELENGTHS_NM for theta in INCIDENCES_DEG]


@pytest.mark.slow
@pytest.mark.parametrize("name, scratches, sigma", VALIDATED, ids=[v[0] for v in VALIDATED])
def test07_sets_without_triple_overlaps_match_the_height_field(name, scratches, sigma):
    raster, out = errors(scratches, sigma, 0.02, ALL_COMBOS)
    assert 0.03 < raster.share < 0.45 and raster.triple_share < 2e-3, (raster.share, raster.triple_share)
    worst = max(out, key=lambda k: out[k][1])
    assert out[worst][1] < TOLERANCE, (worst, out[worst])
    assert max(v[0] for v in out.values()) > 2 * TOLERANCE  # where the additive model fails


DENSE = [
    ("ten, 31 %", cs.random_set(10, 3, 15.0, (1.0, 3.0)), 5.0),
    ("fifty, 9 %", cs.random_set(50, 0, 25.0, (0.1, 0.3)), 5.0),
    ("fifty, 25 %", cs.random_set(50, 4, 25.0, (0.3, 0.8)), 5.0),
]


@pytest.mark.slow
@pytest.mark.parametrize("name, scratches, sigma", DENSE, ids=[v[0] for v in DENSE])
def test08_dense_sets_with_overlaps_of_up_to_five_match_the_height_field(name, scratches, sigma):
    """Triple overlaps (2-4 % of the scratched area, piles of up to five): the pair terms alone equal the
    pairwise inclusion-exclusion of the raster and miss the height field by more than 5 % on the crowded
    sets; with the terms of order 3-5 (docs/model.md §3.4) every combination is within 5 %."""
    raster, out = errors(scratches, sigma, 0.02, ALL_COMBOS)
    assert raster.triple_share > 2e-3
    worst = max(out, key=lambda k: out[k][1])
    assert out[worst][1] < TOLERANCE, (worst, out[worst])
    assert max(v[2] for v in out.values()) < TOLERANCE  # the pair terms: what they implement
    assert max(v[0] for v in out.values()) > 2 * TOLERANCE  # where the additive model fails


def test09_extreme_crossings_stay_finite():
    """Grazing and mirror directions, an 80 µm wide 30 µm deep groove, a 1e-4 µm thin one, a 1 nm piece."""
    scratches = TWO + [ref.Scratch((0, 0), (0.001, 0), 0.5, 0.2), ref.Scratch((-5, -5), (5, 5.0001), 80.0, 30.0),
                       ref.Scratch((-5, 5), (5, -5), 1e-4, 0.1)]
    bsdf = shading.load_bsdf(scratches, crossings="height_field", sigma_um=2.0)
    assert "(7 pairs)" in str(bsdf)
    rng = np.random.default_rng(9)
    wo = np.array([shading.direction(t, p) for t, p in zip(rng.uniform(0, 90, 2000), rng.uniform(0, 360, 2000))]
                  + [shading.direction(89.9, 180), shading.direction(0, 0)])
    for wi in (shading.direction(89.9), shading.direction(0), shading.direction(45, 30)):
        f = shading.eval_brdf(bsdf, wi, wo)
        assert np.isfinite(f).all() and f.max() > 0
    assert "crossings=height_field (0 pairs)" in str(shading.load_bsdf([], crossings="height_field"))


# ------------------------------------------------------ overlaps of three and more
def test10_clipped_cell_matches_a_quadrature_of_the_windowed_integral():
    """polygon.clipped_cell (divergence theorem, window expanded at the cell centre) against a numpy sum over
    a 4 nm grid of random three- and four-strip polygons, at frequencies from 0 (the series) to 3.6 µm⁻¹."""
    rng = np.random.default_rng(1)
    sigma, pitch = 5.0, 0.004
    x = np.arange(-3.0, 3.0, pitch) + 0.5 * pitch
    gx, gy = np.meshgrid(x, x)
    xi = np.array([[0.0, 0.0], [1e-3, 0.0], [0.05, 0.02], [0.3, -0.2], [1.5, 0.7], [3.0, -2.0]])
    for trial in range(6):
        angles = rng.uniform(0, np.pi, 3 + trial % 2)
        strips = [(-np.sin(a), np.cos(a), 0.0 if s < 2 else rng.uniform(-0.5, 0.5), rng.uniform(0.3, 1.2))
                  for s, a in enumerate(angles)]
        centre = rng.uniform(-12, 12, 2)
        inside = np.ones_like(gx, dtype=bool)
        for nx, ny, offset, half in strips:
            inside &= np.abs(nx * gx + ny * gy - offset) <= half
        px, py = gx[inside] + centre[0], gy[inside] + centre[1]
        w = np.exp(-(px * px + py * py) / (2 * sigma ** 2)) * pitch ** 2
        expected = np.array([np.sum(w * np.exp(-2j * np.pi * (k[0] * px + k[1] * py))) for k in xi])
        cell = polygon.clipped_cell([polygon.Strip(*(mi.Float(v) for v in s)) for s in strips],
                                    mi.Float(centre[0]), mi.Float(centre[1]), mi.Float(xi[:, 0]), mi.Float(xi[:, 1]),
                                    mi.Float(sigma))
        got = np.asarray(cell.re) + 1j * np.asarray(cell.im)
        # the window's curvature by its mean over the polygon: < 1 % of the largest value (docs/model.md §3.4)
        assert inside.sum() > 1000  # a polygon of at least 0.016 µm²
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-2 * np.abs(expected).max())


def star(count, shifts_um, length_um=60.0):
    """``count`` rectangular scratches through points within 0.4 µm of x0, 180°/count apart, each starting
    ``30 + shift`` µm before x0: cut into pieces of 15 µm, their piece ends move across the overlaps."""
    scratches = []
    for k in range(count):
        angle = np.radians(10.0 + 180.0 * k / count)
        d = np.array([np.cos(angle), np.sin(angle)])
        centre = 0.4 * np.array([np.cos(2.4 * k), np.sin(2.4 * k)])
        start = centre - (30.0 + shifts_um[k % len(shifts_um)]) * d
        scratches.append(ref.Scratch(tuple(start), tuple(start + length_um * d), 1.2 + 0.2 * k, 0.15 + 0.05 * k))
    return scratches


@pytest.mark.parametrize("count", [3, 5])
def test11_overlaps_of_three_to_five_scratches_match_the_height_field(count):
    """Stars of 3 and 5 scratches (the centre under all of them), piece ends inside the overlaps: each
    overlap counted once, within 1 % of the height field as a single crossing pair is (test04), where the
    pair terms alone leave > 5 % (measured 65-1 200 %)."""
    scratches = star(count, (-1.0, 0.0, 0.7))
    t = tables.build_tables(probe.scratch_set(scratches), crossings=True)
    a = t.segments[:, 0:2].astype(np.float64) + t.segments[:, 2:4]
    near_ends = np.hypot(*((a - probe.X0_UV) * 1e3).T) < 3.0  # piece starts within 3 µm of x0
    assert near_ends.sum() >= 2
    sigma = 2.0
    raster = cs.Raster(scratches, sigma, 0.02)
    height_field = probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field")
    pairs_only = probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field")
    pairs_only.model = dataclasses.replace(pairs_only.model, triples=False)
    for wavelength_nm, theta in [(450.0, 0.0), (650.0, 70.0)]:
        wi, rows, true, _summed = raster.planes(wavelength_nm, theta, 61)
        assert cs.relative_l2(cs.plugin_brdf(height_field, wi, rows, wavelength_nm), true) < 0.01
        assert cs.relative_l2(cs.plugin_brdf(pairs_only, wi, rows, wavelength_nm), true) > 0.05


# ------------------------------------------------------------- V-grooves
V_PAIRS = {  # crossing pairs with a V-groove: V × V, V over a shallower flat bottom, flat bottom over a V
    "V x V": [ref.Scratch((-30, 0.5), (30, 0.5), 1.5, 0.25, ref.TRI), ref.Scratch((-1, -30), (3, 30), 2.0, 0.4, ref.TRI)],
    "V x flat": [ref.Scratch((-30, 0.5), (30, 0.5), 1.5, 0.35, ref.TRI), ref.Scratch((-1, -30), (3, 30), 2.0, 0.2)],
    "flat x V": [ref.Scratch((-30, 0.5), (30, 0.5), 1.5, 0.35), ref.Scratch((-1, -30), (3, 30), 2.0, 0.5, ref.TRI)],
}


def v_errors(scratches, sigma, combos, samples, pitch):
    additive = probe.load_bsdf(scratches, sigma_um=sigma)
    height_field = probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field")
    out = {}
    for wavelength_nm, theta in combos:
        wi, rows, true = cs.sloped_plane(scratches, sigma, wavelength_nm, theta, samples, pitch)
        out[(wavelength_nm, theta)] = tuple(cs.relative_l2(cs.plugin_brdf(b, wi, rows, wavelength_nm), true)
                                            for b in (additive, height_field))
    return out


def test12_a_v_groove_crossing_matches_the_height_field():
    """Where a V-groove crosses, the overlap's depth is max(h_1, h_2) of two planes per cell
    (overlap._sloped_correction): within 1 % of the brute-force height field, where the sum is > 30 % off."""
    out = v_errors(V_PAIRS["V x V"], 2.0, [(550.0, 40.0)], 17, 0.02)
    additive, height_field = out[(550.0, 40.0)]
    assert additive > 0.3 and height_field < 0.01, out


@pytest.mark.slow
@pytest.mark.parametrize("name", list(V_PAIRS))
def test13_v_groove_pairs_match_the_height_field_at_every_wavelength_and_incidence(name):
    """450/550/650 nm each at a different incidence of 0/40/70° (all nine combinations, in
    tests/bench/bench_crossings.py --v-grooves: 0.18-0.62 %)."""
    out = v_errors(V_PAIRS[name], 2.0, [(450.0, 0.0), (550.0, 40.0), (650.0, 70.0)], 19, 0.015)
    assert max(v[1] for v in out.values()) < 0.01, out
    assert max(v[0] for v in out.values()) > 0.3, out


# (the mixed set compiles kernels of both profiles, ~18 s on a cold cache: under the slow marker)
@pytest.mark.parametrize("grooves, wavelength_nm, theta",
                         [("all", 450.0, 0.0), pytest.param("one", 650.0, 70.0, marks=pytest.mark.slow)])
def test14_three_crossing_scratches_with_v_grooves_match_the_height_field(grooves, wavelength_nm, theta):
    """A star of three (the centre under all), all V-grooves or one among flat bottoms: the triple term
    with the minimum of three depth planes (triples._sloped_triple) within 2 % (measured 0.19-1.14 %; the
    all-flat star 0.42 % on these coarse planes); the pair terms alone > 5 % (measured 32-92 %)."""
    scratches = star(3, (-1.0, 0.0, 0.7))
    chosen = range(3) if grooves == "all" else [1]
    scratches = [dataclasses.replace(s, profile=ref.TRI) if k in chosen else s for k, s in enumerate(scratches)]
    height_field = probe.load_bsdf(scratches, sigma_um=2.0, crossings="height_field")
    pairs_only = probe.load_bsdf(scratches, sigma_um=2.0, crossings="height_field")
    pairs_only.model = dataclasses.replace(pairs_only.model, triples=False)
    wi, rows, true = cs.sloped_plane(scratches, 2.0, wavelength_nm, theta, 17, 0.015)
    assert cs.relative_l2(cs.plugin_brdf(height_field, wi, rows, wavelength_nm), true) < 0.02
    assert cs.relative_l2(cs.plugin_brdf(pairs_only, wi, rows, wavelength_nm), true) > 0.05


def test15_a_dense_set_with_v_grooves_stays_within_the_height_fields_bound():
    """A true height field has |T| = 1, so |U| <= ∫w = 2πσ² and f_r <= 4πσ²/λ² (1 571 sr⁻¹ at σ = 5 µm,
    450 nm). Fifty narrow scratches, half V-grooves: sliver polygons of the split cells once gave a negative
    mean square and 10³⁴ (polygon.clipped_cell clamps it); measured max 1 088 at normal incidence, with the
    model's own clamp to that bound switched off (it would hide the terms' errors)."""
    scratches = cs.with_v_grooves(cs.random_set(50, 0, 25.0, (0.1, 0.3)), 0.5, 100)
    bsdf = probe.load_bsdf(scratches, sigma_um=5.0, crossings="height_field")
    bsdf.model = dataclasses.replace(bsdf.model, clamp_to_height_field_bound=False)
    rng = np.random.default_rng(3)
    wo = np.array([shading.direction(t, p) for t, p in zip(np.degrees(np.arccos(rng.uniform(0.05, 1, 3000))),
                                                           rng.uniform(0, 360, 3000))])
    for theta in (0.0, 40.0, 70.0):
        f = cs.plugin_brdf(bsdf, shading.direction(theta, 20.0), wo, 450.0)
        assert np.isfinite(f).all() and f.max() < 4 * np.pi * 5.0 ** 2 / 0.45 ** 2, (theta, f.max())


BEYOND_THE_TERMS = {  # sets where the corrections alone exceed the bound |U| <= 2πσ² of every height field
    # ten mutually nearly parallel scratches 4 µm wide within 3 µm, crossed by one more: piles of ten, whose
    # orders 4 to 10 among the nearly parallel ones stay uncorrected (measured 45x the bound at some directions)
    "bunch": [ref.Scratch((-40, y - 0.03 * k), (40, y + 0.03 * k), 4.0, 0.3 + 0.02 * k)
              for k, y in enumerate(np.linspace(-1.5, 1.5, 10))] + [ref.Scratch((-6, -40), (8, 40), 3.0, 0.35)],
    # nine scratches through one point, 20° apart: orders 6 to 9 uncorrected (19x)
    "star of nine": [ref.Scratch((-40 * np.cos(a), -40 * np.sin(a)), (40 * np.cos(a), 40 * np.sin(a)), 4.0, 0.3)
                     for a in np.radians(np.arange(9) * 20.0 + 3.0)],
}


# (~20 s a set with the kernels it compiles; test15 checks the bound on a dense set in make test: under the
# slow marker)
@pytest.mark.slow
@pytest.mark.parametrize("name", BEYOND_THE_TERMS)
def test16_the_field_never_exceeds_the_height_fields_bound(name):
    """Where the truncated expansion exceeds every height field's |U| <= 2πσ² (docs/model.md §3.4; 1.5x on a
    stress set with the pair terms alone, tests/bench/bench_height_field_bound.py), the clamp caps it:
    f_r <= 4πσ²/λ² everywhere, and below the bound it changes nothing."""
    scratches = BEYOND_THE_TERMS[name]
    bsdf = probe.load_bsdf(scratches, sigma_um=5.0, crossings="height_field")
    raw = probe.load_bsdf(scratches, sigma_um=5.0, crossings="height_field")
    raw.model = dataclasses.replace(raw.model, clamp_to_height_field_bound=False)
    rng = np.random.default_rng(4)
    wo = np.array([shading.direction(t, p) for t, p in zip(np.degrees(np.arccos(rng.uniform(0.05, 1, 4000))),
                                                           rng.uniform(0, 360, 4000))])
    bound = 4 * np.pi * 5.0 ** 2 / 0.55 ** 2
    worst = 0.0
    for theta in (0.0, 30.0, 60.0):
        wi = shading.direction(theta, 10.0)
        clamped, unclamped = cs.plugin_brdf(bsdf, wi, wo, 550.0), cs.plugin_brdf(raw, wi, wo, 550.0)
        assert clamped.max() <= bound * 1.0001
        np.testing.assert_allclose(clamped[unclamped < bound], unclamped[unclamped < bound], rtol=1e-6)
        worst = max(worst, unclamped.max() / bound)
    assert worst > 1.0  # the case is real: the terms alone exceed the bound here


def test17_vanishingly_narrow_v_grooves_cross_without_harm():
    """A V-groove 10⁻⁶ µm wide (the format only asks for a positive width; facet slope 2D/W ~ 10⁶) crossing
    others: the sloped cells stay finite."""
    scratches = [ref.Scratch((-30, 0.5), (30, 0.5), 1e-6, 0.3, ref.TRI), ref.Scratch((-1, -30), (3, 30), 2.0, 0.4, ref.TRI),
                 ref.Scratch((-20, -3), (20, 4), 1.0, 0.2)]
    wo = np.array([shading.direction(t, p) for t in (5, 30, 60) for p in range(0, 360, 15)])
    wi = shading.direction(35, 20)
    height_field = shading.eval_brdf(probe.load_bsdf(scratches, crossings="height_field"), wi, wo)
    assert np.isfinite(height_field).all() and height_field.max() > 0


# ------------------------------------------------- nearly parallel overlaps
def parallel_pairs():
    """Pairs of scratches nearly parallel (|sin θ| < MIN_SINE) or parallel that overlap near x0: the tables list
    none of them; the kernel pairs the pieces it finds (parallel.py). Rotated by 17° so that no edge follows
    the raster's axes."""
    flat, v = ref.RECT, ref.TRI
    pairs = {
        "parallel, half overlapping": [ref.Scratch((-30, 0.0), (30, 0.0), 1.0, 0.25),
                                       ref.Scratch((-30, 0.5), (30, 0.5), 1.5, 0.4)],
        "2 degrees through x0": [ref.Scratch((-30, 0.0), (30, 0.0), 1.0, 0.25),
                                 ref.Scratch((-30, -1.05), (30, 1.05), 1.5, 0.4)],
        "0.6 degrees, ends inside": [ref.Scratch((-30, 0.2), (5, 0.2), 2.0, 0.3),
                                     ref.Scratch((-4, -0.1), (30, 0.25), 1.5, 0.45)],
        "wide along narrow": [ref.Scratch((-30, 0.0), (30, 0.0), 4.0, 0.2), ref.Scratch((-3, 0.5), (3, 0.6), 0.6, 0.5)],
        "V x V, 1 degree, ends inside": [ref.Scratch((-30, 0.2), (5, 0.2), 2.0, 0.3, v),
                                         ref.Scratch((-4, -0.1), (30, 0.4), 1.5, 0.45, v)],
        "flat x V, parallel": [ref.Scratch((-30, 0.0), (30, 0.0), 1.0, 0.25, flat),
                               ref.Scratch((-30, 0.5), (30, 0.5), 1.5, 0.4, v)],
    }
    return turned_off_the_raster_axes(pairs)


def turned_off_the_raster_axes(sets, degrees=17.0):
    """``sets`` ({name: scratches}) rotated about x0, so that no edge follows the raster's axes."""
    turn = np.radians(degrees)
    c, s = np.cos(turn), np.sin(turn)

    def rotated(p):
        return (c * p[0] - s * p[1], s * p[0] + c * p[1])

    return {name: [dataclasses.replace(x, a=rotated(x.a), b=rotated(x.b)) for x in scratches]
            for name, scratches in sets.items()}


PARALLEL_PAIRS = parallel_pairs()


def parallel_errors(scratches, combos, samples=19, pitch=0.015, sigma=2.0, without="parallel_overlaps"):
    """{(λ, θ): (additive, height field ``without`` one of its terms (a Model switch), height field)} against
    the brute-force height field."""
    switched_off = probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field")
    switched_off.model = dataclasses.replace(switched_off.model, **{without: False})
    bsdfs = (probe.load_bsdf(scratches, sigma_um=sigma), switched_off,
             probe.load_bsdf(scratches, sigma_um=sigma, crossings="height_field"))
    out = {}
    for wavelength_nm, theta in combos:
        wi, rows, true = cs.sloped_plane(scratches, sigma, wavelength_nm, theta, samples, pitch)
        out[(wavelength_nm, theta)] = tuple(cs.relative_l2(cs.plugin_brdf(b, wi, rows, wavelength_nm), true)
                                            for b in bsdfs)
    return out


@pytest.mark.parametrize("name", ["parallel, half overlapping"])
def test18_nearly_parallel_overlaps_match_the_height_field(name):
    """Two scratches overlapping along the window without a crossing the tables list (V-grooves: test18b,
    slow): within 2 % of the
    brute-force height field (measured 0.06-1.45 % on all six pairs, every wavelength and incidence:
    tests/bench/bench_crossings.py --parallel); the additive model and the height field without them stay
    the same and > 30 % off."""
    out = parallel_errors(PARALLEL_PAIRS[name], [(550.0, 40.0)])
    additive, without, height_field = out[(550.0, 40.0)]
    assert additive > 0.3 and without == pytest.approx(additive, rel=1e-4) and height_field < 0.02, out


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PARALLEL_PAIRS))
def test18b_nearly_parallel_pairs_at_every_wavelength_and_incidence(name):
    out = parallel_errors(PARALLEL_PAIRS[name], [(450.0, 0.0), (550.0, 40.0), (650.0, 70.0)])
    assert max(v[2] for v in out.values()) < 0.02, out
    assert min(v[0] for v in out.values()) > 0.1, out


# (the V-groove case compiles its own kernels, ~19 s on a cold cache: under the slow marker)
@pytest.mark.parametrize("profile", [ref.RECT, pytest.param(ref.TRI, marks=pytest.mark.slow)])
def test19_a_duplicated_scratch_is_the_scratch_once(profile):
    """Two identical scratches are one groove on a height field: its lines coincide with the other's, which
    the polygons must count once (polygon.TIE_UM), not twice or never."""
    one = [ref.Scratch((-30.0, -4.0), (30.0, 5.0), 1.5, 0.35, profile)]
    d = np.array([60.0, 9.0]) / np.hypot(60.0, 9.0)
    for theta in (0.0, 40.0):
        wi = shading.direction(theta, 20.0)
        # across the scratch's diffraction line (ξ ⟂ its direction), where its light goes, off the mirror lobe
        nu = np.linspace(-1.6, 1.6, 161)
        nu = nu[np.abs(nu) > 4.0 / (2.0 * np.sqrt(2.0) * np.pi * 2.0)]
        tangent = 0.55 * nu[:, None] * np.array([-d[1], d[0]]) - wi[:2]
        tangent = tangent[np.hypot(*tangent.T) < 0.98]
        wo = np.column_stack([tangent, np.sqrt(1.0 - np.sum(tangent ** 2, axis=1))])
        single = cs.plugin_brdf(probe.load_bsdf(one, sigma_um=2.0), wi, wo, 550.0)
        twice = cs.plugin_brdf(probe.load_bsdf(one * 2, sigma_um=2.0, crossings="height_field"), wi, wo, 550.0)
        added = cs.plugin_brdf(probe.load_bsdf(one * 2, sigma_um=2.0), wi, wo, 550.0)
        assert cs.relative_l2(twice, single) < 0.03 < 0.3 < cs.relative_l2(added, single)


def test20_consecutive_pieces_are_not_an_overlap():
    """Pieces of one polyline meet end to start (a gentle bend, a long scratch cut at 1/64 UV): nothing to
    pair, the field is the one without the nearly parallel overlaps bit for bit."""
    bend = ScratchSet.from_polylines([probe.to_uv([(-40, -1.0), (0, 0.0), (40, -0.5)]),
                                      probe.to_uv([(-2000, 3.0), (2000, 3.5)])],
                                     width=[1.5e-6, 2e-6], depth=[3e-7, 2e-7])
    wo = np.array([shading.direction(t, p) for t in (5, 20, 35, 50, 70) for p in range(0, 360, 10)])
    with_pairs = probe.load_bsdf(bend, sigma_um=5.0, crossings="height_field")
    without = probe.load_bsdf(bend, sigma_um=5.0, crossings="height_field")
    without.model = dataclasses.replace(without.model, parallel_overlaps=False)
    assert tables.build_tables(bend).piece_count > 3
    for theta in (0.0, 40.0):
        wi = shading.direction(theta, 20.0)
        np.testing.assert_array_equal(cs.plugin_brdf(with_pairs, wi, wo, 550.0), cs.plugin_brdf(without, wi, wo, 550.0))


# ------------------------------------- a crossing through a nearly parallel overlap
def crossed_parallel_sets():
    """A nearly parallel pair overlapping along the window (2° apart through x0) crossed by a third scratch:
    the overlap of all three is an overlap of order 3 with one nearly parallel pair, found from a crossing pair
    (triples.py).  "bunch of three": three mutually nearly parallel scratches crossed by a fourth: their
    threefold overlap has no crossing pair (parallel.py finds it), the fourfold one is the crossing pairs'.
    Rotated 17° as the parallel pairs."""
    flat, v = ref.RECT, ref.TRI
    sets = {
        "flat": [ref.Scratch((-30, 0.0), (30, 0.0), 1.0, 0.25), ref.Scratch((-30, -1.05), (30, 1.05), 1.5, 0.4),
                 ref.Scratch((-14.7, -25.2), (15.3, 26.8), 1.2, 0.3)],
        "V-grooves": [ref.Scratch((-30, 0.0), (30, 0.0), 1.0, 0.25, v), ref.Scratch((-30, -1.05), (30, 1.05), 1.5, 0.4),
                      ref.Scratch((-14.7, -25.2), (15.3, 26.8), 1.2, 0.3, v)],
        "bunch of three": [ref.Scratch((-30, 0.0), (30, 0.0), 1.0, 0.25), ref.Scratch((-30, -1.05), (30, 1.05), 1.5, 0.4),
                           ref.Scratch((-30, 0.9), (30, -0.6), 1.3, 0.2),
                           ref.Scratch((-14.7, -25.2), (15.3, 26.8), 1.2, 0.3)],
    }
    return turned_off_the_raster_axes(sets)


CROSSED_PARALLEL = crossed_parallel_sets()


@pytest.mark.parametrize("name", ["bunch of three"])
def test21_a_crossing_through_a_nearly_parallel_overlap_matches_the_height_field(name):
    """Overlaps of three and four with nearly parallel pairs in them: within 2 % of the brute-force height field
    (measured worst over 450/550/650 nm × 0/40/70°: tests/bench/bench_crossings.py --parallel); without the
    terms of order 3 and more > 30 % off."""
    out = parallel_errors(CROSSED_PARALLEL[name], [(550.0, 40.0)], without="triples")
    additive, without_triples, height_field = out[(550.0, 40.0)]
    assert height_field < 0.02 and without_triples > 0.3 and additive > 1.0, out


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CROSSED_PARALLEL))
def test21b_crossed_nearly_parallel_pairs_at_every_wavelength_and_incidence(name):
    out = parallel_errors(CROSSED_PARALLEL[name], [(450.0, 0.0), (550.0, 40.0), (650.0, 70.0)], without="triples")
    assert max(v[2] for v in out.values()) < 0.02, out
    assert min(v[1] for v in out.values()) > 0.1, out


# ------------------------------------------------------ a crossing next to an end
ENDED_CROSSINGS = turned_off_the_raster_axes({
    # the crossing 0.7 µm from the first's end: the parallelogram reaches 1.7 µm past it
    "one ends": [ref.Scratch((-30, 0.3), (1.0, 0.3), 2.0, 0.3), ref.Scratch((-20, -24), (20, 24), 2.5, 0.4)],
    "both end": [ref.Scratch((-30, 0.3), (1.0, 0.3), 2.0, 0.3), ref.Scratch((-20, -24), (0.9, 1.6), 2.5, 0.4)],
    "a V-groove ends": [ref.Scratch((-30, 0.3), (1.0, 0.3), 2.0, 0.3, ref.TRI),
                        ref.Scratch((-20, -24), (20, 24), 2.5, 0.4)],
    # 4 mm long, cut into 249 pieces of 1/64 UV, one cut at the crossing: the groove runs on past it
    "a cut run": [ref.Scratch((-2000, 0.3), (2000, 0.3), 2.0, 0.3), ref.Scratch((-20, -24), (20, 24), 2.5, 0.4)],
})


# (the V-groove's case, a set of both profiles, compiles its own kernels: ~19 s on a cold cache, slow marker)
# (5-8 s each: make test keeps the crossing next to one end, the others under the slow marker)
@pytest.mark.parametrize("name", [name if name == "one ends" else pytest.param(name, marks=pytest.mark.slow)
                                  for name in ENDED_CROSSINGS])
def test22_a_crossing_next_to_a_grooves_end_matches_the_height_field(name):
    """Where a groove ends inside the crossing's parallelogram, the overlap ends there too: the pair's cells
    are clipped to the grooves' runs (overlap.run_ends), not to the pieces a long scratch is cut into.
    Measured 0.08-0.23 % over 450/550/650 nm × 0/40/70° on the first three, 0.43 % on the cut run at
    550 nm, 40°; the parallelogram unclipped was 22-77 %, and clipped at the pieces' own ends 67 % on the
    cut run."""
    out = parallel_errors(ENDED_CROSSINGS[name], [(550.0, 40.0)], without="triples")
    additive, _, height_field = out[(550.0, 40.0)]
    assert height_field < 0.01 and additive > 0.3, out
