"""How many pieces a footprint's search can meet: per-cell densities as summed-area tables (numpy,
docs/model.md §11.8).

The footprint filter visits every piece whose centre line passes within its reach; where pieces are
dense (a CD's tracks seen from afar) that is thousands per evaluation.  The kernel caps each sample's
reach so that the **expected** number of pieces inside stays under a budget
(:mod:`..filtered.reach`), from two counts per grid cell:

* ``share``: each piece's fraction of the cells that list it (a piece listed in k cells adds 1/k
  to each): summed over a box, the pieces that lie in it, whole or in part;
* ``listed``: the references of the cell, the pieces that pass through it: a box's mean of them
  is the density of lines that cross its boundary (Crofton's formula, :mod:`..filtered.reach`).

Both are stored as summed-area tables, ``(nv + 1, nu + 1, 2)`` float32 with a zero first row and
column, so that the kernel reads a box's sums with four gathers whatever its size.  float32 keeps
the sums of even the CD's 10⁷ references to about one piece, far finer than the budget.
"""
from __future__ import annotations

import numpy as np

from .grid import GridTables
from .references import aligned

__all__ = ["density_table"]


def density_table(tables: GridTables) -> np.ndarray:
    """``(nv + 1, nu + 1, 2)`` float32 summed-area tables of (``share``, ``listed``) per cell (module docs):
    entry ``[v, u]`` holds the sums over the cells ``[0, u) × [0, v)``."""
    nu, nv = tables.shape
    listed = np.diff(tables.cell_start.astype(np.int64))[:nu * nv].astype(np.float64)
    references = tables.references[:int(tables.cell_start[nu * nv])].astype(np.int64)
    cells_of_piece = np.bincount(references, minlength=max(tables.piece_count, 1)).astype(np.float64)
    cell_of_reference = np.repeat(np.arange(nu * nv), np.diff(tables.cell_start.astype(np.int64))[:nu * nv])
    weight = 1.0 / np.maximum(cells_of_piece[references], 1.0)
    share = np.bincount(cell_of_reference, weights=weight, minlength=nu * nv)
    table = np.zeros((nv + 1, nu + 1, 2), np.float64)
    table[1:, 1:, 0] = share.reshape(nv, nu).cumsum(axis=0).cumsum(axis=1)
    table[1:, 1:, 1] = listed.reshape(nv, nu).cumsum(axis=0).cumsum(axis=1)
    return aligned(table.astype(np.float32))
