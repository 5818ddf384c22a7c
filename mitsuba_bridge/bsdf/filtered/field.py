"""The footprint's expectation of ``|U|²`` piece by piece and pair by pair (docs/model.md §11).

    E|U|² = |U0|² + 2 U0 Re Σ_k E[S_k] + Σ_k E|S_k|² + 2 Re Σ_{k<l} E[S_k S_l*]

(U0 is real and does not depend on the window's position).  :func:`piece_terms` gives a piece's
mean amplitude (:mod:`.mean_field`) and intensity (:mod:`.single`, its share of its straight run);
:func:`pair_term` the interference of two pieces (:mod:`.pairs`): crossing pairs, nearly parallel
ones, nothing for pieces of one run (their shares carry it) or pieces too far apart to share a
window.  Units: µm, 1/µm.
"""
from __future__ import annotations

import math

import drjit as dr

from ..maths.complexmath import Cx
from ..maths.segment import SegmentGeometry
from .along import TAIL_ABOVE
from .footprint import Footprint, projected
from .mean_field import mean_amplitude
from .pairs import PARALLEL_BELOW, crossing_pair, crossing_point, parallel_pair
from .single import segment_intensity

__all__ = ["piece_terms", "pair_term", "COHERENT_SIGMAS", "MIRROR_NEGLIGIBLE"]

#: Pieces whose centre lines stay farther apart than this (in σ) inside the footprint do not interfere
#: (their pair factor e^{-|d|²/4σ²} is below e^{-9}).
COHERENT_SIGMAS = 6.0
#: A piece's ends count for its tails within this many standard deviations of the footprint along it.
ENDS_REACH_STDS = 4.0
#: The mirror lobe's amplitude relative to its peak below which its cross term is skipped (SIMD packets).
MIRROR_NEGLIGIBLE = 1e-6
#: End points closer than this (µm) make two pieces consecutive (parallel.JOINED_UM).
JOINED_UM = 1e-2
#: Footprints whose smaller standard deviation (the sample's radius r) exceeds this (in σ) leave crossing pairs
#: out: a crossing's pair term shrinks as σ/r against the two grooves' intensity (the crossing's share of their
#: length in the footprint).  Measured on the diffraction lines of two grooves crossing at the footprint's
#: centre, the scratches' part of f_r loses 4.6 % / 2.4 % / 1.6 % at r = 4σ / 8σ / 12σ seen from 20°, 1.25×
#: that from 50° (the footprint stretched by 1/cos θ_i): about 1 % at 20σ (docs/model.md §11.5).
CROSSING_PAIRS_BELOW = 20.0
#: Pieces this parallel whose lines lie within JOINED_UM of each other lie on one line.
SAME_LINE_SINE = 1e-4


def piece_terms(segment: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z, sigma, lobe, coherent: bool,
                runs=None, across_nodes: int = 3):
    """``(E[S_k] (complex, zero where the mirror lobe is negligible or not coherent), E|S_k|² or the run share)``."""
    spectrum = type(xi_x)
    zero = dr.zeros(spectrum)
    # far off the piece's diffraction line at every wavelength only its ends' tails remain: nothing where
    # its run's ends lie beyond the footprint's reach (whole SIMD packets skip the piece then)
    nu_par = xi_x * segment.dx + xi_y * segment.dy
    off_line = ((4.0 * math.pi) * sigma) * dr.abs(nu_par) > TAIL_ABOVE
    var_t, _, _ = projected(footprint, segment.dx, segment.dy)
    reach = ENDS_REACH_STDS * dr.sqrt(var_t + sigma * sigma)
    before, after = (0.0, 0.0) if runs is None else runs
    ends_near = (dr.abs(segment.c - before) < reach) | (dr.abs(segment.c + segment.length + after) < reach)
    relevant = ends_near | ~_all_wavelengths(off_line)
    intensity = dr.if_stmt((xi_x, xi_y, k_z), relevant,
                           lambda xi_x, xi_y, k_z: spectrum(segment_intensity(segment, footprint, xi_x, xi_y, k_z,
                                                                             sigma, coherent, runs, across_nodes)),
                           lambda *_: zero, label="scratch_filtered_piece")
    if not coherent:
        return Cx(zero, zero), intensity
    near = dr.max(lobe) > MIRROR_NEGLIGIBLE * (2.0 * math.pi) * sigma * sigma

    def mean(xi_x, xi_y, k_z):
        s = mean_amplitude(segment, footprint, xi_x, xi_y, k_z, sigma)
        return spectrum(s.re), spectrum(s.im)

    re, im = dr.if_stmt((xi_x, xi_y, k_z), near, mean, lambda *_: (zero, zero), label="scratch_filtered_mean")
    return Cx(re, im), intensity


def _all_wavelengths(mask):
    result = mask[0]
    for k in range(1, len(mask)):
        result = result & mask[k]
    return result


def ends(segment: SegmentGeometry):
    """Start and end point relative to x0 (local frame)."""
    nx, ny = -segment.dy, segment.dx
    sx = segment.c * segment.dx + segment.a_perp * nx
    sy = segment.c * segment.dy + segment.a_perp * ny
    return sx, sy, sx + segment.length * segment.dx, sy + segment.length * segment.dy


def pair_term(first: SegmentGeometry, second: SegmentGeometry, footprint: Footprint, xi_x, xi_y, k_z, sigma,
              active=True, across_nodes: int = 3):
    """``2 Re E[S_1 S_2*]`` of two pieces of the footprint (zero where they do not interfere), per wavelength."""
    spectrum = type(xi_x)
    zero = dr.zeros(spectrum)
    s1x, s1y, e1x, e1y = ends(first)
    s2x, s2y, e2x, e2y = ends(second)
    joined = ((dr.square(e1x - s2x) + dr.square(e1y - s2y) < JOINED_UM ** 2)
              | (dr.square(e2x - s1x) + dr.square(e2y - s1y) < JOINED_UM ** 2))
    x, y, sine = crossing_point(first, second)
    parallel = dr.abs(sine) < PARALLEL_BELOW
    # crossing: the crossing point inside both pieces (a cut run's crossing belongs to one of its pieces)
    along_1 = (x * first.dx + y * first.dy - first.c) * dr.rcp(first.length)
    along_2 = (x * second.dx + y * second.dy - second.c) * dr.rcp(second.length)
    inside = (along_1 >= 0.0) & (along_1 < 1.0) & (along_2 >= 0.0) & (along_2 < 1.0)
    reach = COHERENT_SIGMAS * sigma
    # nearly parallel: the second's centre line within reach of the first's somewhere along both
    offset_start = (s2x - s1x) * -first.dy + (s2y - s1y) * first.dx
    offset_end = (e2x - s1x) * -first.dy + (e2y - s1y) * first.dx
    close = (dr.minimum(dr.abs(offset_start), dr.abs(offset_end)) < reach + 0.5 * (first.width + second.width)) \
        | (offset_start * offset_end < 0.0)
    # pieces of one line (a run cut into pieces, a straight polyline): their interference is their shares'
    same_line = (dr.abs(sine) < SAME_LINE_SINE) & (dr.abs(offset_start) < JOINED_UM)
    # (crossing pairs weigh ~ σ/footprint against the pieces' own terms, and only near the mirror direction:
    # footprints wider than CROSSING_PAIRS_BELOW σ leave them out, docs/model.md §11.5)
    narrow = footprint.smallest_variance < (CROSSING_PAIRS_BELOW * sigma) ** 2
    crossing = mask(active) & ~parallel & inside & ~joined & narrow
    beside = mask(active) & parallel & close & ~same_line

    def closed_form(xi_x, xi_y, k_z):
        return spectrum(2.0 * crossing_pair(first, second, footprint, xi_x, xi_y, k_z, sigma).re)

    term = dr.if_stmt((xi_x, xi_y, k_z), crossing, closed_form, lambda *_: zero, label="scratch_filtered_crossing")
    side = dr.if_stmt((xi_x, xi_y, k_z), beside,
                      lambda xi_x, xi_y, k_z: spectrum(2.0 * parallel_pair(first, second, footprint, xi_x, xi_y, k_z,
                                                                           sigma, across_nodes)),
                      lambda *_: zero, label="scratch_filtered_parallel_pair")
    return spectrum(dr.select(crossing, term, 0.0) + dr.select(beside, side, 0.0))


def mask(value):
    import mitsuba as mi
    return mi.Bool(value) if isinstance(value, bool) else value
