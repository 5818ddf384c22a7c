"""Height-field correction of nearly parallel overlapping pieces (Dr.Jit side; docs/model.md §3.4).

The crossing pairs of :mod:`.overlap` are the pairs the tables list: centre lines
that cross inside both pieces at ``|sin θ| >= crossings.MIN_SINE`` (UV).  Two
nearly parallel scratches (``|sin θ| < MIN_SINE`` in UV, parallel ones included)
overlap along a sliver whose shape the pieces' ends and widths decide, and the
tables cannot list them: whether two strips a few µm wide overlap depends on
the UV Jacobian, known only per shading point.  So the kernel pairs the pieces
it finds in the window itself: :func:`add_parallel_overlaps` tests each new
piece against the last ``RECENT_PIECES`` found before it (every pair of a
window holding at most RECENT_PIECES + 1 pieces; in a fuller window a pair
further apart in the scan's order is left additive).

The correction is the one of every overlap of two scratches,

    C(ξ) = -∫_O (e^{ik_z min(h_1, h_2)} - 1) w(x) e^{-2πiξ·x} dx,

over O = R_1 ∩ R_2, R_k the piece's rectangle (its strip between its square
ends).  O is cut along the first piece into slabs of at most σ/2 where it lies
in the window (|t| <= R along the first piece, from x0's foot point), each slab
across into at most MAX_ACROSS slabs of at most σ/2 covering where the second
strip meets the first there, and on a V-groove into its two sides.  Each cell
∩ the second strip ∩ its ends is a convex polygon, integrated with the window
expanded at the cell centre (:func:`.polygon.clipped_cell`).  Where a V-groove
takes part its depth is a plane on each side (the second one's strip is taken
half by half), and the line h_1 = h_2 splits the polygon into two, each with
its depth's phase as a shift of the frequency (as in
:func:`.overlap._sloped_correction`).

**Bunches.**  Three mutually nearly parallel pieces (no crossing pair for
:mod:`.triples` to find their overlap from) get the term of order 3,
``+(e^{iκ_min} - 1) ∫`` over the overlap of the three rectangles, when the
last of them is found with the other two among the recent pieces: the new
piece's pair cells clipped by the third rectangle too (flat bottoms only).
Their piles of four and more stay uncorrected (docs/model.md §3.4 bounds them).

Pairs left alone (additive): consecutive pieces of one polyline or run (they
share an end point) and pieces found more than RECENT_PIECES apart; so are
the triples of a bunch with such a pair or with a V-groove.  The overlaps of
three or more that hold a nearly parallel pair and a crossing pair are
:mod:`.triples`' (found from the crossing pair).  Lengths in µm.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from ..maths.complexmath import Cx, expi
from ..tables.crossings import MIN_SINE
from ..lookup import Grid, LocalJacobian, segment_at
from .overlap import below, depth_plane
from ..maths.polygon import Strip, clipped_cell
from ..maths.segment import SegmentGeometry, flat_bottomed

__all__ = ["RECENT_PIECES", "SUB_EDGE_SIGMAS", "MAX_ALONG", "MAX_ACROSS", "add_parallel_overlaps",
           "parallel_correction", "piece_ends", "consecutive"]

#: Pieces of the window each new one is paired with (the loop state holds their indices).
RECENT_PIECES = 8
#: Cells are at most this many σ long and wide, as the crossings' (overlap.SUB_EDGE_SIGMAS).  An overlap can
#: be a whole piece inside the window (a duplicated scratch), whose correction must then cancel the piece's
#: exact amplitude: a duplicate against the scratch alone, σ = 2 µm, 550 nm, 40°, was 2.4 % off in f_r with
#: cells of σ/2, 0.31 % with σ/4 and 0.02 % with σ/8, but with σ/4 the term made a crossed plate's queries
#: 2.38× as slow instead of 1.49× (docs/bsdf.md, Cost).
SUB_EDGE_SIGMAS = 0.5
#: Most slabs along the overlap (the window is 2R = 8σ long: 16 slabs of σ/2).
MAX_ALONG = 16
#: Most slabs across it (an overlap wider than 2σ gets wider cells).
MAX_ACROSS = 4
#: Cells reach this many σ past the bounds the second piece's strips set (polygon edges never lie on two lines).
PAD_SIGMAS = 1e-3
#: End points closer than this (µm) make two pieces consecutive (float32 positions: ~1e-4 µm).
JOINED_UM = 1e-2


def add_parallel_overlaps(grid: Grid, jac: LocalJacobian, piece, segment: SegmentGeometry, seen, recent: tuple,
                          xi_x, xi_y, k_z, sigma, radius, field, with_triples: bool = True):
    """Add the corrections of ``piece`` with the pieces found before it in the window.

    ``seen``: how many pieces the window's scan has found so far; ``recent``: the last RECENT_PIECES of
    them (slot ``k`` holds the one found ``k`` mod RECENT_PIECES).  ``with_triples``: the threefold
    overlaps of the piece with two of them, all three mutually nearly parallel, too (flat bottoms; module
    docstring).  Returns ``(seen, recent, field)`` with the piece recorded."""
    spectrum = type(xi_x)
    tail = dr.gather(mi.Vector4f, grid.segments, 2 * piece + 1)
    own_ends = piece_ends(segment)  # (the same for every slot)

    def recent_piece(slot):
        found = recent[-1]
        for k in range(len(recent) - 2, -1, -1):
            found = dr.select(slot == k, recent[k], found)
        return found, dr.gather(mi.Vector4f, grid.segments, 2 * found + 1)

    def step(slot, overlapping, re, im):
        other, other_tail = recent_piece(slot)
        candidate = nearly_parallel(tail, other_tail)  # the complement of the tables' pairs (crossings.py), in UV
        first = segment_at(grid, jac, other, candidate)
        paired = candidate & ~consecutive(piece_ends(first), own_ends)
        span = overlap_span(first, segment, sigma, radius, paired)
        c = parallel_correction(first, segment, xi_x, xi_y, k_z, sigma, radius, paired, span=span)
        # the slots whose pair overlaps, for the triples below
        overlapping = dr.select(span.active, overlapping | (mi.UInt32(1) << slot), overlapping)
        return slot + 1, overlapping, spectrum(re + c.re), spectrum(im + c.im)

    slots = dr.minimum(seen, len(recent))
    _, overlapping, re, im = dr.while_loop((dr.zeros(mi.UInt32), dr.zeros(mi.UInt32), field[0], field[1]),
                                           lambda slot, overlapping, re, im: slot < slots, step,
                                           label="scratch_parallel_pairs")
    if with_triples:  # two overlapping slots nearly parallel to each other: the threefold overlap, once
        count = len(recent)

        def advance(later, earlier_bits):
            """The next slot ``later`` whose pair overlaps and that has overlapping slots below it (the rest of
            them in ``earlier_bits``), where ``earlier_bits`` is used up; ``count`` and 0 after the last."""
            def next_later(later, earlier_bits):
                above = overlapping & ~((mi.UInt32(2) << later) - 1)
                later = dr.select(above != 0, dr.tzcnt(above), count)
                return later, dr.select(above != 0, overlapping & ((mi.UInt32(1) << later) - 1), 0)

            return dr.while_loop((later, earlier_bits), lambda later, bits: (bits == 0) & (later < count),
                                 next_later, label="scratch_parallel_triple_next")

        def triple_step(later, earlier_bits, re, im):
            earlier = dr.tzcnt(earlier_bits)
            first_piece, first_tail = recent_piece(later)
            third_piece, third_tail = recent_piece(earlier)
            first, third = segment_at(grid, jac, first_piece, True), segment_at(grid, jac, third_piece, True)
            third_ends = piece_ends(third)
            usable = (nearly_parallel(first_tail, third_tail) & ~consecutive(third_ends, own_ends)
                      & ~consecutive(third_ends, piece_ends(first)))
            c = parallel_correction(first, segment, xi_x, xi_y, k_z, sigma, radius, usable, third)
            later, earlier_bits = advance(later, earlier_bits & (earlier_bits - 1))
            return later, earlier_bits, spectrum(re + c.re), spectrum(im + c.im)

        lowest = dr.select(overlapping != 0, dr.tzcnt(overlapping), count)  # (no slot below it)
        later, earlier_bits = advance(lowest, dr.zeros(mi.UInt32))
        _, _, re, im = dr.while_loop((later, earlier_bits, re, im), lambda later, bits, re, im: bits != 0,
                                     triple_step, label="scratch_parallel_triples")
    here = seen % len(recent)
    recent = tuple(dr.select(here == k, piece, recent[k]) for k in range(len(recent)))
    return seen + 1, recent, (re, im)


def nearly_parallel(tail, other_tail):
    """Whether two pieces' UV directions (their rows' tails) make |sin θ| < MIN_SINE: no pair of the tables."""
    cross = tail.x * other_tail.y - tail.y * other_tail.x
    norms = dr.sqrt((tail.x * tail.x + tail.y * tail.y) * (other_tail.x * other_tail.x + other_tail.y * other_tail.y))
    return dr.abs(cross) < MIN_SINE * norms


def piece_ends(segment: SegmentGeometry):
    """Start and end point relative to x0 (local frame)."""
    nx, ny = -segment.dy, segment.dx
    sx = segment.c * segment.dx + segment.a_perp * nx
    sy = segment.c * segment.dy + segment.a_perp * ny
    return sx, sy, sx + segment.length * segment.dx, sy + segment.length * segment.dy


def consecutive(first_ends, second_ends):
    """Whether one piece ends where the other starts (consecutive pieces of a polyline or of a cut run);
    the arguments are :func:`piece_ends` of the two pieces."""
    s1x, s1y, e1x, e1y = first_ends
    s2x, s2y, e2x, e2y = second_ends
    limit = JOINED_UM * JOINED_UM
    return ((dr.square(e1x - s2x) + dr.square(e1y - s2y) < limit)
            | (dr.square(e2x - s1x) + dr.square(e2y - s1y) < limit))


def parallel_correction(first: SegmentGeometry, second: SegmentGeometry, xi_x, xi_y, k_z, sigma, radius,
                        active, third: SegmentGeometry | None = None, span: OverlapSpan | None = None) -> Cx:
    """``C(ξ)`` of the overlap of two nearly parallel pieces within ``radius`` of x0 along the first
    (module docstring), per wavelength; zero where they do not overlap there or ``active`` is False.

    With ``third`` (a piece nearly parallel to both), the term of order 3 of the overlap of all three
    instead, ``+(e^{iκ_min} - 1) ∫``: the pair's cells clipped by the third piece's rectangle too; flat
    bottoms only (zero where a V-groove takes part).  ``span``: :func:`overlap_span` of the pair with the same
    ``active``, where the caller has it."""
    spectrum = type(xi_x)
    if third is not None:
        active = active & flat_bottomed(first.triangular | second.triangular | third.triangular)
    ax, ay = first.dx, first.dy
    nx, ny = -ay, ax
    bx, by = second.dx, second.dy
    if span is None:
        span = overlap_span(first, second, sigma, radius, active)
    active, t_lo, t_hi, t_b0, u_b0, slope, half_b, pad, sine = span
    half_a = 0.5 * first.width
    sub_edge = SUB_EDGE_SIGMAS * sigma
    along = dr.select(active, dr.clip(dr.ceil((t_hi - t_lo) / sub_edge), 1.0, MAX_ALONG), 0.0)
    step_t = (t_hi - t_lo) / dr.maximum(along, 1.0)
    widest = dr.minimum(first.width, 2.0 * half_b + dr.abs(slope) * step_t)
    across = dr.clip(dr.ceil(widest / sub_edge), 1.0, MAX_ACROSS)
    sides = dr.select(first.triangular, 2.0, 1.0)
    halves = dr.select(second.triangular, 2.0, 1.0)
    grooved = first.triangular | second.triangular
    cells = mi.UInt32(along * sides * across)
    flat_cells = dr.select(grooved, 0, cells)
    sloped_cells = dr.select(grooved, cells * mi.UInt32(halves), 0)
    across_u, sides_u, halves_u = mi.UInt32(across), mi.UInt32(sides), mi.UInt32(halves)

    def cell(index):
        """Centre (local frame) and half sizes of cell ``index`` (row-major: slab along, side, slab across)."""
        j = index % across_u
        rest = index // across_u
        side = rest % sides_u
        k = rest // sides_u
        t0 = t_lo + mi.Float(k) * step_t
        t1 = t0 + step_t
        u_at0, u_at1 = u_b0 + (t0 - t_b0) * slope, u_b0 + (t1 - t_b0) * slope
        u_lo = dr.maximum(first.a_perp - half_a, dr.minimum(u_at0, u_at1) - half_b - pad)
        u_hi = dr.minimum(first.a_perp + half_a, dr.maximum(u_at0, u_at1) + half_b + pad)
        # a V-groove's sides: its depth is a plane on each
        on_low_side = first.triangular & (side == 0)
        on_high_side = first.triangular & (side == 1)
        u_hi = dr.select(on_low_side, dr.minimum(u_hi, first.a_perp), u_hi)
        u_lo = dr.select(on_high_side, dr.maximum(u_lo, first.a_perp), u_lo)
        step_u = dr.maximum(u_hi - u_lo, 0.0) / across
        u_mid = u_lo + (mi.Float(j) + 0.5) * step_u
        t_mid = 0.5 * (t0 + t1)
        return t_mid * ax + u_mid * nx, t_mid * ay + u_mid * ny, 0.5 * step_t, 0.5 * step_u

    def polygon(cx, cy, half_t, half_u, side=None):
        """The cell ∩ the second strip (on a V-groove its half on ``side``) ∩ its ends, offsets from the
        centre c (the cell lies within the first strip; where the second's bounds set its edges, padded)."""
        mx, my = -by, bx
        level, half_w = second.a_perp, 0.5 * second.width
        if side is not None:  # half of a V-groove: |n·x - a⊥ - side W/4| <= W/4
            level = dr.select(second.triangular, level + side * (0.25 * second.width), level)
            half_w = dr.select(second.triangular, 0.25 * second.width, half_w)
        middle = second.c + 0.5 * second.length
        strips = [Strip(ax, ay, 0.0, half_t), Strip(nx, ny, 0.0, half_u),
                  Strip(mx, my, level - (mx * cx + my * cy), half_w),
                  Strip(bx, by, middle - (bx * cx + by * cy), 0.5 * second.length)]
        if third is not None:  # the third rectangle: its strip and its ends
            px, py = -third.dy, third.dx
            strips += [Strip(px, py, third.a_perp - (px * cx + py * cy), 0.5 * third.width),
                       Strip(third.dx, third.dy, third.c + 0.5 * third.length - (third.dx * cx + third.dy * cy),
                             0.5 * third.length)]
        return strips

    def flat_step(index, re, im):
        cx, cy, half_t, half_u = cell(index)
        term = clipped_cell(polygon(cx, cy, half_t, half_u), cx, cy, xi_x, xi_y, sigma)
        return index + 1, spectrum(re + term.re), spectrum(im + term.im)

    scale = k_z * (1.0 / (2.0 * math.pi))

    def sloped_step(index, re, im):
        cx, cy, half_t, half_u = cell(index // halves_u)
        side = dr.select(second.triangular & (index % halves_u == 0), -1.0, 1.0)
        h1, g1x, g1y = depth_plane(first, cx, cy)
        h2, g2x, g2y = depth_plane(second, cx, cy, side)
        region = polygon(cx, cy, half_t, half_u, side)
        lower_half = below((h1, g1x, g1y), (h2, g2x, g2y), 2.0 * (half_t + half_u))  # h_1 <= h_2
        upper_half = Strip(-lower_half.nx, -lower_half.ny, -lower_half.offset)
        phase1, phase2 = k_z * (h1 - g1x * cx - g1y * cy), k_z * (h2 - g2x * cx - g2y * cy)
        lower = clipped_cell(region + [lower_half], cx, cy, spectrum(xi_x - scale * g1x), spectrum(xi_y - scale * g1y),
                             sigma)
        upper = clipped_cell(region + [upper_half], cx, cy, spectrum(xi_x - scale * g2x), spectrum(xi_y - scale * g2y),
                             sigma)
        term = expi(phase1) * lower + expi(phase2) * upper - clipped_cell(region, cx, cy, xi_x, xi_y, sigma)
        return index + 1, spectrum(re - term.re), spectrum(im - term.im)

    zero = dr.zeros(spectrum)
    _, re, im = dr.while_loop((mi.UInt32(0), zero, zero), lambda index, re, im: index < flat_cells, flat_step,
                              label="scratch_parallel" if third is None else "scratch_parallel_triple")
    if third is not None:  # order 3: + (e^{iκ_min} - 1) ∫ over the threefold overlap
        return (expi(k_z * dr.minimum(dr.minimum(first.depth, second.depth), third.depth)) - 1.0) * Cx(re, im)
    shallow = k_z * dr.minimum(first.depth, second.depth)
    flat = -((expi(shallow) - 1.0) * Cx(re, im))
    _, re, im = dr.while_loop((mi.UInt32(0), zero, zero), lambda index, re, im: index < sloped_cells, sloped_step,
                              label="scratch_parallel_sloped")
    return flat + Cx(re, im)


class OverlapSpan(NamedTuple):
    """Where two nearly parallel pieces overlap along the first (:func:`overlap_span`)."""

    active: object  #: whether they overlap within the window
    t_lo: object  #: the overlap's extent along the first, from x0's foot point (µm)
    t_hi: object
    t_b0: object  #: the second's start in the first's frame: along, across
    u_b0: object
    slope: object  #: du/dt of the second centre line in the first's frame
    half_b: object  #: the second strip's half extent across, at fixed t
    pad: object  #: the padding of bounds the second piece sets
    sine: object  #: n_1·d_2


def overlap_span(first: SegmentGeometry, second: SegmentGeometry, sigma, radius, active) -> OverlapSpan:
    """The t-range (along the first, |t| <= ``radius``) where the rectangles of two nearly parallel pieces
    overlap (module docstring); ``active`` False where they do not."""
    ax, ay = first.dx, first.dy
    nx, ny = -ay, ax
    bx, by = second.dx, second.dy
    cosine = ax * bx + ay * by
    sine = ax * by - ay * bx  # n_1·d_2
    active = active & (dr.abs(cosine) > 0.5)  # (a strongly sheared UV map: no longer nearly parallel here)
    cosine = dr.select(active, cosine, 1.0)
    slope = sine / cosine  # du/dt of the second centre line in the first's frame
    # the second's start in the first's frame (t along d_1 from x0's foot point, u across)
    b0x, b0y, _, _ = piece_ends(second)
    t_b0, u_b0 = ax * b0x + ay * b0y, nx * b0x + ny * b0y
    t_b1 = t_b0 + second.length * cosine
    half_b = 0.5 * second.width / dr.abs(cosine)  # the second strip's half extent across, at fixed t
    reach = 0.5 * first.width + half_b
    # t where the strips meet: |u_2(t) - a⊥_1| <= reach
    flat = dr.abs(slope) < 1e-7
    inv_slope = dr.rcp(dr.select(flat, 1.0, slope))
    meet1 = t_b0 + (first.a_perp - reach - u_b0) * inv_slope
    meet2 = t_b0 + (first.a_perp + reach - u_b0) * inv_slope
    always = dr.abs(u_b0 - first.a_perp) <= reach
    far = 1e30
    meet_lo = dr.select(flat, dr.select(always, -far, far), dr.minimum(meet1, meet2))
    meet_hi = dr.select(flat, dr.select(always, far, -far), dr.maximum(meet1, meet2))
    # (bounds that come from the second piece are padded: its own strips clip the cells, and a cell edge on
    # one of their lines, computed otherwise, would leave the polygon's edge to rounding; polygon.TIE_UM
    # settles only lines that agree to 1e-5 µm)
    pad = PAD_SIGMAS * sigma
    corner = 0.5 * second.width * dr.abs(sine) + pad  # the second's square ends reach this far past its centre line
    t_lo = dr.maximum(dr.maximum(first.c, dr.minimum(t_b0, t_b1) - corner), dr.maximum(-radius, meet_lo - pad))
    t_hi = dr.minimum(dr.minimum(first.c + first.length, dr.maximum(t_b0, t_b1) + corner),
                      dr.minimum(radius, meet_hi + pad))
    return OverlapSpan(active & (t_hi > t_lo), t_lo, t_hi, t_b0, u_b0, slope, half_b, pad, sine)
