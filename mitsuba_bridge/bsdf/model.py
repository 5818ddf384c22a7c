"""The scratch BRDF, its sampling density and its sampler on Dr.Jit arrays (docs/model.md §4, §5).

    f_r = F |U0(ξ) + Σ_k S_k(ξ)|² / (λ² π σ²)              (coherent)
    f_r = F [|U0|² (1 - ρ) + Σ_k |S'_k|²] / (λ² π σ²)        (incoherent)

plus an optional Lambertian base ρ_d / π.  Inputs are read from the
SurfaceInteraction only through ``uv``, ``dp_du``, ``dp_dv``, ``sh_frame``, ``wi``
and ``wavelengths`` (and whatever the optional textures read).  Units inside:
micrometres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from . import sampling
from .maths.complexmath import Cx
from .energy import albedo_excess
from .fresnel import fresnel_conductor
from .lookup import Grid, for_each_crossing, for_each_segment, jacobian, replay_pieces, segment_at
from .heightfield.overlap import crossing_correction
from .heightfield.parallel import RECENT_PIECES, add_parallel_overlaps
from .periodic import MAX_INCOHERENT_WIDTH_SIGMAS, family_field, family_intensity, find_family, run_energies
from .maths.segment import SegmentGeometry, amplitude, frequencies, incoherent_intensity
from .heightfield.triples import add_triples
from .maths.window import mirror_lobe

__all__ = ["Model", "WINDOW_RADIUS_SIGMAS"]

#: Segments farther than this from the shading point are ignored (amplitude e^-8).
WINDOW_RADIUS_SIGMAS = 4.0
#: The share of specular samples spent on scratch lines is 2r/(1 + 2r), r = (scratch energy) / A_s, at most this.
MAX_SCRATCH_SHARE = 0.9
#: Shortest wavelength accepted (µm); guards hand-made interactions with zeroed wavelengths.
MIN_WAVELENGTH_UM = 0.01
#: ``Model.evaluate(family=FIND)``: look the periodic family up (the default).
FIND = object()
#: Pieces that :meth:`Model.sample`'s first pass keeps for its evaluation to replay (sparse sets find 0-2).
REPLAY_PIECES = 4


@dataclass
class Model:
    """Everything the kernels read; rebuilt by the plugin when a parameter changes."""

    grid: Grid
    sigma: object  #: opaque mi.Float, σ in µm
    micrometres_per_unit: object  #: opaque mi.Float
    coherent: bool
    eta: object = None  #: mi.Texture or None (perfect mirror)
    k: object = None
    #: fresnel.ConductorSpectra of eta and k where they are a named material's (one gather per wavelength), else None
    spectra: object = None
    diffuse: object = None  #: mi.Texture or None
    depth_phase: str = "kirchhoff"  #: or "incidence", "bounded" (docs/bsdf.md, Energy)
    #: correct crossings of pieces to the height field (docs/model.md §3.4; coherent mode)
    height_field: bool = False
    #: with height_field: add the terms of overlaps of three to five too (triples.py, and parallel.py for three
    #: mutually nearly parallel pieces; docs/model.md §3.4); off only to measure them
    triples: bool = True
    #: with height_field: correct overlaps of nearly parallel pieces too (parallel.py); off only to measure them
    parallel_overlaps: bool = True
    #: with height_field: scale the field back to |U| <= 2πσ² (docs/model.md §3.4); off only to test the terms
    clamp_to_height_field_bound: bool = True
    #: sum periodic families (a CD's tracks, a grating) in closed form where a window lies in one
    #: (docs/model.md §3.5); off only to compare with the scan
    periodic: bool = True

    # ------------------------------------------------------------- pieces
    def _reflectance(self, si, cos_theta, active):
        if self.eta is None:
            return mi.Spectrum(1.0)
        if self.spectra is not None:
            return fresnel_conductor(cos_theta, *self.spectra.eval(si.wavelengths, active))
        return fresnel_conductor(cos_theta, self.eta.eval(si, active), self.k.eval(si, active))

    def _hero(self, si):
        """Per-lane quantities that do not depend on ω_o."""
        wavelength = mi.Spectrum(dr.maximum(mi.Spectrum(si.wavelengths) * 1e-3, MIN_WAVELENGTH_UM))
        return wavelength, jacobian(si, self.micrometres_per_unit)

    def _strategy_weights(self, si, energy, cos_i, has_glossy, has_diffuse, active):
        """(diffuse, scratch, mirror) sample shares; depend on ω_i and the hero wavelength only."""
        has_diffuse = has_diffuse and self.diffuse is not None
        zero = mi.Float(0.0)
        if not has_glossy:  # only the diffuse component is asked for (if there is one)
            return mi.Float(1.0 if has_diffuse else 0.0), zero, zero
        share = sampling_share(energy, self.sigma)
        if has_diffuse:
            rho = self.diffuse.eval(si, active)[0]
            specular = self._reflectance(si, cos_i, active)[0]
            q_d = dr.select(rho > 0.0, rho / dr.maximum(rho + specular, 1e-12), 0.0)
        else:
            q_d = zero
        return q_d, (1.0 - q_d) * share, (1.0 - q_d) * (1.0 - share)

    @staticmethod
    def sums_families(coherent: bool, depth_phase: str) -> bool:
        """Whether a model of these settings sums periodic families in closed form (:mod:`.periodic`):
        not the coherent "bounded" depth phase (its albedo terms are summed piece by piece)."""
        return not (coherent and depth_phase == "bounded")

    def _family(self, jac, active):
        """The periodic family of each lane's window (:mod:`.periodic`), or None where none is used."""
        if not (self.periodic and self.grid.periodic and self.sums_families(self.coherent, self.depth_phase)):
            return None
        family = find_family(self.grid, jac, self.sigma, active)
        if not self.coherent:  # grooves narrow enough for the incoherent quadrature (family_intensity)
            family.eligible &= family.width <= MAX_INCOHERENT_WIDTH_SIGMAS * self.sigma
            if family.kink is not None:
                family.kink &= family.eligible
        return family

    def _family_weights(self, family, kz0):
        """The selection weights of its runs' tracks (hero wavelength): A's, and B's at a kink (else 0);
        0 where the lane has no family (whole SIMD packets without one skip the arithmetic)."""
        def weights(kz0):
            groove = sampling.groove_energy(family.triangular, kz0 * family.depth, self.coherent)
            a, b = run_energies(family, self.sigma)
            return dr.select(family.eligible, a * groove, 0.0), dr.select(family.eligible, b * groove, 0.0)

        zero = dr.zeros(mi.Float)
        return dr.if_stmt((kz0,), family.eligible, weights, lambda kz0: (zero, zero), label="scratch_family_weights")

    def _family_density(self, family, w_a, w_b, xi_x, xi_y, wi, lam0, kz0):
        """``Σ weight · p_line(ξ)`` over its runs (B's only in SIMD packets holding a kink)."""
        density = w_a * self._scratch_density(self._family_line(family), xi_x, xi_y, wi, lam0, kz0)
        if family.kink is None:
            return density

        def second(turn, density):
            line = self._family_line(family, True)
            return turn + 1, density + w_b * self._scratch_density(line, xi_x, xi_y, wi, lam0, kz0)

        # (one turn of a loop on the kink lanes: packets without one leave it at once; as a symbolic branch
        # its body cost every packet, periodic.family_field)
        turns = dr.select(family.kink, 1, 0)
        return dr.while_loop((dr.zeros(mi.UInt32), density), lambda turn, density: turn < turns, second,
                             label="scratch_family_kink_pdf")[1]

    def _family_field(self, family, lobe, xi_x, xi_y, k_z):
        s = family_field(family, xi_x, xi_y, k_z, self.sigma)
        return mi.Spectrum(lobe + s.re), mi.Spectrum(s.im)

    def _family_intensity(self, family, xi_x, xi_y, k_z):
        covered_a, covered_b = run_energies(family, self.sigma)
        return mi.Spectrum(family_intensity(family, xi_x, xi_y, k_z, self.sigma)), mi.Float(covered_a + covered_b)

    @staticmethod
    def _family_line(family, second=False):
        """Its tracks as the sampler sees a segment (direction, width, depth, profile); ``second``: the
        tracks of its run B (at a kink; a mask selects per lane)."""
        zero = dr.zeros(mi.Float)
        a0, dx, dy = family.a0, family.dx, family.dy
        if second is not False:
            a0, dx, dy = (dr.select(second, b, a) for a, b in ((a0, family.b_a0), (dx, family.b_dx), (dy, family.b_dy)))
        return SegmentGeometry(c=zero, length=zero, a_perp=a0, dx=dx, dy=dy,
                               width=family.width, depth=family.depth, triangular=family.triangular)

    def _runs_on(self, segment, piece):
        """How far (µm) the piece's groove runs straight on before its start and after its end."""
        if self.grid.continuation is None:
            zero = dr.zeros(mi.Float)
            return zero, zero
        ratio = dr.gather(mi.Vector2f, self.grid.continuation, piece)
        return ratio.x * segment.length, ratio.y * segment.length

    # --------------------------------------------------------- evaluation
    def evaluate(self, si, wo, *, has_glossy=True, has_diffuse=True, want_value=True, want_pdf=True,
                 active=True, pieces_in_window=True, family=FIND, found=None, keep_search=False):
        """``(f_r cos θ_o, pdf)`` (either may be ``None`` when not wanted).

        ``pieces_in_window`` (mask): False where the caller knows that no piece lies in the window
        (:meth:`sample` has just looked): the search for them is then skipped.  ``family``: the
        periodic family of each lane's window when the caller has found it (:meth:`sample`; None:
        none is used), else it is looked up here.  ``found``: ``(count, pieces)`` of a search of the
        same window, the first ``REPLAY_PIECES`` pieces in the order it found them: lanes with that
        many or fewer replay them instead of searching (the same sums, bit for bit).

        ``keep_search``: return ``(value, pdf, search)``, ``search`` being ``(family, count, pieces)``
        of this window as :meth:`sample` would find them (``search=``), the first ``REPLAY_PIECES``
        pieces kept in the order found; the window is then searched wherever ω_i is above the surface,
        whatever ω_o (:mod:`.handoff`: ``eval_pdf`` towards a light, then ``sample``)."""
        wi = si.wi
        searched = mi.Bool(active) & (wi.z > 0.0)  # the window's search depends on x0 and ω_i only
        active = searched & (wo.z > 0.0)
        searching = searched if keep_search else active
        wavelength, jac = self._hero(si)
        q = self._frequencies(wi, wo, wavelength)

        zero_s, zero_f = dr.zeros(mi.Spectrum), dr.zeros(mi.Float)
        field = (q.lobe, zero_s) if self.coherent else (zero_s, zero_f)
        energy0 = density0 = zero_f
        scanning = searching & has_glossy & pieces_in_window
        if family is FIND:
            family = self._family(jac, searching & has_glossy) if has_glossy else None
        if family is not None and has_glossy:  # lanes inside a periodic family: its closed form, no search
            scanning &= ~family.eligible
            field, energy0, density0 = self._family_terms(family, q, wi, field, zero_s, zero_f, want_value, want_pdf)
        # "bounded": Σ_k e_k(ω_i), Σ_k e_k(ω_o), the albedo estimate's segment terms (docs/model.md §4.1)
        bounded = self.depth_phase == "bounded" and self.coherent and want_value and has_glossy
        # nearly parallel overlaps: each piece found is paired with the last RECENT_PIECES found (parallel.py)
        pairing = self.height_field and self.parallel_overlaps and self.coherent and want_value and has_glossy
        body = self._piece_terms(q, jac, wi, wo, wavelength, has_glossy=has_glossy, want_value=want_value,
                                 want_pdf=want_pdf, bounded=bounded, pairing=pairing, keep_search=keep_search)

        # (the excess sums, the recent and the kept pieces join the loop state only when they are used)
        no_pieces = (dr.zeros(mi.UInt32), tuple(dr.zeros(mi.UInt32) for _ in range(RECENT_PIECES)))
        none_kept = (dr.zeros(mi.UInt32), tuple(dr.zeros(mi.UInt32) for _ in range(REPLAY_PIECES)))
        state = (field, energy0, density0, (zero_s, zero_s) if bounded else (), no_pieces if pairing else (),
                 none_kept if keep_search else ())
        (a, b), energy, density, excess, _, kept = _fold_pieces(self.grid, jac, WINDOW_RADIUS_SIGMAS * self.sigma,
                                                                state, body, scanning, found)

        value = pdf = None
        if want_value:
            if self.height_field and self.coherent and self.clamp_to_height_field_bound:
                a, b = self._within_height_field_bound(a, b, self.sigma)
            if bounded:  # f / max(1, Â(ω_i), Â(ω_o)): reciprocal, albedo ≤ 1 (docs/model.md §4.1)
                a, b = self._bounded(a, b, *excess)
            value = self._value(si, wo, q.inv_wavelength, q.lobe, a, b, has_glossy, has_diffuse, active)
        if want_pdf:
            pdf = self._pdf(si, wo, q, energy, density, has_glossy, has_diffuse, active)
        if keep_search:
            return value, pdf, (family, *kept)
        return value, pdf

    def _frequencies(self, wi, wo, wavelength) -> "_Frequencies":
        """ξ, k_z and the mirror lobe per wavelength, and the hero wavelength's share of them (docs/model.md §1, §2)."""
        # ---- spatial frequency and depth phase, per wavelength
        spectrum = mi.Spectrum
        # (one reciprocal per wavelength, then products: divisions and square roots are what the
        # common, empty-window lanes spend most on, docs/bsdf.md, Performance)
        inv_wavelength = dr.rcp(wavelength)
        xi_x = spectrum((wi.x + wo.x) * inv_wavelength)
        xi_y = spectrum((wi.y + wo.y) * inv_wavelength)
        if self.depth_phase == "incidence":  # a screen fixed by ω_i: Parseval bounds the albedo
            k_z = spectrum(((4.0 * math.pi) * wi.z) * inv_wavelength)
        else:
            k_z = spectrum(((2.0 * math.pi) * (wi.z + wo.z)) * inv_wavelength)
        lobe = spectrum(mirror_lobe(xi_x * xi_x + xi_y * xi_y, self.sigma))

        # ---- hero-wavelength quantities of the sampling density
        lam0 = wavelength[0]
        kz0 = (4.0 * math.pi) * wi.z * inv_wavelength[0]  # κ / D at γ_o = γ_i (as sample()'s)
        return _Frequencies(inv_wavelength, xi_x, xi_y, k_z, lobe, lam0, kz0, xi_x[0], xi_y[0])

    def _family_terms(self, family, q: "_Frequencies", wi, field, zero_s, zero_f, want_value, want_pdf):
        """The field and sampling sums ``(field, energy, density)`` a fold starts from on lanes whose window lies
        in a periodic family: its closed form (``field``, the mirror lobe's, and zeros on the other lanes)."""
        inside = family.eligible
        energy0 = density0 = zero_f
        if want_value and self.coherent:  # (whole SIMD packets outside every family skip it)
            field = dr.if_stmt((q.lobe,), inside, lambda lobe: self._family_field(family, lobe, q.xi_x, q.xi_y, q.k_z),
                               lambda lobe: (lobe, zero_s), label="scratch_family_field")
        elif want_value:  # incoherent: (Σ|S'|², Σ ε) as the scan sums them
            field = dr.if_stmt((zero_f,), inside, lambda _: self._family_intensity(family, q.xi_x, q.xi_y, q.k_z),
                               lambda _: (zero_s, zero_f), label="scratch_family_intensity")
        if want_pdf:  # (whole SIMD packets outside every family skip it)
            def weights(kz0):
                w_a, w_b = self._family_weights(family, kz0)
                density = self._family_density(family, w_a, w_b, q.xi0_x, q.xi0_y, wi, q.lam0, kz0)
                return w_a + w_b, dr.select(inside, density, 0.0)

            energy0, density0 = dr.if_stmt((q.kz0,), inside, weights, lambda kz0: (zero_f, zero_f),
                                           label="scratch_family_pdf")
        return field, energy0, density0

    def _piece_terms(self, q: "_Frequencies", jac, wi, wo, wavelength, *, has_glossy, want_value, want_pdf,
                     bounded, pairing, keep_search):
        """The fold's body: what one piece found in the window adds to the field (with its crossings and
        nearly parallel overlaps), to the albedo estimate and to the sampling sums."""
        spectrum, sigma, coherent = mi.Spectrum, self.sigma, self.coherent
        xi_x, xi_y, k_z, kz0 = q.xi_x, q.xi_y, q.k_z, q.kz0

        def body(segment, piece, state):
            (a, b), energy, density, excess, paired, kept = state
            if keep_search:  # the first REPLAY_PIECES pieces, in the order found (as sample()'s search)
                count, pieces = kept
                kept = (count + 1, tuple(dr.select(count == k, piece, pieces[k]) for k in range(REPLAY_PIECES)))
            if want_value and has_glossy:
                if coherent:
                    s = amplitude(segment, xi_x, xi_y, k_z, sigma)
                    a, b = spectrum(a + s.re), spectrum(b + s.im)
                    if self.height_field:
                        def add_crossing(partner, partner_piece, crossing_uv, field):
                            # (clipped where a groove ends inside the overlap: needs the runs' table)
                            runs = ((self._runs_on(segment, piece), self._runs_on(partner, partner_piece))
                                    if self.grid.continuation is not None else (None, None))
                            c = crossing_correction(segment, partner, xi_x, xi_y, k_z, sigma, *runs)
                            field = spectrum(field[0] + c.re), spectrum(field[1] + c.im)
                            if self.triples:
                                field = add_triples(self.grid, jac, segment, partner, piece, partner_piece,
                                                    crossing_uv, xi_x, xi_y, k_z, sigma, field,
                                                    with_parallel=self.parallel_overlaps)
                            return field

                        a, b = for_each_crossing(self.grid, jac, piece, segment, WINDOW_RADIUS_SIGMAS * sigma, (a, b),
                                                 add_crossing)
                    if pairing:
                        seen, recent, (a, b) = add_parallel_overlaps(
                            self.grid, jac, piece, segment, *paired, xi_x, xi_y, k_z, sigma,
                            WINDOW_RADIUS_SIGMAS * sigma, (a, b), with_triples=self.triples)
                        paired = (seen, recent)
                else:  # Σ|S'|² over straight segments, pieces of one joined (segment.incoherent_intensity)
                    before, after = self._runs_on(segment, piece)
                    a = spectrum(a + incoherent_intensity(segment, xi_x, xi_y, k_z, sigma, before, after))
                    b = b + sampling.window_energy(segment, sigma)
                if bounded:
                    e_i, e_o = albedo_excess(segment, wi, wo, wavelength, sigma)
                    excess = (spectrum(excess[0] + e_i), spectrum(excess[1] + e_o))
            if want_pdf and has_glossy:
                weight = sampling.selection_weight(segment, kz0 * segment.depth, sigma, coherent)
                # (never in place: the inputs of a symbolic branch must stay untouched)
                energy = energy + weight
                density = density + weight * self._scratch_density(segment, q.xi0_x, q.xi0_y, wi, q.lam0, kz0)
            return (a, b), energy, density, excess, paired, kept

        return body

    def _pdf(self, si, wo, q: "_Frequencies", energy, density, has_glossy, has_diffuse, active):
        """The sampling density of ``wo`` from the fold's sums (one-sample MIS of the strategies, docs/model.md §5)."""
        q_d, q_s, q_m = self._strategy_weights(si, energy, si.wi.z, has_glossy, has_diffuse, active)
        xi0_2 = q.xi0_x * q.xi0_x + q.xi0_y * q.xi0_y
        scratch = dr.select(energy > 0.0, density / dr.maximum(energy, 1e-30), 0.0)
        specular = (q_m * sampling.pdf_mirror(xi0_2, self.sigma) + q_s * scratch) * wo.z \
            * dr.square(q.inv_wavelength[0])
        pdf = dr.select(active, specular + q_d * wo.z * (1.0 / math.pi), 0.0)
        return dr.select(dr.isfinite(pdf), pdf, 0.0)

    @staticmethod
    def _within_height_field_bound(a, b, sigma):
        """The field scaled back to ``|U| <= 2πσ²`` where it exceeds it (docs/model.md §3.4).

        Every height field has |T| = 1, so ``|U| <= ∫ w = 2πσ²``; the truncated inclusion–exclusion can
        exceed that in piles beyond its orders and where mutually nearly parallel scratches all cross
        another one (their overlaps of three and more are not corrected)."""
        limit2 = (2.0 * math.pi * sigma * sigma) ** 2
        size2 = a * a + b * b
        scale = dr.select(size2 > limit2, dr.sqrt(limit2 / dr.maximum(size2, 1e-30)), 1.0)
        return mi.Spectrum(a * scale), mi.Spectrum(b * scale)

    @staticmethod
    def _bounded(a, b, excess_i, excess_o):
        """The field scaled by ``1/√max(1, Â(ω_i), Â(ω_o))``, Â = 1 + Σ_k e_k (so f_r by the square's inverse)."""
        norm = dr.maximum(1.0 + dr.maximum(excess_i, excess_o), 1.0)
        scale = dr.rsqrt(norm)
        return mi.Spectrum(a * scale), mi.Spectrum(b * scale)

    def _scratch_density(self, segment, xi_x, xi_y, wi, lam0, kz0):
        """``p_k(ξ)`` of the scratch-line sampler of one segment (hero wavelength)."""
        nu_par, nu_perp = frequencies(segment, xi_x, xi_y)
        lo, hi = self._band(segment, wi, lam0)
        return (sampling.pdf_along(nu_par, self.sigma)
                * sampling.pdf_across(nu_perp, segment, kz0 * segment.depth, lo, hi))

    @staticmethod
    def _band(segment, wi, lam0):
        """Visible ν⊥ band: |λ ν⊥ - ω_i,t · n| < 1."""
        wi_n = wi.y * segment.dx - wi.x * segment.dy
        return (wi_n - 1.0) / lam0, (wi_n + 1.0) / lam0

    def _value(self, si, wo, inv_wavelength, lobe, a, b, has_glossy, has_diffuse, active):
        """f_r cos θ_o from the summed field (a, b) (``inv_wavelength``: 1/λ per wavelength, µm⁻¹)."""
        intensity = None
        if has_glossy:
            if self.coherent:
                intensity = Cx(a, b).abs2()
            else:  # a: Σ|S'_k|², b: Σ ε_k (scratch area in the squared window)
                covered = dr.minimum(b * dr.rcp(math.pi * self.sigma * self.sigma), 1.0)
                intensity = lobe * lobe * (1.0 - covered) + a
        return self._value_of_intensity(si, wo, inv_wavelength, intensity, has_glossy, has_diffuse, active)

    def _value_of_intensity(self, si, wo, inv_wavelength, intensity, has_glossy, has_diffuse, active):
        """f_r cos θ_o from the intensity E|U|² (per wavelength; the footprint filter's average too)."""
        sigma = self.sigma
        value = dr.zeros(mi.Spectrum)
        if has_glossy:
            inv_window_area = dr.rcp(math.pi * sigma * sigma)  # 1/(πσ²), µm⁻²

            def reflected(intensity):
                half = dr.normalize(si.wi + wo)
                fresnel = self._reflectance(si, dr.dot(si.wi, half), active)
                return fresnel * intensity * (dr.square(inv_wavelength) * inv_window_area)

            # (the conductor's Fresnel, four complex square roots, only in SIMD packets where some lane's field is
            # not zero: a light far off the mirror lobe and every scratch line, the common case of a light
            # sample, gives 0 either way; the same values bit for bit, Fig. 7(b) lamp 4 % faster)
            lit = active & (dr.max(intensity) > 0.0)
            value = dr.if_stmt((intensity,), lit, reflected, lambda intensity: dr.zeros(mi.Spectrum),
                               label="scratch_fresnel")
        if has_diffuse and self.diffuse is not None:
            value = value + self.diffuse.eval(si, active) * (1.0 / math.pi)
        value = dr.select(active, value * wo.z, 0.0)
        return dr.select(dr.isfinite(value), value, 0.0)

    # ----------------------------------------------------------- sampling
    def sample(self, si, sample1, sample2, *, has_glossy=True, has_diffuse=True, active=True, search=None):
        """``(wo, pdf, value, diffuse_chosen)``; ``value`` is f_r cos θ_o (not divided by the pdf).

        ``search``: ``(family, count, pieces)`` of this very window from :meth:`evaluate`
        (``keep_search``, same ``si``, ``active`` and lobes): its family is taken and lanes with at most
        ``REPLAY_PIECES`` pieces replay them instead of searching (the same sample, bit for bit)."""
        wi = si.wi
        active = mi.Bool(active) & (wi.z > 0.0)
        wavelength, jac = self._hero(si)
        sigma = self.sigma
        lam0 = wavelength[0]
        kz0 = (4.0 * math.pi) * wi.z * dr.rcp(lam0)  # (the expression of evaluate(), which it calls)

        # ---- one pass: total scratch energy and a segment drawn in proportion (reservoir)
        # (it also keeps the first REPLAY_PIECES pieces it finds: the evaluation below replays them in the
        # same order instead of searching again, with the same result bit for bit; not with the height
        # field: its body, traced once more for the replay, doubled the kernel's compile time, 12.7 → 20.7 s
        # on Fig. 17, for no faster passes)
        replays = not (self.height_field and self.coherent)
        kept_count = REPLAY_PIECES if replays else 0

        def body(segment, piece, state):
            weight = sampling.selection_weight(segment, kz0 * segment.depth, sigma, self.coherent)
            return reservoir_step(weight, piece, state, kept_count)

        energy0, scanning = dr.zeros(mi.Float), active & has_glossy
        if search is None:
            family = self._family(jac, active & has_glossy) if has_glossy else None
        else:
            family, found_count, found_pieces = search
        if family is not None:  # a periodic family: its tracks' weight (all sample alike: its line, below)
            w_a, w_b = self._family_weights(family, kz0)
            energy0 = w_a + w_b
            scanning &= ~family.eligible
        no_pieces = tuple(dr.zeros(mi.UInt32) for _ in range(kept_count))
        state = (energy0, dr.zeros(mi.UInt32), mi.Float(sample1), dr.zeros(mi.UInt32), no_pieces)
        # (with a search: the pieces evaluate() found here, in its order, give the same reservoir)
        energy, chosen, u, count, kept = _fold_pieces(self.grid, jac, WINDOW_RADIUS_SIGMAS * sigma, state, body,
                                                      scanning, None if search is None else (found_count, found_pieces))

        second = False
        if family is not None and family.kink is not None:  # at a kink: B's line in proportion to its weight
            p_b = dr.select(family.kink & (energy0 > 0.0), w_b / dr.maximum(energy0, 1e-30), 0.0)
            second = family.kink & (u < p_b)
            reused = dr.select(second, u / dr.maximum(p_b, 1e-30), (u - p_b) / dr.maximum(1.0 - p_b, 1e-30))
            u = dr.select(family.kink, dr.clip(reused, 0.0, 0.99999994), u)

        wo, diffuse, active = self._draw_direction(
            si, jac, chosen, energy, u, sample2, lam0, kz0, has_glossy, has_diffuse, active, family,
            (lambda: self._family_line(family, second)) if family is not None else None, "scratch_line_sample")

        # the same window as above: where it held no piece, the evaluation need not search again, and
        # where it held a few, it replays them
        value, pdf = self.evaluate(si, wo, has_glossy=has_glossy, has_diffuse=has_diffuse, active=active,
                                   pieces_in_window=count > 0, family=family,
                                   found=(count, kept) if replays else None)
        return wo, pdf, value, diffuse

    def _draw_direction(self, si, jac, chosen, energy, u, sample2, lam0, kz0, has_glossy, has_diffuse, active,
                        family, family_line, label):
        """``(wo, diffuse chosen, active)`` of :meth:`sample` once a piece ``chosen`` (or a ``family``, whose
        tracks' line ``family_line()`` gives) is drawn from the pieces' total selection weight ``energy``,
        ``u`` the left-over uniform (the footprint filter draws the same way, over its footprint)."""
        wi, sigma = si.wi, self.sigma
        # ---- strategy from the left-over uniform (independent of the segment drawn)
        q_d, q_s, q_m = self._strategy_weights(si, energy, wi.z, has_glossy, has_diffuse, active)
        diffuse = active & (u < q_d)
        scratch = active & ~diffuse & (u < q_d + q_s)

        def scratch_line(mirror_x, mirror_y):
            """ξ on the chosen segment's scratch line."""
            segment = segment_at(self.grid, jac, chosen, scratch & ~family.eligible if family is not None else scratch)
            if family is not None:  # exactly the line the density of evaluate() assumes
                segment = SegmentGeometry(*(dr.select(family.eligible, mine, theirs)
                                            for mine, theirs in zip(family_line(), segment)))
            lo, hi = self._band(segment, wi, lam0)
            nu_par = sampling.sample_along(sample2.x, sigma)
            nu_perp = sampling.sample_across(sample2.y, segment, kz0 * segment.depth, lo, hi)
            return nu_par * segment.dx - nu_perp * segment.dy, nu_par * segment.dy + nu_perp * segment.dx

        # ---- ξ: the mirror lobe, or a scratch line (its gathers and inverse CDFs only in SIMD packets
        # where some lane drew one: on a sparsely scratched surface most have nothing in reach)
        mirror_x, mirror_y = sampling.sample_mirror(sample2, sigma)
        xi_x, xi_y = dr.if_stmt((mirror_x, mirror_y), scratch, scratch_line, lambda x, y: (x, y), label=label)

        # ---- ξ → direction; diffuse base: cosine hemisphere
        out_x = lam0 * xi_x - wi.x
        out_y = lam0 * xi_y - wi.y
        sin2 = out_x * out_x + out_y * out_y
        specular = mi.Vector3f(out_x, out_y, dr.safe_sqrt(1.0 - sin2))
        wo = dr.select(diffuse, mi.warp.square_to_cosine_hemisphere(sample2), specular)
        return wo, diffuse, active & (diffuse | (sin2 < 1.0))


def reservoir_step(weight, piece, state, kept_count: int):
    """One piece of :meth:`Model.sample`'s draw in proportion to the pieces' weights (a reservoir of one):
    ``state = (energy, chosen, u, count, kept)``, ``u`` rescaled to stay uniform, the first ``kept_count``
    pieces kept for the evaluation's replay."""
    energy, chosen, u, count, kept = state
    energy = energy + weight
    p = dr.select(energy > 0.0, weight / energy, 0.0)
    pick = u < p
    chosen = dr.select(pick, piece, chosen)
    u = dr.select(pick, u / dr.maximum(p, 1e-30), (u - p) / dr.maximum(1.0 - p, 1e-30))
    kept = tuple(dr.select(count == k, piece, kept[k]) for k in range(kept_count))
    return energy, chosen, dr.clip(u, 0.0, 0.99999994), count + 1, kept


class _Frequencies(NamedTuple):
    """Per lane: ξ (1/µm), k_z (rad/µm) and the mirror lobe per wavelength, 1/λ; the hero wavelength's λ0,
    κ/D at γ_o = γ_i and ξ (the sampling density's)."""

    inv_wavelength: object
    xi_x: object
    xi_y: object
    k_z: object
    lobe: object
    lam0: object
    kz0: object
    xi0_x: object
    xi0_y: object


def _fold_pieces(grid, jac, radius, state, body, scanning, found):
    """``body`` folded over the window's pieces (:func:`.lookup.for_each_segment`); ``found``: ``(count,
    pieces)`` of an earlier search of the same window, whose lanes with at most ``REPLAY_PIECES`` pieces
    replay them in its order instead of searching (the same fold, bit for bit)."""
    if found is not None:
        count, pieces = found
        replaying = scanning & (count <= REPLAY_PIECES)
        scanning &= ~replaying
        state = replay_pieces(grid, jac, count, pieces, state, body, replaying)
    return for_each_segment(grid, jac, radius, state, body, scanning)


def sampling_share(energy, sigma):
    """Share of specular samples for the scratch lines: ``2r / (1 + 2r)`` capped, r = energy / (πσ²)."""
    r = energy / (math.pi * sigma * sigma)
    return dr.select(energy > 0.0, dr.minimum(2.0 * r / (1.0 + 2.0 * r), MAX_SCRATCH_SHARE), 0.0)
