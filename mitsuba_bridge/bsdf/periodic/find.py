"""Finding the family whose tracks fill a shading point's window (docs/model.md §3.5): the window's
box in at most 2 × 2 cells, the same run in each, kinks and edges (:mod:`..periodic` says when a
lane takes a family).  Units: µm inside, cells for what the tables store.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from ..maths import profiles
from ..tables.periodic import (KINK_MIN_COS, LINE_NORMAL_TOLERANCE, LINE_OFFSET_TOLERANCE, PITCH_TOLERANCE, SLOTS,
                               VECTORS)

__all__ = ["Family", "find_family", "ACROSS_SIGMAS", "ALONG_SIGMAS"]

#: The same checks in the kernel, between the float32 families of neighbouring cells: directions, and
#: offsets a whole number of pitches apart up to both families' deviations (and pitches as close).
PARALLEL_SIN_KERNEL = 1e-5
PITCH_TOLERANCE_KERNEL = 2 * PITCH_TOLERANCE
#: Window reach (σ) across the tracks that must lie among the family's tracks: the
#: scan's window radius (model.WINDOW_RADIUS_SIGMAS); what lies beyond, the scan drops too (e^-8).
ACROSS_SIGMAS = 4.0
#: ... and along the tracks inside its rectangle: every end lying outside the ball of this radius around
#: x0, it lies more than 6σ from x0's foot point on any track within 4σ (√(6² + 4²) = 7.21), where the
#: scan skips the end's term (window.END_NEGLIGIBLE_SIGMAS).
ALONG_SIGMAS = math.sqrt(6.0 ** 2 + 4.0 ** 2) * 1.001
#: Smallest σ/P for the three-order sum (the fourth order is then below e^-44 of the nearest) ...
MIN_SIGMA_PER_PITCH = 1.0


@dataclass
class Family:
    """The family a shading point's window lies in (``eligible``), seen from x0 (local frame, µm)."""

    eligible: object  #: mi.Bool
    dx: object  #: mi.Float: unit direction of the tracks
    dy: object
    pitch: object  #: mi.Float: P (µm)
    a0: object  #: mi.Float: signed distance a·n of the nearest track's centre line from x0, |a0| <= P/2
    width: object  #: mi.Float: W (µm)
    depth: object  #: mi.Float: D (µm)
    triangular: object  #: mi.Bool
    #: mi.Bool: the window straddles a kink line: the run above (A) holds the half-plane y·l >= h (y = x - x0)
    #: only, and a second run B of the same groove (direction b_dx, b_dy, pitch b_pitch, offset b_a0) the rest
    kink: object = None
    lone: object = None  #: mi.Bool: at a kink, run A alone (the whole box on its side of its end line; no B)
    b_pitch: object = None
    b_dx: object = None
    b_dy: object = None
    b_a0: object = None
    l_x: object = None  #: mi.Float: unit normal of the kink line into A's side (local frame)
    l_y: object = None
    h: object = None  #: mi.Float: signed distance of the kink line from x0 along l (µm)
    #: mi.Bool: the window reaches past the first or last track (an *edge*): its closed form is
    #: ``base`` (0, or the infinite run where fewer tracks are missing than present) plus ``edge_sign``
    #: (±1) times the sum over ``edge_tracks`` tracks at offsets ``edge_a + j · edge_step`` (µm)
    edge: object = None
    edge_base: object = None  #: mi.Bool: the infinite run's closed form is the base (else 0)
    edge_a: object = None
    edge_step: object = None
    edge_tracks: object = None  #: mi.UInt32 (0 on lanes without an edge)


class _Slot(NamedTuple):
    """One family slot of one cell, tested against one window."""

    holds: object  #: mi.Bool: a family whose rectangle holds the window's part in the cell
    cut: object  #: mi.Bool: a family cut by a kink line, among whose tracks the window lies up to that line
    n_u: object
    n_v: object
    pitch: object  #: µm
    offset: object  #: µm: signed distance a·n of its first track from x0 (n of the tracks' local frame)
    width: object
    depth: object  #: ±D
    l_u: object  #: its end line (cells): unit normal into the family's side, offset (zero: none)
    l_v: object
    l_offset: object
    pitch_cells: object
    #: (own cell only) the window reaches past its first or last track, no other piece within reach:
    #: its tracks in reach, by index from the first: lowest, highest, and the index of the last track
    edge: object = None
    j_lo: object = None
    j_hi: object = None
    last: object = None


def find_family(grid, jac, sigma, active, reach_um=None) -> Family:
    """The family whose tracks fill x0's window, if any (module docstring).

    The window's box may reach into the neighbouring cells (at most 2 × 2 cells): each cell it touches
    must hold the same run (same direction, pitch and groove, offsets a whole number of pitches apart)
    with a rectangle holding the window's part in that cell (the box clipped to it).  ``reach_um``
    (per lane): how far across the tracks the box reaches instead of ``ACROSS_SIGMAS`` σ, along them
    ``ALONG_SIGMAS / ACROSS_SIGMAS`` times that (the footprint filter's reach, docs/model.md §11.6)."""
    window = _Window(grid, jac, sigma, active, reach_um)
    found = dr.if_stmt((window.candidate,), window.candidate, window.search, window.nothing, label="scratch_family")
    eligible, dx, dy, pitch, offset, width, depth = found[:7]
    family = Family(eligible=eligible, dx=dx, dy=dy, pitch=pitch, a0=offset,
                    width=dr.maximum(width, profiles.MIN_WIDTH_UM), depth=dr.abs(depth),
                    triangular=depth < 0.0 if grid.triangular is None else grid.triangular)
    family.edge, family.edge_base, family.edge_a, family.edge_step, family.edge_tracks = found[7:12]
    if window.kinks:
        (family.kink, family.lone, family.b_pitch, family.b_dx, family.b_dy, family.b_a0, family.l_x, family.l_y,
         family.h) = found[12:]
    return family


class _Window:
    """One lane's window against the family tables: its box in grid cells (at most 2 × 2), the slots of
    those cells seen from x0, and the searches for a run, an edge and a kink (:func:`find_family`)."""

    # ---- the window's box in cells
    def __init__(self, grid, jac, sigma, active, reach_um=None):
        self.grid, self.jac, self.sigma = grid, jac, sigma
        self.gu = gu = (jac.uv.x - grid.origin_u) * grid.inverse_cell_size
        self.gv = gv = (jac.uv.y - grid.origin_v) * grid.inverse_cell_size
        self.det = det = jac.j00 * jac.j11 - jac.j01 * jac.j10
        norm2 = jac.j00 * jac.j00 + jac.j01 * jac.j01 + jac.j10 * jac.j10 + jac.j11 * jac.j11
        usable = mi.Bool(active) & (dr.abs(det) > 1e-12 * norm2)
        inv_det = dr.rcp(dr.select(usable, dr.abs(det), 1.0))
        self.scale = inv_det * grid.inverse_cell_size  # cells per µm, times |adj(J)ᵀ·| below
        self.reach_um = ACROSS_SIGMAS * sigma if reach_um is None else reach_um
        self.along_um = ALONG_SIGMAS * sigma if reach_um is None else (ALONG_SIGMAS / ACROSS_SIGMAS) * reach_um
        reach = self.reach_um * self.scale
        self.extent_u = extent_u = reach * dr.sqrt(jac.j11 * jac.j11 + jac.j01 * jac.j01) + grid.margin
        self.extent_v = extent_v = reach * dr.sqrt(jac.j10 * jac.j10 + jac.j00 * jac.j00) + grid.margin
        self.u0, self.u1 = u0, u1 = dr.floor(gu - extent_u), dr.floor(gu + extent_u)
        self.v0, self.v1 = v0, v1 = dr.floor(gv - extent_v), dr.floor(gv + extent_v)
        usable &= dr.isfinite(extent_u) & dr.isfinite(extent_v)
        last_u, last_v = mi.Float(grid.cells_u - 1), mi.Float(grid.cells_v - 1)
        self.in_grid = ((u0 >= 0.0) & (v0 >= 0.0) & (u1 <= last_u) & (v1 <= last_v) & (u1 - u0 <= 1.0)
                        & (v1 - v0 <= 1.0))
        # an edge's box may reach past the grid, where no centre line lies: clamped to the grid, it must lie
        # in one cell (x0's own, the nearest cell where x0 lies outside)
        self.own_box = ((dr.maximum(u0, 0.0) == dr.minimum(u1, last_u))
                        & (dr.maximum(v0, 0.0) == dr.minimum(v1, last_v)))
        usable &= self.in_grid | self.own_box
        self.signed = dr.select(det >= 0.0, 1.0, -1.0)
        self.kinks = grid.kink_count > 0  # (a Python choice: sets without kinks compile no kink code)

        # ---- only lanes whose own cell holds a family go on (whole SIMD packets elsewhere skip the rest)
        self.u = dr.floor(dr.clip(gu, 0.0, mi.Float(grid.cells_u - 1)))
        self.v = dr.floor(dr.clip(gv, 0.0, mi.Float(grid.cells_v - 1)))
        own_cell = mi.UInt32(mi.Int32(self.v) * grid.cells_u + mi.Int32(self.u))
        pitch_floats = [4 * ((own_cell * SLOTS + k) * VECTORS) + 3 for k in range(SLOTS)]
        self.candidate = usable & ((dr.gather(mi.Float, grid.family_frames, pitch_floats[0], usable) > 0.0)
                                   | (dr.gather(mi.Float, grid.family_frames, pitch_floats[1], usable) > 0.0))
        self.corners = ((u0, v0), (u1, v0), (u0, v1), (u1, v1))
        #: whether each corner is a cell not listed before it (a box within one cell column or row repeats them)
        self.new_corner = (u0 == u0, u1 != u0, v1 != v0, (u1 != u0) & (v1 != v0))

    def box_range(self, cu, cv, n_u, n_v):
        """``(min, max)`` of n·x over the window's box clipped to cell (cu, cv) (that cell's coordinates)."""
        du, dv = self.gu - cu, self.gv - cv  # x0 in this cell's coordinates
        box_u0, box_u1 = dr.maximum(du - self.extent_u, 0.0), dr.minimum(du + self.extent_u, 1.0)
        box_v0, box_v1 = dr.maximum(dv - self.extent_v, 0.0), dr.minimum(dv + self.extent_v, 1.0)
        positive_u, positive_v = n_u >= 0.0, n_v >= 0.0
        return (n_u * dr.select(positive_u, box_u0, box_u1) + n_v * dr.select(positive_v, box_v0, box_v1),
                n_u * dr.select(positive_u, box_u1, box_u0) + n_v * dr.select(positive_v, box_v1, box_v0))

    # ---- one slot of one cell
    def slot(self, cu, cv, k, wanted, edges=False) -> _Slot:
        """Slot k of cell (cu, cv) against the window's box clipped to that cell (``edges``: x0's own cell,
        whether the window lies at an edge of the family instead)."""
        grid, jac, sigma = self.grid, self.jac, self.sigma
        cell = mi.UInt32(mi.Int32(cv) * grid.cells_u + mi.Int32(cu))
        base = (cell * SLOTS + k) * VECTORS
        f0 = dr.gather(mi.Vector4f, grid.family_frames, base, wanted)  # n_u, n_v, o_first, pitch
        f1 = dr.gather(mi.Vector4f, grid.family_frames, base + 1, wanted)  # o_last, s_lo, s_hi, W
        f2 = dr.gather(mi.Vector4f, grid.family_frames, base + 2, wanted)  # ±D, l_u, l_v, l_offset
        du, dv = self.gu - cu, self.gv - cv  # x0 in this cell's coordinates
        box_lo, box_hi = self.box_range(cu, cv, f0.x, f0.y)
        s = f0.y * du - f0.x * dv  # along t = (n_v, -n_u)
        adj_n = dr.sqrt(dr.square(jac.j11 * f0.x - jac.j10 * f0.y) + dr.square(jac.j00 * f0.y - jac.j01 * f0.x))
        adj_t = dr.sqrt(dr.square(jac.j11 * f0.y + jac.j10 * f0.x) + dr.square(jac.j00 * f0.x + jac.j01 * f0.y))
        along = self.along_um * self.scale * adj_t + grid.margin
        micrometres_per_cell = dr.abs(self.det) * dr.rcp(dr.maximum(adj_n, 1e-30)) * grid.cell_size
        # no lattice position of the part lies beyond the first or the last track (those beyond the cell's
        # part belong to its neighbours, checked there), and every track runs past the window's reach
        gap = (1.0 - 2.0 * PITCH_TOLERANCE) * f0.w
        across = wanted & (f0.w > 0.0) & (box_lo >= f0.z - gap) & (box_hi <= f1.x + gap)
        below, above = s - along >= f1.y, s + along <= f1.z
        # cut by its end line: only the far end (away from the line, along t) must lie beyond the reach
        into = f0.y * f2.y - f0.x * f2.z  # t·l
        cut = across & ((f2.y != 0.0) | (f2.z != 0.0)) & dr.select(into > 0.0, above, below)
        offset = self.signed * (f0.z - (f0.x * du + f0.y * dv)) * micrometres_per_cell
        found = _Slot(across & below & above, cut, f0.x, f0.y, f0.w * micrometres_per_cell, offset, f1.w, f2.x,
                      f2.y, f2.z, f2.w, f0.w)
        if not edges:
            return found
        # at an edge: the whole box in this cell, along the tracks as above, and across them clear of any
        # other piece; the tracks in reach: |offset + signed·j·P| <= the window radius (as the scan's)
        f3 = dr.gather(mi.Vector4f, grid.family_frames, base + 3, wanted)  # clear_before, clear_after
        edge = (wanted & (f0.w > 0.0) & ~(across & self.in_grid) & below & above & self.own_box
                & (box_lo >= f0.z - f3.x) & (box_hi <= f1.x + f3.y))
        pitch = found.pitch
        step = self.signed * dr.maximum(pitch, 1e-30)
        j0, j1 = (-self.reach_um - offset) / step, (self.reach_um - offset) / step
        last = dr.round((f1.x - f0.z) * dr.rcp(dr.maximum(f0.w, 1e-30)))
        j_lo = dr.maximum(dr.ceil(dr.minimum(j0, j1)), 0.0)
        j_hi = dr.minimum(dr.floor(dr.maximum(j0, j1)), last)
        return found._replace(edge=edge, j_lo=j_lo, j_hi=j_hi, last=last)

    @staticmethod
    def same_run(other: _Slot, run: _Slot):
        """``other`` (a slot of any cell, seen from x0) continues ``run``: same direction, pitch and groove,
        offsets a whole number of pitches apart."""
        same_way = dr.abs(other.n_u * run.n_v - other.n_v * run.n_u) < PARALLEL_SIN_KERNEL
        flip = dr.select(other.n_u * run.n_u + other.n_v * run.n_v >= 0.0, 1.0, -1.0)
        shift = (flip * other.offset - run.offset) * dr.rcp(dr.maximum(run.pitch, 1e-30))
        return (same_way & (dr.abs(shift - dr.round(shift)) < PITCH_TOLERANCE_KERNEL)
                & (dr.abs(other.pitch - run.pitch) < PITCH_TOLERANCE_KERNEL * run.pitch)
                & (other.width == run.width) & (other.depth == run.depth))

    def local_run(self, run: _Slot):
        """The run's direction J t (t = (n_v, -n_u)) in the local frame and its nearest track's offset."""
        jac = self.jac
        ex, ey = jac.j00 * run.n_v - jac.j01 * run.n_u, jac.j10 * run.n_v - jac.j11 * run.n_u
        inv = dr.rsqrt(dr.maximum(ex * ex + ey * ey, 1e-30))
        return ex * inv, ey * inv, run.offset - run.pitch * dr.round(run.offset * dr.rcp(run.pitch))

    # ---- a run filling the window, or an edge of one
    def search(self, candidate):
        sigma, u, v = self.sigma, self.u, self.v
        first = self.slot(u, v, 0, candidate, edges=True)
        second = self.slot(u, v, 1, candidate & ~first.holds, edges=True)
        own = _pick(first.holds, first, second)
        eligible = own.holds & self.in_grid & (sigma >= MIN_SIGMA_PER_PITCH * own.pitch)
        # an edge: fewer tracks missing (lattice positions in reach beyond the first or last) than present
        # are summed as the infinite run's closed form less those (where it applies), else the present ones
        at_edge = ~eligible & (first.edge | second.edge)
        edge = _pick(first.edge, first, second)
        step = dr.select(self.det >= 0.0, 1.0, -1.0) * edge.pitch
        j0, j1 = (-self.reach_um - edge.offset) / step, (self.reach_um - edge.offset) / step
        j_min, j_max = dr.ceil(dr.minimum(j0, j1)), dr.floor(dr.maximum(j0, j1))
        present = dr.maximum(edge.j_hi - edge.j_lo + 1.0, 0.0)
        before, after = dr.maximum(-j_min, 0.0), dr.maximum(j_max - edge.last, 0.0)
        subtract = (at_edge & (sigma >= MIN_SIGMA_PER_PITCH * edge.pitch) & ((before == 0.0) | (after == 0.0))
                    & (before + after < present))
        edge_start = dr.select(subtract, dr.select(before > 0.0, j_min, edge.last + 1.0), edge.j_lo)
        edge_tracks = mi.UInt32(dr.select(at_edge, dr.select(subtract, before + after, present), 0.0))
        edge_fields = (at_edge, subtract, edge.offset + edge_start * step, step, edge_tracks)
        own = _pick(at_edge, edge, own)

        def neighbours(eligible):
            """Every cell of the window's box continues the run (x0's own cell matches itself)."""
            for cu, cv in self.corners:
                wanted = eligible & ((cu != u) | (cv != v))
                a = self.slot(cu, cv, 0, wanted)
                matched = a.holds & self.same_run(a, own)
                b = self.slot(cu, cv, 1, wanted & ~matched)
                eligible = eligible & (~wanted | matched | (b.holds & self.same_run(b, own)))
            return (eligible,)

        # (whole SIMD packets whose boxes stay in their own cells skip this)
        leaves = eligible & ((self.u0 != self.u1) | (self.v0 != self.v1))
        eligible = dr.if_stmt((eligible,), leaves, neighbours, lambda eligible: (eligible,),
                              label="scratch_family_neighbours")[0]
        dx, dy, offset = self.local_run(own)
        found = (eligible | at_edge, dx, dy, own.pitch, offset, own.width, own.depth) + edge_fields
        if not self.kinks:
            return found
        # lanes without a run of their own may lie at a kink (found in any cell of the box)
        wanted = candidate & self.in_grid & ~eligible & ~at_edge
        kink = dr.if_stmt((wanted,), wanted, self.at_kink, self.no_kink, label="scratch_kink")
        return tuple(dr.select(kink[0], k, f) for k, f in zip(kink[:7], found[:7])) + found[7:] + kink[7:]

    # ---- two runs meeting on a kink line
    def at_kink(self, active):
        """A kink holding the window (:func:`.tables.periodic._end_lines`).  Some cell of the box holds two
        runs A and B that share their end line (or one run A cut by its end line, with the whole box on its
        side: *lone*), and in every cell of the box the part of the box on A's side of the line lies among
        A's tracks up to the line (A continuing, cut by the same line, or running through with the part
        wholly on its side), the same for B, and no other piece lies there (other runs end on the line from
        beyond)."""
        sigma = self.sigma
        found = lone = dr.zeros(mi.Bool)
        run_a = run_b = None
        ru, rv = self.u, self.v
        for (cu, cv), new in zip(self.corners, self.new_corner):
            wanted = active & ~found & new
            a = self.slot(cu, cv, 0, wanted)
            b = self.slot(cu, cv, 1, wanted)
            pair = (wanted & _on_line(b, a, 0.0, 0.0, -1.0) & (a.width == b.width) & (a.depth == b.depth)
                    & (sigma >= MIN_SIGMA_PER_PITCH * dr.maximum(a.pitch, b.pitch)))
            part_lo, _ = self.box_range(cu, cv, a.l_u, a.l_v)
            single = (wanted & ~pair & a.cut & ~(b.pitch_cells > 0.0) & ((a.l_u != 0.0) | (a.l_v != 0.0))
                      & (part_lo >= a.l_offset) & (sigma >= MIN_SIGMA_PER_PITCH * a.pitch))
            here = pair | single
            run_a = a if run_a is None else _pick(here, a, run_a)
            b = _pick(single, a, b)  # (a lone run's B: valid numbers, no weight)
            run_b = b if run_b is None else _pick(here, b, run_b)
            ru, rv = dr.select(here, cu, ru), dr.select(here, cv, rv)
            lone = dr.select(here, single, lone)
            found = found | here
        kink = found
        for (cu, cv), new in zip(self.corners, self.new_corner):
            shift_u, shift_v = cu - ru, cv - rv
            a = self.slot(cu, cv, 0, kink & new)
            b = self.slot(cu, cv, 1, kink & new)
            part_lo, part_hi = self.box_range(cu, cv, run_a.l_u, run_a.l_v)
            line = run_a.l_offset - (run_a.l_u * shift_u + run_a.l_v * shift_v)
            a_side, b_side = part_lo >= line, part_hi <= line  # the part wholly on A's / B's side

            def beyond(x, sign):  # x's tracks end on the line from the other side than ``sign``'s run's
                return _on_line(x, run_a, shift_u, shift_v, -sign)

            def covers(x, run, sign, side):  # x continues the run, cut by the line or wholly on its side
                return self.same_run(x, run) & ((x.cut & _on_line(x, run_a, shift_u, shift_v, sign)) | (x.holds & side))

            alone = ~(b.pitch_cells > 0.0)
            a_covers_a, b_covers_a = covers(a, run_a, 1.0, a_side), covers(b, run_a, 1.0, a_side)
            a_covers_b, b_covers_b = covers(a, run_b, -1.0, b_side), covers(b, run_b, -1.0, b_side)
            on_a = a_side & ((a_covers_a & (alone | beyond(b, 1.0))) | (b_covers_a & beyond(a, 1.0)))
            on_b = b_side & ((a_covers_b & (alone | beyond(b, -1.0))) | (b_covers_b & beyond(a, -1.0)))
            ok = dr.select(lone, on_a, (a_covers_a & b_covers_b) | (a_covers_b & b_covers_a) | on_a | on_b)
            kink = kink & (ok | ~new)
        return self._kink_fields(kink, lone, run_a, run_b, ru, rv)

    def _kink_fields(self, kink, lone, run_a, run_b, ru, rv):
        """The kink's part of the family's fields, seen from x0 (the line's normal and distance, both runs)."""
        jac, det = self.jac, self.det
        dx, dy, offset = self.local_run(run_a)
        b_dx, b_dy, b_a0 = self.local_run(run_b)
        # the kink line in the local frame: normal ⟂ J t_L (t_L = (l_v, -l_u)), turned towards J l; its
        # distance from x0 through the UV Jacobian as for the tracks' offsets
        lu, lv = run_a.l_u, run_a.l_v
        tx, ty = jac.j00 * lv - jac.j01 * lu, jac.j10 * lv - jac.j11 * lu
        towards = (jac.j00 * lu + jac.j01 * lv) * -ty + (jac.j10 * lu + jac.j11 * lv) * tx
        inv = dr.select(towards >= 0.0, 1.0, -1.0) * dr.rsqrt(dr.maximum(tx * tx + ty * ty, 1e-30))
        adj_l = dr.sqrt(dr.square(jac.j11 * lu - jac.j10 * lv) + dr.square(jac.j00 * lv - jac.j01 * lu))
        h = ((run_a.l_offset - (lu * (self.gu - ru) + lv * (self.gv - rv))) * dr.abs(det)
             * dr.rcp(dr.maximum(adj_l, 1e-30)) * self.grid.cell_size)
        l_x, l_y = -ty * inv, tx * inv
        # nearly across both runs where the lane sees them (a shear of the UV map turns the line obliquely)
        kink = kink & ((dr.abs(l_x * dx + l_y * dy) >= KINK_MIN_COS) & (dr.abs(l_x * b_dx + l_y * b_dy) >= KINK_MIN_COS))
        return (kink, dx, dy, run_a.pitch, offset, run_a.width, run_a.depth,
                kink, lone, run_b.pitch, b_dx, b_dy, b_a0, l_x, l_y, h)

    @staticmethod
    def no_kink(active):
        zero = dr.zeros(mi.Float)
        return (dr.zeros(mi.Bool),) + (zero,) * 6 + (dr.zeros(mi.Bool),) * 2 + (zero,) * 7

    def nothing(self, candidate):
        zero = dr.zeros(mi.Float)
        kink = (dr.zeros(mi.Bool), dr.zeros(mi.Bool), zero, zero, zero, zero, zero, zero, zero) if self.kinks else ()
        edge = (dr.zeros(mi.Bool), dr.zeros(mi.Bool), zero, zero, dr.zeros(mi.UInt32))
        return (dr.zeros(mi.Bool), zero, zero, zero, zero, zero, zero) + edge + kink


def _pick(mask, a: _Slot, b: _Slot) -> _Slot:
    """``a``'s fields where ``mask``, else ``b``'s (fields that neither has stay None)."""
    return _Slot(*(x if x is None else dr.select(mask, x, y) for x, y in zip(a, b)))


def _on_line(other: _Slot, run: _Slot, shift_u, shift_v, sign):
    """``other``'s end line is ``sign`` × ``run``'s, ``run`` being stored in the cell (shift_u, shift_v)
    cells before ``other``'s (a line n·x = c there is n·x = c - n·shift here)."""
    offset = run.l_offset - (run.l_u * shift_u + run.l_v * shift_v)
    return ((dr.abs(other.l_u - sign * run.l_u) < LINE_NORMAL_TOLERANCE)
            & (dr.abs(other.l_v - sign * run.l_v) < LINE_NORMAL_TOLERANCE)
            & (dr.abs(other.l_offset - sign * offset) < LINE_OFFSET_TOLERANCE * run.pitch_cells)
            & ((run.l_u != 0.0) | (run.l_v != 0.0)))
