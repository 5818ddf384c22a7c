"""A footprint's reach capped where pieces are dense: the expected pieces one evaluation visits stay
under a budget (docs/model.md §11.8).

The filtered BRDF visits every piece whose centre line passes within ``R = REACH_STDS ·
√(λ_max + σ²)`` of the shading point (λ_max: the footprint's larger variance).  With the per-cell
densities of :mod:`..tables.density` read over the reach's UV box (four gathers each), the pieces
expected inside it are

    E(R) = S_box + (π/4) n̄ (e_u + e_v)

S_box: the pieces lying in the box (each piece's share of its cells, summed); n̄: the box's mean
references per cell, i.e. lines crossing a cell.  Isotropic lines of length λ per unit area hit a
convex set of perimeter P λP/π times (Crofton) and a unit cell 4λ/π times, so n̄ lines per cell
hit the reach's ellipse, semi-axes at most (e_u, e_v) cells and perimeter at most π(e_u + e_v),
(π/4) n̄ (e_u + e_v) times.  Where E(R) exceeds ``MAX_EXPECTED_PIECES`` the reach shrinks to the
root of that model with the box's densities held (S_box grows as the box's area, the lines as its
size), and again with the smaller box's densities (a dense patch found closer), ``CAP_REFINEMENTS``
times.  The footprint then shrinks with it (:func:`capped_footprint`): a smaller footprint only
filters less, the image converges to the same one (§11.8).
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from .footprint import Footprint

__all__ = ["MAX_EXPECTED_PIECES", "CAP_REFINEMENTS", "SNAP_TO_POINT_SIGMAS", "expected_pieces", "capped_reach",
           "capped_footprint"]

#: Pieces one filtered evaluation is expected to visit at most: high enough that sets of ordinary density (the
#: demo plate close and from afar, the test surfaces' two 300 µm grooves cut into 40 pieces) are not capped,
#: low enough for a CD's tracks (docs/model.md §11.8 has the counts).
MAX_EXPECTED_PIECES = 64.0
#: A footprint capped to a larger standard deviation below this many σ becomes the point (it would filter next
#: to nothing, at the filtered terms' cost).
SNAP_TO_POINT_SIGMAS = 0.5
#: Times the capped reach is estimated again with the densities of its own, smaller box.
CAP_REFINEMENTS = 3


def _box(grid, density, jac, reach_um):
    """``(share, listed, cells, per_um_u, per_um_v)``: the sums of ``density`` (mi.Float, the summed-area
    tables of :func:`..tables.density.density_table`) over the cells of the reach's UV box
    (the sums clipped to the grid), its cell count, and its half extents per µm of reach, in cells."""
    det = jac.j00 * jac.j11 - jac.j01 * jac.j10
    inv_det = dr.rcp(dr.maximum(dr.abs(det), 1e-30))
    per_um_u = inv_det * grid.inverse_cell_size * dr.sqrt(jac.j11 * jac.j11 + jac.j01 * jac.j01)
    per_um_v = inv_det * grid.inverse_cell_size * dr.sqrt(jac.j10 * jac.j10 + jac.j00 * jac.j00)
    gu = (jac.uv.x - grid.origin_u) * grid.inverse_cell_size
    gv = (jac.uv.y - grid.origin_v) * grid.inverse_cell_size
    extent_u, extent_v = reach_um * per_um_u, reach_um * per_um_v
    nu, nv = mi.Float(grid.cells_u), mi.Float(grid.cells_v)

    def column(x, cells):  # a summed-area table's index: cells [0, index) lie before it
        x = dr.select(dr.isfinite(x), x, 0.0)
        return mi.Int32(dr.clip(x, 0.0, cells))

    low_u, high_u = dr.floor(gu - extent_u), dr.floor(gu + extent_u) + 1.0
    low_v, high_v = dr.floor(gv - extent_v), dr.floor(gv + extent_v) + 1.0
    u0, u1, v0, v1 = column(low_u, nu), column(high_u, nu), column(low_v, nv), column(high_v, nv)
    row = grid.cells_u + 1

    def corner(u, v):
        return dr.gather(mi.Vector2f, density, mi.UInt32(v * row + u))

    total = corner(u1, v1) - corner(u0, v1) - corner(u1, v0) + corner(u0, v0)
    empty = (u1 <= u0) | (v1 <= v0)
    share = dr.select(empty, 0.0, dr.maximum(total.x, 0.0))
    listed = dr.select(empty, 0.0, dr.maximum(total.y, 0.0))
    # the densities are over the whole box: its cells outside the grid hold no piece
    cells = dr.select(dr.isfinite(high_u - low_u) & dr.isfinite(high_v - low_v), (high_u - low_u) * (high_v - low_v),
                      1.0)
    return share, listed, dr.maximum(cells, 1.0), per_um_u, per_um_v


def expected_pieces(grid, density, jac, reach_um):
    """E(R): the pieces a search of ``reach_um`` around the shading point is expected to visit (module docs)."""
    share, listed, cells, per_um_u, per_um_v = _box(grid, density, jac, reach_um)
    return share + (0.25 * math.pi) * listed * dr.rcp(cells) * (per_um_u + per_um_v) * reach_um


def capped_reach(grid, density, jac, reach_um, budget=MAX_EXPECTED_PIECES):
    """The reach (µm) at most ``reach_um`` whose expected pieces are at most ``budget`` (module docs)."""
    reach = mi.Float(reach_um)
    for _ in range(CAP_REFINEMENTS):
        share, listed, cells, per_um_u, per_um_v = _box(grid, density, jac, reach)
        # E(r) ≈ a r² + b r with the box's densities: S_box over the box's area 4 e_u e_v, the lines as above
        a = share * dr.rcp(cells) * 4.0 * per_um_u * per_um_v
        b = (0.25 * math.pi) * listed * dr.rcp(cells) * (per_um_u + per_um_v)
        denominator = b + dr.sqrt(b * b + 4.0 * a * budget)
        root = dr.select(denominator > 0.0, 2.0 * budget * dr.rcp(denominator), math.inf)
        reach = dr.select(dr.isfinite(root) & (root < reach), root, reach)
    return reach


def capped_footprint(footprint: Footprint, grid, density, jac, sigma, reach_stds) -> Footprint:
    """``footprint`` scaled down where its reach ``reach_stds · √(λ_max + σ²)`` is expected to hold more than
    ``MAX_EXPECTED_PIECES`` pieces; the same footprint elsewhere (zero stays zero)."""
    largest = footprint.largest_variance
    sigma2 = sigma * sigma
    reach = reach_stds * dr.sqrt(largest + sigma2)
    capped = capped_reach(grid, density, jac, reach)
    allowed = dr.maximum(dr.square(capped * (1.0 / reach_stds)) - sigma2, 0.0)
    # a footprint capped below SNAP_TO_POINT_SIGMAS σ filters next to nothing at the cost of the filtered terms:
    # the point model's instead (lanes whose reach is not capped keep their footprint bit for bit)
    allowed = dr.select(allowed < dr.square(SNAP_TO_POINT_SIGMAS * sigma), 0.0, allowed)
    factor = dr.select(capped < reach, dr.minimum(allowed * dr.rcp(dr.maximum(largest, 1e-30)), 1.0), 1.0)
    return Footprint(footprint.xx * factor, footprint.xy * factor, footprint.yy * factor)
