"""Periodic families (:mod:`...bsdf.periodic`): a grating's tracks summed in closed form.

The reference is the BSDF's own scan (``Model.periodic = False``), which the other tests check
against brute-force wave optics.  The closed form sums the infinite run of tracks where the scan
drops every track beyond the window radius 4σ (a window factor below e^-8 = 3.4e-4 each); the two
agree to ~1e-4 (measured 0.5–2.6e-4 relative L2 on the CD and the Fig. 9 grating), asserted at 1e-3.
Lanes that use no family must give the scan's values bit for bit.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf import periodic
from scratch_iridescence.mitsuba_bridge.bsdf.tables import periodic as periodic_tables
from scratch_iridescence.mitsuba_bridge.bsdf.tables import grid as tables
from scratch_iridescence.mitsuba_bridge.validation import reference as ref
from scratch_iridescence.mitsuba_bridge.bsdf.lookup import jacobian
from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet
import shading

#: The test grating (µm around x0): tracks at this pitch, each this long, σ = 2 µm >= the pitch, and
#: cells of 62.5 µm (1/16 UV, UNIT_SCALE being 1 mm per UV unit): dense enough cells for families,
#: small enough that windows straddle cells.
PITCH, TRACKS, HALF_LENGTH, SIGMA = 1.2, 81, 200.0, 2.0
CELL_UV = 1.0 / 16.0


def grating(profile=ref.RECT, *, drop=(), wide=(), crossing=False, jitter=0.0, split=False, seed=0, width_um=0.6):
    """The grating as reference Scratches of ``width_um``: ``drop`` tracks left out, ``wide`` ones wider, an
    optional scratch across it, offsets jittered by up to ``jitter`` µm, tracks cut into collinear halves."""
    rng = np.random.default_rng(seed)
    scratches = []
    for k in range(TRACKS):
        if k in drop:
            continue
        y = (k - TRACKS // 2) * PITCH + rng.uniform(-jitter, jitter)
        width = 0.9 if k in wide else width_um
        if split:
            scratches += [ref.Scratch((-HALF_LENGTH, y), (30.0, y), width, 0.2, profile),
                          ref.Scratch((30.0, y), (HALF_LENGTH, y), width, 0.2, profile)]
        else:
            scratches.append(ref.Scratch((-HALF_LENGTH, y), (HALF_LENGTH, y), width, 0.2, profile))
    if crossing:
        scratches.append(ref.Scratch((20.0, -60.0), (40.0, 60.0), 0.5, 0.1))
    return scratches


#: The kinked grating's kink line (µm, mid-cell) and its chords' half-angle (a CD's is 1.26°).
KINK_X, KINK_HALF_ANGLE_DEG = 31.25, 3.0


def kinked_grating(profile=ref.RECT, *, slant_deg=0.0, shift=0.0, second_width=0.6, kink_x=KINK_X):
    """Tracks of two chords each, turning by twice ``KINK_HALF_ANGLE_DEG`` at vertices on one line (as a
    CD's polygons do), tilted by ``slant_deg``; ``shift``: every 20th track's vertex moved along it (µm);
    ``second_width``: the second chords' width (µm); ``kink_x``: where the vertices lie (µm)."""
    d = np.radians(KINK_HALF_ANGLE_DEG)
    a_way, b_way = np.array([np.cos(d), np.sin(d)]), np.array([np.cos(d), -np.sin(d)])
    scratches = []
    for k in range(TRACKS):
        y = (k - TRACKS // 2) * PITCH / np.cos(d)
        vertex = np.array([kink_x + y * np.tan(np.radians(slant_deg)), y])
        if k % 20 == 7:
            vertex = vertex + shift * a_way
        scratches.append(ref.Scratch(tuple(vertex - HALF_LENGTH * a_way), tuple(vertex), 0.6, 0.2, profile))
        scratches.append(ref.Scratch(tuple(vertex), tuple(vertex + HALF_LENGTH * b_way), second_width, 0.2, profile))
    return scratches


def load(scratches, **kwargs):
    return shading.load_bsdf(scratches, sigma_um=SIGMA, cell_size=CELL_UV, **kwargs)


#: UV maps of the test surface (dp_du, dp_dv): plain, sheared and scaled, mirrored (negative determinant).
UV_MAPS = {"plain": ((1, 0, 0), (0, 1, 0)), "shear": ((1.0, 0.3, 0), (-0.2, 0.8, 0)),
           "mirror": ((-0.9, 0.1, 0), (0.2, 1.1, 0))}


def lanes(count, rng, *, x=(-150.0, 150.0), y=(-40.0, 40.0), uv_map="plain"):
    """Shading points (µm around x0), random ω_i and wavelengths, on one of the ``UV_MAPS``."""
    points = np.stack([rng.uniform(*x, count), rng.uniform(*y, count)], axis=1)
    uv = shading.to_uv(points)
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.uv = mi.Point2f(shading.floats(uv[:, 0]), shading.floats(uv[:, 1]))
    si.dp_du, si.dp_dv = (mi.Vector3f(*axis) for axis in UV_MAPS[uv_map])
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = directions(count, rng)
    si.wavelengths = mi.Spectrum(*(shading.floats(rng.uniform(360, 830, count)) for _ in range(4)))
    return si, points


def directions(count, rng):
    """``count`` random outgoing directions, cosine-distributed over the hemisphere."""
    return mi.warp.square_to_cosine_hemisphere(mi.Point2f(shading.floats(rng.random(count)),
                                                          shading.floats(rng.random(count))))


def eligible(bsdf, si, kink=False):
    """Lanes that use a family (``kink``: and a pair of kink masks, eligible and at a kink)."""
    model = bsdf.model
    family = model._family(jacobian(si, model.micrometres_per_unit), True)
    none = np.zeros(dr.width(si), bool)
    if family is None:
        return (none, none) if kink else none
    if kink:
        return np.asarray(family.eligible), none if family.kink is None else np.asarray(family.kink)
    return np.asarray(family.eligible)


def scan_and_closed_form(bsdf, si, wo):
    """(eval, pdf) with the families and with the scan alone."""
    ctx = mi.BSDFContext()
    closed = [np.asarray(x, np.float64) for x in bsdf.eval_pdf(ctx, si, wo)]
    bsdf.model.periodic = False
    try:
        scan = [np.asarray(x, np.float64) for x in bsdf.eval_pdf(ctx, si, wo)]
    finally:
        bsdf.model.periodic = True
    return closed, scan


def relative_l2(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def assert_family_lanes_match_the_scan(bsdf, si, wo, inside, value_limit, pdf_limit):
    """On the ``inside`` lanes value and pdf within these relative L2 of the scan's, elsewhere the scan's
    bit for bit."""
    (value, pdf), (scan_value, scan_pdf) = scan_and_closed_form(bsdf, si, wo)
    assert np.abs(scan_value[:, inside]).max() > 0
    assert relative_l2(value[:, inside], scan_value[:, inside]) < value_limit
    assert relative_l2(pdf[inside], scan_pdf[inside]) < pdf_limit
    np.testing.assert_array_equal(value[:, ~inside], scan_value[:, ~inside])
    np.testing.assert_array_equal(pdf[~inside], scan_pdf[~inside])


@pytest.mark.parametrize("profile,uv_map,split", [(ref.RECT, "plain", False), (ref.TRI, "plain", False),
                                                  (ref.RECT, "shear", True), (ref.TRI, "shear", False),
                                                  (ref.TRI, "mirror", True)])
def test01_closed_form_equals_the_scan(profile, uv_map, split):
    bsdf = load(grating(profile, split=split))
    assert bsdf.model.grid.periodic
    assert f"periodic families={bsdf.model.grid.family_count}, kinks=0," in str(bsdf)
    assert bsdf.model.grid.family_count >= 8
    rng = np.random.default_rng(1)
    count = 1 << 13
    si, _ = lanes(count, rng, uv_map=uv_map)
    wo = directions(count, rng)
    inside = eligible(bsdf, si)
    assert inside.mean() > 0.9  # every window here lies among the tracks, away from their ends
    assert_family_lanes_match_the_scan(bsdf, si, wo, inside, 1e-3, 1e-3)


def test02_windows_near_the_last_track_or_the_ends_scan():
    """The family is used only where the window (4σ) lies among its tracks and no end lies within 7.2σ."""
    bsdf = load(grating())
    edge = (TRACKS // 2) * PITCH  # the outermost track's offset
    points = np.array([[0.0, 0.0], [-120.0, 10.0],  # inside
                       [0.0, edge - 2.0 * SIGMA],  # the window reaches past the last track
                       [HALF_LENGTH - 6.0 * SIGMA, 0.0], [-HALF_LENGTH + 3.0 * SIGMA, 5.0]])  # ends near
    uv = shading.to_uv(points)
    si = shading.interaction(len(points), shading.direction(30.0), uv=(uv[:, 0], uv[:, 1]))
    assert eligible(bsdf, si).tolist() == [True, True, False, False, False]


@pytest.mark.parametrize("change", ["drop", "wide", "crossing", "jitter"])
def test03_irregular_tracks_are_scanned(change):
    """A missing track, one of another width, a scratch across, offsets off the lattice by more than
    ``PITCH_TOLERANCE``: windows that see them scan (and give the scan's values bit for bit)."""
    middle = TRACKS // 2
    kwargs = {"drop": {"drop": (middle + 3,)}, "wide": {"wide": (middle - 2,)}, "crossing": {"crossing": True},
              "jitter": {"jitter": 2.5 * periodic_tables.PITCH_TOLERANCE * PITCH}}[change]
    bsdf = load(grating(**kwargs))
    rng = np.random.default_rng(5)
    count = 4096
    si, points = lanes(count, rng)
    inside = eligible(bsdf, si)
    if change == "jitter":
        assert not inside.any()
    else:
        spot = {"drop": (None, (middle + 3 - middle) * PITCH), "wide": (None, -2 * PITCH), "crossing": (30.0, 0.0)}
        x, y = spot[change]
        near = np.abs(points[:, 1] - y) < 4.0 * SIGMA if x is None else np.hypot(*(points - (x, y)).T) < 4 * SIGMA
        assert near.any() and not inside[near].any()
        assert inside.any()  # the rest of the grating still sums in closed form
    wo = directions(count, rng)
    (value, pdf), (scan_value, scan_pdf) = scan_and_closed_form(bsdf, si, wo)
    np.testing.assert_array_equal(value[:, ~inside], scan_value[:, ~inside])
    if inside.any():
        assert relative_l2(value[:, inside], scan_value[:, inside]) < 1e-3


def test04_small_jitter_stays_periodic_within_its_phase_error():
    """Offsets off the lattice by up to 0.4 % of the pitch (a grating painted through float32
    coordinates) still form a family; the closed form then differs from the scan by the phase
    errors 2π ν⊥ δ it ignores: < 1 % here."""
    bsdf = load(grating(jitter=0.004 * PITCH))
    rng = np.random.default_rng(6)
    count = 1 << 12
    si, _ = lanes(count, rng)
    inside = eligible(bsdf, si)
    assert inside.mean() > 0.9
    wo = directions(count, rng)
    (value, _), (scan_value, _) = scan_and_closed_form(bsdf, si, wo)
    error = relative_l2(value[:, inside], scan_value[:, inside])
    assert 1e-4 < error < 1e-2


def assert_sample_weight_is_eval_over_pdf(bsdf, si, lanes_used, rng, share):
    """On ``lanes_used`` (at least ``share`` of them with a sample): ``sample``'s pdf is ``eval_pdf``'s at
    the sampled direction and its weight is eval/pdf."""
    ctx = mi.BSDFContext()
    count = dr.width(si)
    bs, weight = bsdf.sample(ctx, si, shading.floats(rng.random(count)),
                             mi.Point2f(shading.floats(rng.random(count)), shading.floats(rng.random(count))))
    value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
    weight, value, pdf, bs_pdf = (np.asarray(x, dtype=np.float64) for x in (weight, value, pdf, bs.pdf))
    valid = (bs_pdf > 0) & lanes_used
    assert valid.mean() > share
    np.testing.assert_allclose(bs_pdf[valid], pdf[valid], rtol=1e-4)
    np.testing.assert_allclose(weight[:, valid], value[:, valid] / pdf[valid], rtol=1e-4, atol=1e-7)


def test05_sample_weight_is_eval_over_pdf_inside_a_family():
    bsdf = load(grating(ref.TRI))
    rng = np.random.default_rng(7)
    si, _ = lanes(1 << 13, rng)
    assert_sample_weight_is_eval_over_pdf(bsdf, si, eligible(bsdf, si), rng, 0.5)


def test06_the_bounded_depth_phase_scans():
    """The coherent "bounded" depth phase normalises by albedo terms summed piece by piece: no closed form."""
    rng = np.random.default_rng(8)
    count = 2048
    si, _ = lanes(count, rng)
    wo = directions(count, rng)
    bsdf = load(grating(), depth_phase="bounded")
    assert bsdf.model._family(jacobian(si, bsdf.model.micrometres_per_unit), True) is None
    (value, _), (scan_value, _) = scan_and_closed_form(bsdf, si, wo)
    np.testing.assert_array_equal(value, scan_value)


def test07_pieces_that_run_straight_on_are_joined():
    """``tables.continuations``: a long scratch split into pieces and a straight polyline join; a kink,
    another width and a gap do not."""
    polylines = [np.array([[0.1, 0.1], [0.3, 0.1], [0.5, 0.1]]),  # straight on
                 np.array([[0.1, 0.2], [0.3, 0.2], [0.5, 0.25]]),  # a kink
                 np.array([[0.1, 0.3], [0.3, 0.3]]), np.array([[0.3, 0.3], [0.5, 0.3]]),  # touching scratches
                 np.array([[0.1, 0.4], [0.3, 0.4]]), np.array([[0.3 + 1e-6, 0.4], [0.5, 0.4]])]  # a gap
    widths = [1e-6, 1e-6, 1e-6, 2e-6, 1e-6, 1e-6]  # the touching pair differs in width
    scratches = ScratchSet.from_polylines(polylines, width=1e-6, depth=1e-7)
    scratches = ScratchSet(uv=scratches.uv, offsets=scratches.offsets, width=np.asarray(widths),
                           depth=scratches.depth, profile=scratches.profile,
                           width_variation=scratches.width_variation, depth_variation=scratches.depth_variation,
                           seed=scratches.seed)
    built, a, b = tables.build_sorted(scratches)
    joined = built.continuation
    start_row = {tuple(np.round(p, 6)): row for row, p in enumerate(a)}
    end_row = {tuple(np.round(p, 6)): row for row, p in enumerate(b)}
    first, second = end_row[(0.3, 0.1)], start_row[(0.3, 0.1)]
    assert joined[first, 1] == pytest.approx(0.2, rel=1e-6) and joined[second, 0] == pytest.approx(0.2, rel=1e-6)
    for point in ((0.3, 0.2), (0.3, 0.3)):
        assert joined[end_row[point], 1] == 0 and joined[start_row[point], 0] == 0
    assert joined[end_row[(0.3, 0.4)], 1] == 0
    # long scratches are split into pieces of at most MAX_PIECE_UV, all joined end to end
    long = tables.build_sorted(ScratchSet.from_polylines([np.array([[0.0, 0.5], [1.0, 0.5]])], width=1e-6,
                                                         depth=1e-7))[0]
    pieces = long.piece_count
    assert pieces > 1 and np.count_nonzero(long.continuation[:, 1]) == pieces - 1
    # two long scratches crossing where both are cut (several pieces start at one point): each joins its own
    crossing = tables.build_sorted(ScratchSet.from_polylines([np.array([[0.0, 0.5], [1.0, 0.5]]),
                                                              np.array([[0.0, 0.0], [1.0, 1.0]])],
                                                             width=1e-6, depth=1e-7))[0]
    assert np.count_nonzero(crossing.continuation[:, 1]) == crossing.piece_count - 2


def test08_the_chi2_gratings_of_test_sampling_are_families():
    """``test_sampling``'s "periodic_grating" (chi² of sample against pdf) runs through the closed form."""
    from test_sampling import SHADING_UV, make

    bsdf, wi = make("periodic_grating")
    assert eligible(bsdf, shading.interaction(16, wi)).all()
    bsdf, wi = make("kinked_grating")  # and its "kinked_grating" through the two cut runs
    inside, kink = eligible(bsdf, shading.interaction(16, wi, uv=SHADING_UV["kinked_grating"]), kink=True)
    assert kink.all() and inside.all()
    bsdf, wi = make("incoherent_kinked_grating")  # and the incoherent closed form at a kink
    inside, kink = eligible(bsdf, shading.interaction(16, wi, uv=SHADING_UV["incoherent_kinked_grating"]),
                            kink=True)
    assert kink.all() and inside.all()


def test09_degenerate_shading_points_use_no_family():
    """NaN or infinite UVs, a zero and a huge UV Jacobian: no family, finite values."""
    bsdf = load(grating())
    count = 4
    si = shading.interaction(count, shading.direction(30.0))
    x0 = np.asarray(shading.X0_UV, np.float64)
    si.uv = mi.Point2f(shading.floats([np.nan, np.inf, x0[0], x0[0]]), shading.floats([x0[1]] * count))
    scale = shading.floats([1.0, 1.0, 0.0, 1e9])
    si.dp_du, si.dp_dv = mi.Vector3f(scale, 0, 0), mi.Vector3f(0, scale, 0)
    assert not eligible(bsdf, si).any()
    value = np.asarray(bsdf.eval(mi.BSDFContext(), si, shading.vector([(0.2, 0.1, 0.97)] * count)))
    assert np.isfinite(value).all()


KINK_LANES = {"x": (KINK_X - 25.0, KINK_X + 25.0), "y": (-30.0, 30.0)}


@pytest.mark.parametrize("profile,uv_map,slant", [(ref.RECT, "plain", 0.0), (ref.RECT, "plain", 6.0),
                                                  (ref.TRI, "shear", 0.0), (ref.RECT, "mirror", 0.0)])
def test10_at_a_kink_the_two_cut_runs_equal_the_scan(profile, uv_map, slant):
    """Windows across a kink line sum each chord's run cut by the line's half-plane (docs/model.md §3.5).
    The scan ends each piece square where the closed form cuts it along the line: they differ by wedges
    of W² tan(angle) per track, measured 4–9e-4 relative L2 here (6° kinks, up to 9° off square)."""
    bsdf = load(kinked_grating(profile, slant_deg=slant))
    rng = np.random.default_rng(11)
    count = 1 << 13
    si, _ = lanes(count, rng, uv_map=uv_map, **KINK_LANES)
    wo = directions(count, rng)
    inside, kink = eligible(bsdf, si, kink=True)
    assert kink.mean() > 0.3 and not (kink & ~inside).any()
    (value, pdf), (scan_value, scan_pdf) = scan_and_closed_form(bsdf, si, wo)
    assert relative_l2(value[:, kink], scan_value[:, kink]) < 2e-3
    assert relative_l2(pdf[kink], scan_pdf[kink]) < 1e-4
    plain = inside & ~kink
    assert relative_l2(value[:, plain], scan_value[:, plain]) < 1e-3
    np.testing.assert_array_equal(value[:, ~inside], scan_value[:, ~inside])


def test11_kinks_need_every_end_on_the_line_and_one_groove():
    """One vertex in 20 off the line (by 10 % of the pitch), or chords of another width after the turn:
    no kink, and the windows there scan, bit for bit."""
    rng = np.random.default_rng(12)
    si, _ = lanes(4096, rng, **KINK_LANES)
    wo = directions(4096, rng)
    for spoiled in (kinked_grating(shift=0.1 * PITCH), kinked_grating(second_width=0.7)):
        bsdf = load(spoiled)
        inside, kink = eligible(bsdf, si, kink=True)
        assert not kink.any() and "kinks=0," in str(bsdf) and inside.mean() < 0.9
        (value, _), (scan_value, _) = scan_and_closed_form(bsdf, si, wo)
        np.testing.assert_array_equal(value[:, ~inside], scan_value[:, ~inside])


@pytest.mark.parametrize("kink_x,x", [(KINK_X, KINK_LANES["x"]), (58.0, (33.0, 83.0))])
def test12_sample_weight_is_eval_over_pdf_at_a_kink(kink_x, x):
    """``sample`` draws one run's line in proportion to its cut weight: its pdf is the mixture's (and a
    lone run's own, near a cell's edge)."""
    bsdf = load(kinked_grating(ref.TRI, kink_x=kink_x))
    rng = np.random.default_rng(13)
    si, _ = lanes(1 << 13, rng, x=x, y=KINK_LANES["y"])
    assert_sample_weight_is_eval_over_pdf(bsdf, si, eligible(bsdf, si, kink=True)[1], rng, 0.3)


@pytest.mark.parametrize("profile,uv_map", [(ref.RECT, "plain"), (ref.TRI, "shear")])
def test13_kink_windows_across_cells_and_single_runs_by_their_end_line(profile, uv_map):
    """The kink line 4.5 µm from a cell's edge (cells of 62.5 µm, one edge at y = 0 too): windows reaching
    the next cell, which holds one run only, find the kink in their neighbour, and windows in that cell
    whose box stays on its side but whose along reach (7.2σ) meets the line sum the run cut by it alone
    (lone); every lane of this strip uses a family.  The cut runs' wedges weigh more here, where most
    windows lie near the line: < 4·10⁻³ (measured 1.6–2.5·10⁻³)."""
    bsdf = load(kinked_grating(profile, kink_x=58.0))
    rng = np.random.default_rng(14)
    count = 1 << 13
    si, points = lanes(count, rng, x=(33.0, 83.0), y=(-30.0, 30.0), uv_map=uv_map)
    wo = directions(count, rng)
    family = periodic.find_family(bsdf.model.grid, jacobian(si, bsdf.model.micrometres_per_unit),
                                  bsdf.model.sigma, True)
    inside, kink, lone = (np.asarray(x) for x in (family.eligible, family.kink, family.lone))
    box = 4.0 * SIGMA * 1.3  # beyond the box of any of the UV maps
    crosses = (np.floor((points[:, 0] - box) / 62.5) != np.floor((points[:, 0] + box) / 62.5)) | (
        np.abs(points[:, 1]) < box)
    assert inside.all() and (kink & crosses).mean() > 0.2 and (lone & (points[:, 0] > 62.5)).mean() > 0.02
    (value, pdf), (scan_value, scan_pdf) = scan_and_closed_form(bsdf, si, wo)
    assert relative_l2(value[:, kink], scan_value[:, kink]) < 4e-3
    assert relative_l2(value[:, lone], scan_value[:, lone]) < 1e-3
    assert relative_l2(pdf[kink], scan_pdf[kink]) < 1e-4


@pytest.mark.parametrize("profile,uv_map,split,width_um", [
    (ref.RECT, "plain", False, 0.6), (ref.TRI, "shear", True, 0.6), (ref.RECT, "mirror", False, 0.6),
    (ref.RECT, "plain", False, 0.4), (ref.TRI, "shear", False, 0.4)])
def test14_incoherent_closed_form_equals_the_scan(profile, uv_map, split, width_um):
    """Incoherently a run of tracks sums to the along factor's square times (σ/P) the squared groove
    transform averaged over the squared window's transform (Poisson's order 0, a 4-point Gauss–Hermite
    rule, 2 points for grooves of W <= σ/4 as the 0.4-µm ones; docs/model.md §3.5).  The scan drops tracks
    beyond 4σ at e^-16 of the intensity each: the two agree to ~1e-6 (measured 0.7–3·10⁻⁶), asserted at
    1e-4; the pdf to ~1e-7."""
    assert (width_um <= periodic.NARROW_GROOVE_SIGMAS * SIGMA) == (width_um == 0.4)  # both rules are tested
    bsdf = load(grating(profile, split=split, width_um=width_um), coherent=False)
    rng = np.random.default_rng(15)
    count = 1 << 13
    si, _ = lanes(count, rng, uv_map=uv_map)
    wo = directions(count, rng)
    inside = eligible(bsdf, si)
    assert inside.mean() > 0.9
    assert_family_lanes_match_the_scan(bsdf, si, wo, inside, 1e-4, 1e-5)


@pytest.mark.parametrize("profile,uv_map,slant,kink_x,x", [
    (ref.RECT, "plain", 0.0, KINK_X, KINK_LANES["x"]), (ref.RECT, "plain", 6.0, KINK_X, KINK_LANES["x"]),
    (ref.TRI, "shear", 0.0, KINK_X, KINK_LANES["x"]), (ref.RECT, "mirror", 0.0, KINK_X, KINK_LANES["x"]),
    (ref.TRI, "shear", 0.0, 58.0, (33.0, 83.0))])
def test15_incoherent_kinks_equal_the_scan(profile, uv_map, slant, kink_x, x):
    """Incoherently each track of a run cut by the kink line ends on it, as the scan's chord does: the
    closed form averages the cut along factor over the tracks' offsets (docs/model.md §3.5).  Measured
    2–3·10⁻⁶ for flat bottoms (the 6° slant and mirrored map included), 1.5·10⁻⁴ for V-grooves on the
    sheared map (|A'|² is not even in the offset there), lone runs 1–2·10⁻⁶; asserted at 1e-3."""
    bsdf = load(kinked_grating(profile, slant_deg=slant, kink_x=kink_x), coherent=False)
    rng = np.random.default_rng(16)
    count = 1 << 13
    si, _ = lanes(count, rng, uv_map=uv_map, x=x, y=KINK_LANES["y"])
    wo = directions(count, rng)
    family = bsdf.model._family(jacobian(si, bsdf.model.micrometres_per_unit), True)
    inside, kink, lone = (np.asarray(m) for m in (family.eligible, family.kink, family.lone))
    assert inside.mean() > 0.9 and kink.mean() > 0.3 and (lone.any() or kink_x == KINK_X)
    (value, pdf), (scan_value, scan_pdf) = scan_and_closed_form(bsdf, si, wo)
    assert relative_l2(value[:, kink], scan_value[:, kink]) < 1e-3
    assert relative_l2(pdf[kink], scan_pdf[kink]) < 1e-5
    assert relative_l2(value[:, inside & ~kink], scan_value[:, inside & ~kink]) < 1e-4
    np.testing.assert_array_equal(value[:, ~inside], scan_value[:, ~inside])


def test16_incoherent_sample_weight_is_eval_over_pdf_inside_a_family_and_at_a_kink():
    rng = np.random.default_rng(17)
    bsdf = load(grating(ref.TRI), coherent=False)
    si, _ = lanes(1 << 13, rng)
    assert_sample_weight_is_eval_over_pdf(bsdf, si, eligible(bsdf, si), rng, 0.5)
    bsdf = load(kinked_grating(ref.TRI, kink_x=58.0), coherent=False)
    si, _ = lanes(1 << 13, rng, x=(33.0, 83.0), y=KINK_LANES["y"])
    assert_sample_weight_is_eval_over_pdf(bsdf, si, eligible(bsdf, si, kink=True)[1], rng, 0.3)


#: Lanes across the test grating's upper edge (µm): within 1.2 window radii of its last track.
EDGE_Y = (TRACKS // 2) * PITCH
EDGE_LANES = dict(y=(EDGE_Y - 4.8 * SIGMA, EDGE_Y + 4.8 * SIGMA))


def edge_masks(bsdf, si):
    """(edge lanes summing their tracks in reach, edge lanes subtracting the missing ones, other family
    lanes) of the lanes ``si``."""
    family = bsdf.model._family(jacobian(si, bsdf.model.micrometres_per_unit), True)
    edge, base, inside = (np.asarray(m) for m in (family.edge, family.edge_base, family.eligible))
    return edge & ~base, edge & base, inside & ~edge


@pytest.mark.parametrize("coherent", [True, False])
@pytest.mark.parametrize("profile,uv_map", [(ref.RECT, "plain"), (ref.TRI, "shear"), (ref.RECT, "mirror")])
def test17_at_an_edge_the_tracks_in_reach_equal_the_scan(profile, uv_map, coherent):
    """A window across the first or last track sums the tracks in its reach one by one, exactly the scan's
    (measured 0.4–2.8·10⁻⁵ relative L2 coherent, 1.4–2.4·10⁻⁷ incoherent), or the infinite run's closed
    form less the missing ones where fewer are missing (the closed form's ~10⁻⁴: 0.9–1.3·10⁻⁴ coherent,
    2·10⁻⁶ incoherent); pdfs 1–2·10⁻⁷; docs/model.md §3.5, Edges.  Lanes without a family: the scan's bit
    for bit."""
    bsdf = load(grating(profile), coherent=coherent)
    rng = np.random.default_rng(18)
    count = 1 << 12
    si, _ = lanes(count, rng, uv_map=uv_map, **EDGE_LANES)
    wo = directions(count, rng)
    summed, subtracted, plain = edge_masks(bsdf, si)
    assert summed.mean() > 0.2 and subtracted.mean() > 0.2
    (value, pdf), (scan_value, scan_pdf) = scan_and_closed_form(bsdf, si, wo)
    assert np.abs(scan_value[:, summed]).max() > 0
    assert relative_l2(value[:, summed], scan_value[:, summed]) < (1e-4 if coherent else 1e-5)
    assert relative_l2(value[:, subtracted], scan_value[:, subtracted]) < 1e-3
    assert relative_l2(pdf[summed | subtracted], scan_pdf[summed | subtracted]) < 1e-5
    used = summed | subtracted | plain
    np.testing.assert_array_equal(value[:, ~used], scan_value[:, ~used])
    np.testing.assert_array_equal(pdf[~used], scan_pdf[~used])


def test18_an_edge_next_to_another_scratch_scans():
    """Beyond its last track a family is clear only up to the nearest other centre line of the cell: a
    short scratch 3σ beyond the edge makes the windows that reach it scan, bit for bit."""
    beside = ref.Scratch((10.0, EDGE_Y + 3.0 * SIGMA - 2.0), (10.0, EDGE_Y + 3.0 * SIGMA + 2.0), 0.5, 0.1)
    bsdf = load(grating() + [beside])
    far = load(grating())
    rng = np.random.default_rng(19)
    count = 1 << 12
    si, points = lanes(count, rng, x=(-20.0, 40.0), **EDGE_LANES)
    # windows (4σ) that reach the scratch's centre line
    near = np.hypot(points[:, 0] - 10.0, np.maximum(np.abs(points[:, 1] - (EDGE_Y + 3.0 * SIGMA)) - 2.0, 0.0)) < 4.0 * SIGMA
    summed, subtracted, _ = edge_masks(bsdf, si)
    alone = edge_masks(far, si)
    assert (alone[0] | alone[1])[near].mean() > 0.5  # without it, these windows sum their tracks
    assert not (summed | subtracted)[near].any()
    assert (summed | subtracted)[~near].any()
    (value, _), (scan_value, _) = scan_and_closed_form(bsdf, si, directions(count, rng))
    np.testing.assert_array_equal(value[:, near], scan_value[:, near])


@pytest.mark.parametrize("coherent", [True, False])
def test19_sample_weight_is_eval_over_pdf_at_an_edge(coherent):
    rng = np.random.default_rng(20)
    bsdf = load(grating(ref.TRI), coherent=coherent)
    si, _ = lanes(1 << 13, rng, uv_map="shear", **EDGE_LANES)
    summed, subtracted, _ = edge_masks(bsdf, si)
    assert_sample_weight_is_eval_over_pdf(bsdf, si, summed | subtracted, rng, 0.3)
