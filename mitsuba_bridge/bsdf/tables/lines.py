"""Straight runs of pieces whatever their profiles: the footprint filter's runs (numpy, docs/model.md §11.3).

:func:`.grid.continuations` joins pieces of one width and depth that meet end to start on one line
(the incoherent model and the periodic families need that); the footprint filter joins every piece
of one straight line, whose depth changes along it (a scratch's depth noise cuts it into pieces of
their own depth), so that a cut is never an end of the along factor.  The pieces' ends are rebuilt
from the tables' rows (``a_hi + a_lo`` and ``a + e``, float64 of float32 parts) and matched on a
lattice of 2⁻²⁴ of the extent (the rows' float32 directions leave ends ~10⁻⁹ of the extent apart).
"""
from __future__ import annotations

import numpy as np

from .grid import GridTables, box_lattice, continuations
from .references import aligned

__all__ = ["line_continuation", "LATTICE_BITS"]

#: Ends closer than 2^-LATTICE_BITS of the set's extent meet.
LATTICE_BITS = 24


def line_continuation(tables: GridTables) -> np.ndarray:
    """``(N, 2)`` float32: per piece, how far its line runs on straight through other pieces before its start
    and after its end, in units of the piece's own length (the kernel's µm come from its own length)."""
    count = tables.piece_count
    if count == 0:
        return aligned(np.zeros((1, 2), np.float32))
    rows = tables.segments[:count].astype(np.float64)
    a = rows[:, 0:2] + rows[:, 2:4]
    b = a + rows[:, 4:6]
    lo, hi = np.minimum(a.min(axis=0), b.min(axis=0)), np.maximum(a.max(axis=0), b.max(axis=0))
    origin, _ = box_lattice(lo, hi)
    step = max(float(np.max(hi - lo)), 1e-30) / float(1 << LATTICE_BITS)
    runs = continuations(a, b, tables.segments[:count], lattice=(origin - 0.5 * step, step), same_profile=False)
    length = np.hypot(rows[:, 4], rows[:, 5])
    return aligned((runs / np.where(length > 0.0, length, 1.0)[:, None]).astype(np.float32))
