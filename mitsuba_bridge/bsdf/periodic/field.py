"""The families' closed forms (docs/model.md §3.5): a run's field by Poisson summation over its tracks
(the nearest orders), its incoherent intensity, the half-plane cut at a kink, the tracks summed one by
one at an edge, and the runs' selection weights.  Units: µm, 1/µm.
"""
from __future__ import annotations

import functools
import math
import operator

import drjit as dr
import mitsuba as mi

from ..maths.complexmath import Cx, expi
from ..maths.faddeeva import faddeeva
from ..maths.segment import SegmentGeometry, cross_section
from ..maths.window import window_integral
from .find import Family

__all__ = ["groove_transform", "family_field", "family_intensity", "run_energies", "MAX_INCOHERENT_WIDTH_SIGMAS",
           "NARROW_GROOVE_SIGMAS"]

#: ... and from which the nearest order alone does (the next lies 0.5/P > 0.9/σ away: below e^-16).
ONE_ORDER_SIGMA_PER_PITCH = 1.8
#: The sign of the transform's exponent in a run's frame: ``S(ξ) = ∫ w T e^{-2πiK·y}`` with an order's
#: frequency K = ν∥ t + (ν⊥ + m/P) n as :func:`_run_field` builds it (n = (-t_y, t_x))
HALF_PLANE_SIGN = -1.0


def _sinc(x):
    return dr.select(dr.abs(x) < 1e-4, 1.0 - x * x * (1.0 / 6.0), dr.sin(x) / x)


def groove_transform(family: Family, mu, kappa, coherent: bool = True) -> Cx:
    """``G(μ) = ∫ (e^{iκp(v)} - 1) e^{2πiμv} dv`` over one groove (µm), per wavelength; ``coherent=False``:
    the transform of ``e^{iκp(v)}`` over the groove instead (the incoherent mode's, docs/model.md §4.2).
    The V-groove's facets cost only in SIMD packets that hold one."""
    width = family.width
    kind = type(mu)  # (the branches' arithmetic may widen the type; both must return the same one)
    box = 1.0 if coherent else 0.0

    def flat(mu, kappa):
        g = (expi(kappa) - box) * (width * _sinc(math.pi * mu * width))
        return kind(g.re), kind(g.im)

    def v_groove(mu, kappa):  # two facets of phase κ ± (2κ/W) v, less the box
        quarter = 0.25 * width
        plus = (2.0 * math.pi) * mu + 2.0 * kappa / width
        minus = (2.0 * math.pi) * mu - 2.0 * kappa / width
        facets = (expi(kappa - plus * quarter) * _sinc(plus * quarter)
                  + expi(kappa + minus * quarter) * _sinc(minus * quarter))
        g = facets * (0.5 * width)
        if coherent:
            g = g - width * _sinc(math.pi * mu * width)
        return kind(g.re), kind(g.im)

    re, im = dr.if_stmt((mu, kappa), family.triangular, v_groove, flat, label="scratch_family_groove")
    return Cx(re, im)


def _groove_intensity(family: Family, mu, kappa):
    """``|G'(μ)|²`` of :func:`groove_transform` (``coherent=False``): for a flat bottom ``(W sinc(πμW))²``,
    the phase e^{iκ} drops out."""
    kind = type(mu)

    def v_groove(mu, kappa):
        return (kind(groove_transform(family, mu, kappa, coherent=False).abs2()),)

    def flat(mu, kappa):
        return (kind(dr.square(family.width * _sinc(math.pi * mu * family.width))),)

    return dr.if_stmt((mu, kappa), family.triangular, v_groove, flat, label="scratch_family_groove_intensity")[0]


def family_field(family: Family, xi_x, xi_y, k_z, sigma) -> Cx:
    """``Σ_n S_n(ξ)`` over the family's infinite run (module docstring), per wavelength; at a kink, the
    sum of its two runs, each cut by the kink line's half-plane (docs/model.md §3.5)."""
    kappa = k_z * family.depth
    kind = type(xi_x)
    full = _run_field(family, family.pitch, family.dx, family.dy, family.a0, xi_x, xi_y, kappa, sigma)
    full = _at_edges(family, full, xi_x, xi_y, kappa, sigma, coherent=True)
    if family.kink is None:
        return full

    def cut_run(i, re, im):
        """Run A (i = 0) or B (i = 1), cut by its side of the kink line."""
        second = i == 1
        pick = lambda a, b: dr.select(second, b, a)
        side = dr.select(second, -1.0, 1.0)
        s = _run_field(family, pick(family.pitch, family.b_pitch), pick(family.dx, family.b_dx),
                       pick(family.dy, family.b_dy), pick(family.a0, family.b_a0), xi_x, xi_y, kappa, sigma,
                       cut=(side * family.l_x, side * family.l_y, side * family.h))
        return i + 1, kind(re + s.re), kind(im + s.im)

    # A loop of two turns on the kink lanes, none elsewhere: SIMD packets without a kink leave it at once.
    # A body this heavy still costs the kernel where it never runs (on the grating, had it kinks: +30 % per
    # query as a symbolic branch, +12 % as this loop, measured), hence no kink code for sets without kinks
    # (find_family); the loop also traces the body once for both runs
    turns = dr.select(family.kink, dr.select(family.lone, 1, 2), 0)
    _, re, im = dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(kind), dr.zeros(kind)),
                              lambda i, re, im: i < turns, cut_run, label="scratch_family_kink")
    return Cx(dr.select(family.kink, re, full.re), dr.select(family.kink, im, full.im))


#: Gauss–Hermite nodes and weights (4 points) of the incoherent closed form's average over the squared
#: window's transform (:func:`family_intensity`) ...
HERMITE_NODES = (-1.6506801238857845, -0.5246476232752904, 0.5246476232752904, 1.6506801238857845)
HERMITE_WEIGHTS = (0.08131283544724518, 0.8049140900055128, 0.8049140900055128, 0.08131283544724518)
#: ... exact to 3e-4 (relative L2 over ν⊥) for grooves up to this many σ wide, to 1e-6 up to one σ;
#: wider grooves scan (incoherent mode only).
MAX_INCOHERENT_WIDTH_SIGMAS = 2.0
#: The 2-point rule (nodes ±1/√2) for grooves up to this many σ wide: exact to 6e-6 there (relative L2 over
#: ν⊥, flat and V-grooves; docs/model.md §3.5), as the 4-point one is to 1e-6 at one σ.
HERMITE_NODES_2 = (-0.7071067811865476, 0.7071067811865476)
HERMITE_WEIGHTS_2 = (0.8862269254527580, 0.8862269254527580)
NARROW_GROOVE_SIGMAS = 0.25


def family_intensity(family: Family, xi_x, xi_y, k_z, sigma):
    """``Σ_n |S'_n(ξ)|²`` over the family's infinite run: the incoherent mode's closed form (docs/model.md
    §3.5), per wavelength; at a kink the sum of its two runs, each cut by its side of the line.

    Poisson summation over the tracks' offsets leaves the order m = 0 alone (the others carry
    e^{-π²σ²m²/P²}, below 5e-5 where σ >= P): the along factor's square times
    (1/P) ∫ |A'(ν⊥; a)|² da = (σ√π/P) E[|G'(ν⊥ + η)|²] over η ~ N(0, 1/(8π²σ²)), the squared window's
    transform, which a 4-point Gauss–Hermite rule averages (``MAX_INCOHERENT_WIDTH_SIGMAS``)."""
    kappa = k_z * family.depth
    kind = type(xi_x)
    full = _run_intensity(family, family.pitch, family.dx, family.dy, xi_x, xi_y, kappa, sigma)
    full = _at_edges(family, full, xi_x, xi_y, kappa, sigma, coherent=False)
    if family.kink is None:
        return full

    def cut_run(i, total):
        """Run A (i = 0) or B (i = 1), cut by its side of the kink line."""
        second = i == 1
        pick = lambda a, b: dr.select(second, b, a)
        side = dr.select(second, -1.0, 1.0)
        run = _run_intensity(family, pick(family.pitch, family.b_pitch), pick(family.dx, family.b_dx),
                             pick(family.dy, family.b_dy), xi_x, xi_y, kappa, sigma,
                             cut=(side * family.l_x, side * family.l_y, side * family.h))
        return i + 1, kind(total + run)

    # (a loop on the kink lanes only, as in family_field)
    turns = dr.select(family.kink, dr.select(family.lone, 1, 2), 0)
    _, total = dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(kind)), lambda i, total: i < turns, cut_run,
                             label="scratch_family_kink_intensity")
    return dr.select(family.kink, total, full)


def _edge_sum(family: Family, term, initial):
    """``edge_sign × Σ term(a)`` over an edge lane's tracks, offsets ``a = edge_a + j · edge_step`` (µm), added
    to ``initial`` (a tuple); the loop runs no turn on other lanes (SIMD packets without an edge skip it)."""
    def body(j, *total):
        terms = term(family.edge_a + mi.Float(j) * family.edge_step)
        return (j + 1,) + tuple(type(t)(t + x) for t, x in zip(total, terms))

    zeros = tuple(dr.zeros(type(x)) for x in initial)
    sums = dr.while_loop((dr.zeros(mi.UInt32),) + zeros, lambda j, *total: j < family.edge_tracks, body,
                         label="scratch_family_edge")[1:]
    return tuple(type(x)(dr.select(family.edge_base, x - t, t)) for x, t in zip(initial, sums))


def _at_edges(family: Family, full, xi_x, xi_y, kappa, sigma, coherent: bool):
    """The run's sum ``full`` (field or intensity), at an edge the sum over its tracks in reach instead
    (:func:`_edge_sum`; docs/model.md §3.5, Edges): each track a whole line across the window, its windowed
    groove transform (:func:`.segment.cross_section`, as the scan's) times the Gaussian along."""
    nu_par = xi_x * family.dx + xi_y * family.dy
    nu_perp = xi_y * family.dx - xi_x * family.dy
    kind = type(xi_x)
    zero = dr.zeros(mi.Float)

    def track(a):  # (c and length: not read across)
        return SegmentGeometry(c=zero, length=zero, a_perp=a, dx=family.dx, dy=family.dy, width=family.width,
                               depth=family.depth, triangular=family.triangular)

    if coherent:
        along = math.sqrt(2.0 * math.pi) * sigma * dr.exp((-2.0 * math.pi ** 2) * sigma * sigma * nu_par * nu_par)

        def term(a):
            s = cross_section(track(a), nu_perp, kappa, sigma, True)
            return kind(s.re * along), kind(s.im * along)

        re, im = _edge_sum(family, term, (full.re, full.im))
        return Cx(dr.select(family.edge, re, full.re), dr.select(family.edge, im, full.im))
    along2 = (2.0 * math.pi) * sigma * sigma * dr.exp((-4.0 * math.pi ** 2) * sigma * sigma * nu_par * nu_par)

    def term(a):
        return (kind(cross_section(track(a), nu_perp, kappa, sigma, False).abs2() * along2),)

    return dr.select(family.edge, _edge_sum(family, term, (full,))[0], full)


def _run_intensity(family: Family, pitch, dx, dy, xi_x, xi_y, kappa, sigma, cut=None):
    """One run's ``Σ_n |S'_n(ξ)|²`` (:func:`family_intensity`).  ``cut = (l_x, l_y, h)``: only the half-plane
    y·l >= h of each track (y = x - x0).  Track n then ends where it meets the line, at a point that
    moves along it with the track's offset a: its along factor |Φ|² is averaged over a with the
    weight e^{-a²/σ²} of the tracks' squared window across (Gauss–Hermite again).  That leaves out
    |A'(ν⊥; a)|²'s own shape in a: its spread, of order (W/σ)² tan²θ (θ the line's angle to the tracks'
    normal), and its odd part (V-grooves), of order tan θ (docs/model.md §3.5)."""
    nu_par = xi_x * dx + xi_y * dy
    nu_perp = xi_y * dx - xi_x * dy
    spread = 1.0 / (2.0 * math.pi) * dr.rcp(sigma)  # √2 × the std of η
    kind = type(xi_x)

    def average(nodes, weights):
        def rule(nu_perp, kappa):
            total = dr.zeros(kind)
            for node, weight in zip(nodes, weights):
                total += weight * _groove_intensity(family, nu_perp + node * spread, kappa)
            return (kind(total),)
        return rule

    def across_tracks(nu_perp, kappa):
        # (the 2-point rule where it is as exact as the scan's own sums: half the groove transforms; whole
        # SIMD packets of narrow grooves skip the 4-point one)
        narrow = family.width <= NARROW_GROOVE_SIGMAS * sigma
        across = dr.if_stmt((nu_perp, kappa), narrow, average(HERMITE_NODES_2, HERMITE_WEIGHTS_2),
                            average(HERMITE_NODES, HERMITE_WEIGHTS), label="scratch_family_across")[0]
        return across * (sigma * dr.rcp(pitch))

    if cut is None:
        along = (2.0 * math.pi) * sigma * sigma * dr.exp((-4.0 * math.pi ** 2) * sigma * sigma * nu_par * nu_par)
        # off the tracks' diffraction line (ν∥ beyond ~1.6/σ: most light samples of a world emitter) the along
        # factor is 0 in float32 at every wavelength: whole SIMD packets there skip the groove transforms
        positive = along > 0.0
        lit = positive if dr.depth_v(positive) == 1 else functools.reduce(operator.or_, positive)
        return dr.if_stmt((nu_perp, kappa, along), lit,
                          lambda nu_perp, kappa, along: (kind(across_tracks(nu_perp, kappa) * along),),
                          lambda nu_perp, kappa, along: (dr.zeros(kind),), label="scratch_family_lit")[0]
    across = across_tracks(nu_perp, kappa)
    l_x, l_y, h = cut
    l_t = l_x * dx + l_y * dy  # |l·t| >= KINK_MIN_COS
    l_n = l_y * dx - l_x * dy  # l·n, n = (-dy, dx)
    forward = l_t > 0.0  # the kept part of a track: s >= its end (forward) or s <= it
    inv_l_t = dr.rcp(l_t)
    along = dr.zeros(type(xi_x))
    for node, weight in zip(HERMITE_NODES, HERMITE_WEIGHTS):
        end = (h - (node * sigma) * l_n) * inv_l_t  # where the track at offset a = σ·node meets the line
        phi = window_integral(dr.select(forward, end, -_FAR), dr.select(forward, _FAR, end), nu_par, sigma)
        along += weight * phi.abs2()
    return across * along * (1.0 / math.sqrt(math.pi))


#: Beyond any window (µm): an open end of an integral along a track (window_integral clamps it to 8σ).
_FAR = 1e30


def _run_field(family: Family, pitch, dx, dy, a0, xi_x, xi_y, kappa, sigma, cut=None) -> Cx:
    """One run's ``Σ_n S_n(ξ)``: the order nearest to the window's peak, and its two neighbours where
    σ < ``ONE_ORDER_SIGMA_PER_PITCH`` P (beyond, they lie more than 0.9/σ away: below e^-16 of the
    window's peak).  ``cut = (l_x, l_y, h)``: only the half-plane y·l >= h of the run (y = x - x0)."""
    nu_par = xi_x * dx + xi_y * dy
    nu_perp = xi_y * dx - xi_x * dy
    sigma2 = sigma * sigma
    gauss = math.sqrt(2.0 * math.pi) * sigma
    inv_pitch = dr.rcp(pitch)
    if cut is None:
        along = gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * nu_par * nu_par)
        nearest = dr.round(-nu_perp * pitch)
        spacing = 1.0
    else:
        # an order's frequency K = ν∥ t + (ν⊥ + m/P) n has the components k_l along l (cut: the half-plane
        # integral) and k_c along the line (whole: a Gaussian); the orders lie |l·t|/P apart in k_c
        l_x, l_y, h = cut
        l_t = l_x * dx + l_y * dy  # = l⊥·n, l⊥ = (-l_y, l_x), n = (-dy, dx); |l·t| >= KINK_MIN_COS
        l_n = l_y * dx - l_x * dy  # l·n = -(l⊥·t)
        nearest = dr.round(-(nu_perp - nu_par * l_n * dr.rcp(l_t)) * pitch)
        spacing = dr.abs(l_t)

    def order_term(order):
        mu = order * inv_pitch
        eta = nu_perp + mu
        phase = expi((2.0 * math.pi) * order * a0 * inv_pitch)
        if cut is None:  # (the along factor is common to all orders: applied once, below)
            window = gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * eta * eta)
            return groove_transform(family, mu, kappa) * phase * window
        k_l = nu_par * l_t + eta * l_n
        k_c = eta * l_t - nu_par * l_n
        window = _half_plane(k_l, h, sigma) * (gauss * dr.exp((-2.0 * math.pi ** 2) * sigma2 * k_c * k_c))
        return groove_transform(family, mu, kappa) * phase * window

    def neighbours(nearest):
        both = order_term(nearest - 1.0) + order_term(nearest + 1.0)
        return type(nearest)(both.re), type(nearest)(both.im)

    def none(nearest):
        return dr.zeros(type(nearest)), dr.zeros(type(nearest))

    wide = sigma * spacing < ONE_ORDER_SIGMA_PER_PITCH * pitch
    total = order_term(nearest) + Cx(*dr.if_stmt((nearest,), wide, neighbours, none, label="scratch_family_orders"))
    return total * (inv_pitch if cut is not None else along * inv_pitch)


def _half_plane(k, h, sigma) -> Cx:
    """``∫_{α >= h} e^{-α²/2σ²} e^{HALF_PLANE_SIGN 2πikα} dα``: the window across a kink line, cut at h.

    ``σ√(π/2) e^{-h²/2σ²} e^{2πikh} w((2πσ²k + ih)/(√2σ))`` for h >= 0 (Faddeeva's w, bounded in the
    upper half plane), and the whole integral ``σ√(2π) e^{-2π²σ²k²}`` less the mirrored one for h < 0
    (docs/model.md §3.5)."""
    k = k * HALF_PLANE_SIGN
    positive = h >= 0.0
    distance = dr.abs(h)
    flipped = dr.select(positive, k, -k)
    inv = dr.rcp(math.sqrt(2.0) * sigma)
    w = faddeeva(Cx((2.0 * math.pi) * sigma * sigma * flipped * inv, distance * inv))
    part = w * expi((2.0 * math.pi) * k * h) * (math.sqrt(0.5 * math.pi) * sigma
                                                 * dr.exp(-0.5 * dr.square(distance / sigma)))
    whole = math.sqrt(2.0 * math.pi) * sigma * dr.exp((-2.0 * math.pi ** 2) * sigma * sigma * k * k)
    return Cx(dr.select(positive, part.re, whole - part.re), dr.select(positive, part.im, -part.im))


def run_energies(family: Family, sigma):
    """``(A, B)``: ``Σ_n ε_n`` of :func:`.sampling.window_energy` over each run (Poisson summation of
    e^{-a_n²/σ²}); at a kink each is cut to its side of the line (the
    squared window's share there, ½ erfc(±h/σ)), elsewhere B is 0."""
    a = _run_energy(family, family.pitch, family.a0, sigma)
    # at an edge: each track in reach a whole line, ε = W σ√π e^{-a²/σ²} (sampling.window_energy)
    inv = dr.rcp(sigma)
    edge = _edge_sum(family, lambda t: (family.width * math.sqrt(math.pi) * sigma * dr.exp(-dr.square(t * inv)),),
                     (a,))[0]
    a = dr.select(family.edge, edge, a)
    if family.kink is None:
        return a, dr.zeros(mi.Float)
    side = 0.5 - 0.5 * dr.erf(family.h * dr.rcp(sigma))  # share of w² on A's side, y·l >= h
    b = _run_energy(family, family.b_pitch, family.b_a0, sigma)
    return dr.select(family.kink, a * side, a), dr.select(family.kink & ~family.lone, b * (1.0 - side), 0.0)


def _run_energy(family: Family, pitch, a0, sigma):
    ratio = sigma * dr.rcp(pitch)
    tracks = math.sqrt(math.pi) * ratio * (1.0 + 2.0 * dr.exp(-(math.pi ** 2) * ratio * ratio)
                                           * dr.cos((2.0 * math.pi) * a0 * dr.rcp(pitch)))
    return family.width * math.sqrt(math.pi) * sigma * tracks
