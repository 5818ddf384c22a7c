"""The scratch BRDF averaged over each camera sample's footprint (docs/model.md §11).

:class:`FilteredModel` is the :class:`..model.Model` with a footprint: the expectation of its BRDF
over a Gaussian footprint (:mod:`.footprint`) centred on the shading point,

    E f_r = F [|U0|² + 2 U0 Re Σ_k E[S_k] + Σ_k E|S_k|² + 2 Re Σ_{k<l} E[S_k S_l*]] / (λ²πσ²)

(coherent; incoherent: ``F [|U0|² (1 - E ρ) + Σ_k E|S'_k|²] / (λ²πσ²)``), piece by piece over the
pieces whose centre lines pass within ``REACH_STDS`` standard deviations of the footprint widened
by the window, each pair of them among the last ``RECENT_PIECES`` found (:mod:`.field`).  Lanes
whose footprint is narrower than ``POINT_BELOW_SIGMAS`` σ take the point model itself (the same
values bit for bit where the footprint is zero).  With ``crossings = "height_field"`` the crossings'
corrections are added as the point model has them at the shading point (module docs: not averaged).
Sampling draws a piece in proportion to its footprint-averaged selection weight and then ξ on its
line as the point model does (:mod:`..sampling`), so ``pdf`` is the same mixture over the same
pieces.  Units: µm inside.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi

from .. import sampling
from ..heightfield.overlap import crossing_correction
from ..heightfield.triples import add_triples
from ..lookup import for_each_crossing, for_each_segment, jacobian, replay_pieces, segment_at
from ..maths.complexmath import Cx
from ..maths.segment import SegmentGeometry, amplitude
from ..model import FIND, REPLAY_PIECES, WINDOW_RADIUS_SIGMAS, Model, reservoir_step
from ..periodic import MAX_INCOHERENT_WIDTH_SIGMAS, family_intensity, find_family
from .families import family_energy, family_terms
from .along import _pick
from .field import CROSSING_PAIRS_BELOW, pair_term, piece_terms
from .pairs import PARALLEL_BELOW
from .footprint import Footprint, footprint_of, projected
from .reach import capped_footprint

__all__ = ["FilteredModel", "POINT_BELOW_SIGMAS", "REACH_STDS", "RECENT_PIECES", "filtered_window_energy"]

#: A sample's footprint radius is capped at this many σ, whatever the pieces' density (where they are dense the
#: reach is capped further, :mod:`.reach`; a smaller footprint only filters less, docs/model.md §11.8).
MAX_RADIUS_SIGMAS = 32.0
#: Footprints whose larger standard deviation is below this many σ take the point model.
POINT_BELOW_SIGMAS = 0.05
#: Pieces farther than this many standard deviations of the footprint widened by the window are left out
#: (a piece there weighs at most e^{-REACH²/2} = 2·10⁻³ of one through the centre).
REACH_STDS = 3.5
#: Pieces each new one is paired with (their indices are the loop's state).
RECENT_PIECES = 8


def filtered_window_energy(segment: SegmentGeometry, footprint: Footprint, sigma):
    """``E[ε_k]``: the footprint's mean of the piece's share of the squared window (:func:`..sampling.window_energy`).

    Across, ``E e^{-(a⊥ - u)²/σ²} = σ/√(σ² + 2Σ_uu) e^{-a⊥²/(σ² + 2Σ_uu)}``; along, each ``erf(t/σ)``
    becomes ``erf(t/√(σ² + 2Σ_tt))`` (the marginals: exact for footprints isotropic in the piece's frame).
    """
    var_t, var_u, _ = projected(footprint, segment.dx, segment.dy)
    sigma2 = sigma * sigma
    spread_u, spread_t = sigma2 + 2.0 * var_u, sigma2 + 2.0 * var_t
    inv_t = dr.rsqrt(spread_t)
    along = dr.erf((segment.c + segment.length) * inv_t) - dr.erf(segment.c * inv_t)
    across = sigma * dr.rsqrt(spread_u) * dr.exp(-dr.square(segment.a_perp) * dr.rcp(spread_u))
    return segment.width * across * (0.5 * math.sqrt(math.pi)) * sigma * along


@dataclass
class FilteredModel(Model):
    """:class:`..model.Model` averaged over each sample's footprint (module docstring)."""

    footprint_angle: object = None  #: opaque mi.Float: radians of a camera sample's cone (0: points)
    footprint_width: object = None  #: opaque mi.Float: scene units of an orthographic sample's width
    #: mi.Float, 2 per piece: how far its line runs on straight through other pieces, in its own lengths
    line_continuation: object = None
    #: Gauss–Hermite nodes across a groove (:mod:`.single`): 2 where every groove is at most 1.2σ wide
    across_nodes: int = 3
    #: mi.Float: the grid's per-cell piece densities as summed-area tables (:func:`..tables.density.density_table`);
    #: None: footprints are not capped by density (only by ``MAX_RADIUS_SIGMAS``)
    piece_density: object = None

    # ------------------------------------------------------------ helpers
    def footprint(self, si) -> Footprint:
        """The footprint of the sample at ``si`` (µm², local frame), shrunk where its reach is expected to hold more
        than :data:`.reach.MAX_EXPECTED_PIECES` pieces (docs/model.md §11.8)."""
        footprint = footprint_of(si, self.footprint_angle, self.footprint_width, self.micrometres_per_unit,
                                 MAX_RADIUS_SIGMAS * self.sigma)
        if self.piece_density is None:
            return footprint
        jac = jacobian(si, self.micrometres_per_unit)
        footprint = capped_footprint(footprint, self.grid, self.piece_density, jac, self.sigma, REACH_STDS)
        reach_family = self._footprint_family(jac, footprint, self._reach(footprint), mi.Bool(True))
        if reach_family is None:
            return footprint
        # inside a periodic family whose closed form the footprint's reach loses (an edge or a kink within it, or
        # more than 2 × 2 cells), the point window's closed form instead of every track piece by piece
        window_family = find_family(self.grid, jac, self.sigma, mi.Bool(True))
        point = window_family.eligible & ~reach_family.eligible
        return Footprint(*(dr.select(point, 0.0, part) for part in footprint))

    def _is_point(self, footprint: Footprint):
        return footprint.largest_variance < (POINT_BELOW_SIGMAS * self.sigma) ** 2

    def _footprint_family(self, jac, footprint: Footprint, radius, active):
        """The periodic family whose run fills the footprint's reach (no edge, no kink: those scan), or None
        where the model sums none (docs/model.md §11.6)."""
        if not (self.periodic and self.grid.periodic and self.sums_families(self.coherent, self.depth_phase)):
            return None
        family = find_family(self.grid, jac, self.sigma, active, reach_um=radius)
        plain = family.eligible & ~family.edge
        if family.kink is not None:
            plain &= ~family.kink
        if not self.coherent:
            plain &= family.width <= MAX_INCOHERENT_WIDTH_SIGMAS * self.sigma
        family.eligible = plain
        return family

    def _family_start(self, family, footprint, q, wi, want_value, want_pdf):
        """``(mean, intensity, covered, energy, density)`` a fold starts from where the lane's footprint lies in
        a family: its closed forms (:mod:`.families`), zeros elsewhere (whole SIMD packets skip them)."""
        zero_s, zero_f = dr.zeros(mi.Spectrum), dr.zeros(mi.Float)
        inside = family.eligible
        sigma = self.sigma

        def terms(kz0):
            mean = intensity = zero_s
            covered = energy = density = zero_f
            if want_value and self.coherent:
                mean, intensity = family_terms(family, footprint, q.xi_x, q.xi_y, q.k_z, sigma)
            elif want_value:
                intensity = mi.Spectrum(family_intensity(family, q.xi_x, q.xi_y, q.k_z, sigma))
                covered = family_energy(family, footprint, sigma)
            if want_pdf:
                energy = family_energy(family, footprint, sigma) \
                    * sampling.groove_energy(family.triangular, kz0 * family.depth, self.coherent)
                density = energy * self._scratch_density(self._family_line(family), q.xi0_x, q.xi0_y, wi, q.lam0,
                                                         kz0)
            return (mi.Spectrum(dr.select(inside, mean, 0.0)), mi.Spectrum(dr.select(inside, intensity, 0.0)),
                    dr.select(inside, covered, 0.0), dr.select(inside, energy, 0.0), dr.select(inside, density, 0.0))

        return dr.if_stmt((q.kz0,), inside, terms, lambda kz0: (zero_s, zero_s, zero_f, zero_f, zero_f),
                          label="scratch_filtered_family")

    def _line_runs(self, segment, piece):
        ratio = dr.gather(mi.Vector2f, self.line_continuation, piece)
        return ratio.x * segment.length, ratio.y * segment.length

    def _reach(self, footprint: Footprint):
        return REACH_STDS * dr.sqrt(footprint.largest_variance + self.sigma * self.sigma)

    # --------------------------------------------------------- evaluation
    def evaluate(self, si, wo, *, has_glossy=True, has_diffuse=True, want_value=True, want_pdf=True,
                 active=True, pieces_in_window=True, family=FIND, found=None, keep_search=False):
        """:meth:`..model.Model.evaluate` over the footprint (the point model where it is a point)."""
        footprint = self.footprint(si)
        point = self._is_point(footprint)
        active = mi.Bool(active)
        result = Model.evaluate(self, si, wo, has_glossy=has_glossy, has_diffuse=has_diffuse, want_value=want_value,
                                want_pdf=want_pdf, active=active & point, pieces_in_window=pieces_in_window,
                                family=family, found=found, keep_search=keep_search)
        spread = self._evaluate_filtered(si, wo, footprint, has_glossy=has_glossy, has_diffuse=has_diffuse,
                                         want_value=want_value, want_pdf=want_pdf, active=active & ~point,
                                         found=found, keep_search=keep_search)
        merged = [None if a is None else dr.select(point, a, b) for a, b in zip(result[:2], spread[:2])]
        if keep_search:
            family_found, count, pieces = result[2]
            _, spread_count, spread_pieces = spread[2]
            merged.append((family_found, dr.select(point, count, spread_count),
                           tuple(dr.select(point, p, q) for p, q in zip(pieces, spread_pieces))))
        return tuple(merged)

    def _evaluate_filtered(self, si, wo, footprint: Footprint, *, has_glossy, has_diffuse, want_value, want_pdf,
                           active, found, keep_search):
        wi = si.wi
        searched = active & (wi.z > 0.0)
        active = searched & (wo.z > 0.0)
        searching = searched if keep_search else active
        wavelength, jac = self._hero(si)
        q = self._frequencies(wi, wo, wavelength)
        zero_s, zero_f = dr.zeros(mi.Spectrum), dr.zeros(mi.Float)
        coherent, sigma = self.coherent, self.sigma
        height_field = self.height_field and coherent and want_value and has_glossy
        pairing = coherent and want_value and has_glossy
        # the last RECENT_PIECES pieces found: their indices and local directions (the pair loop's cheap test)
        recent = (dr.zeros(mi.UInt32), tuple(dr.zeros(mi.UInt32) for _ in range(RECENT_PIECES)),
                  tuple(dr.zeros(mi.Float) for _ in range(2 * RECENT_PIECES)))
        none_kept = (dr.zeros(mi.UInt32), tuple(dr.zeros(mi.UInt32) for _ in range(REPLAY_PIECES)))
        window = WINDOW_RADIUS_SIGMAS * sigma

        def body(segment, piece, state):
            mean, intensity, covered, energy, density, paired, point_field, kept = state
            if keep_search:
                count, pieces = kept
                kept = (count + 1, tuple(dr.select(count == k, piece, pieces[k]) for k in range(REPLAY_PIECES)))
            if want_value and has_glossy:
                s, i = piece_terms(segment, footprint, q.xi_x, q.xi_y, q.k_z, sigma, q.lobe, coherent,
                                   self._line_runs(segment, piece), self.across_nodes)
                mean, intensity = mi.Spectrum(mean + s.re), mi.Spectrum(intensity + i)
                if coherent:
                    if pairing:
                        intensity, paired = self._pairs(jac, footprint, q, segment, piece, intensity, *paired)
                    if height_field:
                        point_field = self._point_crossings(jac, q, segment, piece, point_field, window)
                else:
                    covered = covered + filtered_window_energy(segment, footprint, sigma)
            if want_pdf and has_glossy:
                weight = filtered_window_energy(segment, footprint, sigma) \
                    * sampling.groove_energy(segment.triangular, q.kz0 * segment.depth, coherent)
                energy = energy + weight
                density = density + weight * self._scratch_density(segment, q.xi0_x, q.xi0_y, wi, q.lam0, q.kz0)
            return mean, intensity, covered, energy, density, paired, point_field, kept

        point_field = ((q.lobe, zero_s), (zero_s, zero_s)) if height_field else ()
        scanning = searching & has_glossy
        radius = self._reach(footprint)
        family = self._footprint_family(jac, footprint, radius, searching & has_glossy) if has_glossy else None
        start = (zero_s, zero_s, zero_f, zero_f, zero_f)
        if family is not None:  # lanes whose footprint lies in a periodic family: its closed form, no search
            scanning &= ~family.eligible
            start = self._family_start(family, footprint, q, wi, want_value, want_pdf)
        state = (*start, recent if pairing else (), point_field, none_kept if keep_search else ())
        if found is not None:
            count, pieces = found
            replaying = scanning & (count <= REPLAY_PIECES)
            scanning &= ~replaying
            state = replay_pieces(self.grid, jac, count, pieces, state, body, replaying)
        mean, intensity, covered, energy, density, _, point_field, kept = for_each_segment(
            self.grid, jac, radius, state, body, scanning)

        value = pdf = None
        if want_value:
            lobe = q.lobe
            if coherent:
                total = lobe * lobe + 2.0 * lobe * mean + intensity
                if height_field:  # the crossings' corrections at the shading point (module docstring)
                    (a, b), (c_re, c_im) = point_field
                    total = total + self._crossing_excess(a, b, c_re, c_im)
            else:
                total = lobe * lobe * (1.0 - dr.minimum(covered * dr.rcp(math.pi * sigma * sigma), 1.0)) + intensity
            value = self._value_of_intensity(si, wo, q.inv_wavelength, dr.maximum(total, 0.0), has_glossy,
                                             has_diffuse, active)
        if want_pdf:
            pdf = self._pdf(si, wo, q, energy, density, has_glossy, has_diffuse, active)
        return value, pdf, (family, *kept) if keep_search else None

    def _pairs(self, jac, footprint, q, segment, piece, intensity, seen, recent, directions):
        """``intensity`` plus the piece's pair terms with the last RECENT_PIECES found; the piece recorded.

        Footprints wide enough to leave crossing pairs out (:data:`.field.CROSSING_PAIRS_BELOW`) pair a
        piece only with the nearly parallel ones, told apart by their stored directions (no gather)."""
        crossings = footprint.smallest_variance < (CROSSING_PAIRS_BELOW * self.sigma) ** 2

        def step(slot, intensity):
            other = _pick(slot, recent)
            dx, dy = _pick(slot, directions[0::2]), _pick(slot, directions[1::2])
            candidate = crossings | (dr.abs(dx * segment.dy - dy * segment.dx) < PARALLEL_BELOW)

            def term(intensity):
                first = segment_at(self.grid, jac, other, True)
                return (mi.Spectrum(intensity + pair_term(first, segment, footprint, q.xi_x, q.xi_y, q.k_z,
                                                          self.sigma, across_nodes=self.across_nodes)),)

            intensity = dr.if_stmt((intensity,), candidate, term, lambda intensity: (intensity,),
                                   label="scratch_filtered_pair")[0]
            return slot + 1, intensity

        slots = dr.minimum(seen, len(recent))
        _, intensity = dr.while_loop((dr.zeros(mi.UInt32), intensity), lambda slot, _: slot < slots, step,
                                     label="scratch_filtered_pairs")
        here = seen % len(recent)
        recent = tuple(dr.select(here == k, piece, recent[k]) for k in range(len(recent)))
        directions = tuple(dr.select(here == k // 2, segment.dx if k % 2 == 0 else segment.dy, d)
                           for k, d in enumerate(directions))
        return intensity, (seen + 1, recent, directions)

    def _point_crossings(self, jac, q, segment, piece, point_field, window):
        """The point model's field at the shading point, (U0 + Σ S_k, Σ C): pieces and crossings in its window."""
        (a, b), (c_re, c_im) = point_field
        spectrum, sigma = mi.Spectrum, self.sigma
        near = dr.square(segment.a_perp) + dr.square(dr.clip(0.0, segment.c, segment.c + segment.length)) \
            < window * window

        def add(a, b, c_re, c_im):
            s = amplitude(segment, q.xi_x, q.xi_y, q.k_z, sigma)

            def add_crossing(partner, partner_piece, crossing_uv, field):
                runs = ((self._runs_on(segment, piece), self._runs_on(partner, partner_piece))
                        if self.grid.continuation is not None else (None, None))
                c = crossing_correction(segment, partner, q.xi_x, q.xi_y, q.k_z, sigma, *runs)
                field = spectrum(field[0] + c.re), spectrum(field[1] + c.im)
                if self.triples:
                    field = add_triples(self.grid, jac, segment, partner, piece, partner_piece, crossing_uv,
                                        q.xi_x, q.xi_y, q.k_z, sigma, field, with_parallel=self.parallel_overlaps)
                return field

            c_re, c_im = for_each_crossing(self.grid, jac, piece, segment, window, (c_re, c_im), add_crossing)
            return spectrum(a + s.re), spectrum(b + s.im), c_re, c_im

        a, b, c_re, c_im = dr.if_stmt((a, b, c_re, c_im), near, add, lambda *x: x,
                                      label="scratch_filtered_point_crossings")
        return (a, b), (c_re, c_im)

    def _crossing_excess(self, a, b, c_re, c_im):
        """``|U + C|² - |U|²`` at the shading point, the height field's bound applied as the point model does."""
        if self.clamp_to_height_field_bound:
            c_a, c_b = self._within_height_field_bound(a + c_re, b + c_im, self.sigma)
        else:
            c_a, c_b = a + c_re, b + c_im
        return Cx(c_a, c_b).abs2() - Cx(a, b).abs2()

    # ----------------------------------------------------------- sampling
    def sample(self, si, sample1, sample2, *, has_glossy=True, has_diffuse=True, active=True, search=None):
        """:meth:`..model.Model.sample` with the pieces of the footprint drawn by their averaged weights."""
        footprint = self.footprint(si)
        point = self._is_point(footprint)
        active = mi.Bool(active)
        wo, pdf, value, diffuse = Model.sample(self, si, sample1, sample2, has_glossy=has_glossy,
                                               has_diffuse=has_diffuse, active=active & point, search=search)
        f_wo, f_pdf, f_value, f_diffuse = self._sample_filtered(si, footprint, sample1, sample2, has_glossy=has_glossy,
                                                                has_diffuse=has_diffuse, active=active & ~point,
                                                                search=search)
        return (dr.select(point, wo, f_wo), dr.select(point, pdf, f_pdf), dr.select(point, value, f_value),
                dr.select(point, diffuse, f_diffuse))

    def _sample_filtered(self, si, footprint, sample1, sample2, *, has_glossy, has_diffuse, active, search):
        wi = si.wi
        active = active & (wi.z > 0.0)
        wavelength, jac = self._hero(si)
        sigma = self.sigma
        lam0 = wavelength[0]
        kz0 = (4.0 * math.pi) * wi.z * dr.rcp(lam0)

        def body(segment, piece, state):
            weight = filtered_window_energy(segment, footprint, sigma) \
                * sampling.groove_energy(segment.triangular, kz0 * segment.depth, self.coherent)
            return reservoir_step(weight, piece, state, REPLAY_PIECES)

        scanning = active & has_glossy
        radius = self._reach(footprint)
        family = self._footprint_family(jac, footprint, radius, active & has_glossy) if has_glossy else None
        energy0 = dr.zeros(mi.Float)
        if family is not None:  # a periodic family: its tracks' weight (they sample as one line)
            energy0 = dr.select(family.eligible, family_energy(family, footprint, sigma)
                                * sampling.groove_energy(family.triangular, kz0 * family.depth, self.coherent), 0.0)
            scanning &= ~family.eligible
        state = (energy0, dr.zeros(mi.UInt32), mi.Float(sample1), dr.zeros(mi.UInt32),
                 tuple(dr.zeros(mi.UInt32) for _ in range(REPLAY_PIECES)))
        if search is not None:  # the pieces eval_pdf found in this footprint, in its order
            _, found_count, found_pieces = search
            replaying = scanning & (found_count <= REPLAY_PIECES)
            scanning &= ~replaying
            state = replay_pieces(self.grid, jac, found_count, found_pieces, state, body, replaying)
        energy, chosen, u, count, kept = for_each_segment(self.grid, jac, radius, state, body, scanning)

        wo, diffuse, active = self._draw_direction(
            si, jac, chosen, energy, u, sample2, lam0, kz0, has_glossy, has_diffuse, active, family,
            (lambda: self._family_line(family)) if family is not None else None, "scratch_filtered_line_sample")
        value, pdf, _ = self._evaluate_filtered(si, wo, footprint, has_glossy=has_glossy, has_diffuse=has_diffuse,
                                                want_value=True, want_pdf=True, active=active,
                                                found=(count, kept), keep_search=False)
        return wo, pdf, value, diffuse
