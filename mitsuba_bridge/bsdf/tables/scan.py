"""What the kernel's window search scans besides the tables themselves (numpy, built once per set):
each cell's references grouped into offset buckets, and the periodic families.

:class:`ScanArrays` is the costly part of an upload (the grating's families: 0.2 s) and what the disk
cache keeps beside :class:`.grid.GridTables`; :meth:`..lookup.Grid.from_arrays` uploads both.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .grid import GridTables, aligned, empty_aligned
from .periodic import periodic_families

__all__ = ["ScanArrays", "offset_buckets", "references_per_occupied_cell", "profiles_of", "relative_continuation",
           "BUCKET_REFERENCES", "BUCKETED_ABOVE"]

#: References per offset bucket (a query scans half a bucket below its window on average).
BUCKET_REFERENCES = 4
#: Sets with more references per occupied cell than this scan from offset buckets (a Python choice:
#: two kernels at most).  The Fig. 10 and Fig. 7(b) plates hold 2.5 and 6.4, the grating 270, the CD 480.
BUCKETED_ABOVE = 4 * BUCKET_REFERENCES


@dataclass(frozen=True, eq=False)
class ScanArrays:
    """What :meth:`..lookup.Grid.upload` builds on the CPU besides :class:`.grid.GridTables` (numpy): the offset
    buckets and the periodic families, the costly part of an upload (the grating's families: 0.2 s)."""

    bucketed: bool  #: :attr:`..lookup.Grid.bucketed`
    scan_frames: np.ndarray  #: (cells, 4) float32
    cell_bucket: np.ndarray  #: uint32
    bucket_start: np.ndarray  #: uint32
    family_frames: np.ndarray | None = None  #: :attr:`.periodic.PeriodicTables.frames`, or None
    family_count: int = 0
    kink_count: int = 0

    @classmethod
    def of(cls, tables: GridTables, periodic: bool = True) -> "ScanArrays":
        """Built from ``tables``; ``periodic``: with the periodic families (bucketed sets only)."""
        bucketed = references_per_occupied_cell(tables.cell_start) > BUCKETED_ABOVE
        if bucketed:
            scan_frames, cell_bucket, bucket_start = offset_buckets(tables.cell_start, tables.offsets,
                                                                    tables.cell_frames)
        else:  # the sparse scan reads the normals only, the first two columns of the tables' own frames
            scan_frames = tables.cell_frames  # (no buckets: their build costs ~7 % of the tables' own)
            cell_bucket = bucket_start = aligned(np.zeros(2, np.uint32))
        families = periodic_families(tables.cell_start, tables.references, tables.segments, tables.cell_frames,
                                     tables.origin, tables.cell_size, tables.shape,
                                     tables.continuation) if bucketed and periodic else None
        if families is None:
            return cls(bool(bucketed), scan_frames, cell_bucket, bucket_start)
        return cls(bool(bucketed), scan_frames, cell_bucket, bucket_start, families.frames, int(families.families),
                   int(families.kinks))


def profiles_of(tables: GridTables):
    """:attr:`..lookup.Grid.triangular`: True / False where every piece / no piece is a V-groove, else None."""
    v_grooves = tables.segments[:tables.piece_count, 7] < 0.0
    return None if v_grooves.any() and not v_grooves.all() else bool(v_grooves.any())


def relative_continuation(tables: GridTables) -> np.ndarray:
    """``tables.continuation`` in units of each piece's own UV length (the kernel knows that in µm)."""
    if tables.continuation is None or tables.piece_count == 0:  # (one dummy row: see tables._empty_tables)
        return aligned(np.zeros((max(tables.piece_count, 1), 2), np.float32))
    rows = tables.segments[:tables.piece_count]
    length = np.hypot(rows[:, 4].astype(np.float64), rows[:, 5].astype(np.float64))
    ratio = tables.continuation[:tables.piece_count] / np.where(length > 0.0, length, 1.0)[:, None]
    return aligned(ratio.astype(np.float32))


def references_per_occupied_cell(cell_start) -> float:
    """Mean number of references of the cells that hold any."""
    counts = np.diff(cell_start.astype(np.int64))
    occupied = np.count_nonzero(counts)
    return float(counts.sum()) / occupied if occupied else 0.0


def offset_buckets(cell_start, offsets, cell_frames, per_bucket: int = BUCKET_REFERENCES):
    """Each cell's references cut into buckets of equal offset width (numpy, at upload).

    Returns ``(scan_frames, cell_bucket, bucket_start)``: per cell its normal
    (u, v), its lowest offset plus its largest offset spread, and its buckets
    per offset unit (``scale``, float32 as the kernel reads them); the CSR start
    of each cell's buckets (``max(1, references // per_bucket)`` of them); the
    first reference of each bucket: bucket ``k`` of a cell holds the offsets in
    ``[lowest + k/scale, lowest + (k+1)/scale)``, the last one everything above.
    """
    starts = cell_start.astype(np.int64)
    counts = np.diff(starts)
    buckets = np.maximum(1, counts // per_bucket)
    cell_bucket = np.zeros(len(counts) + 1, np.int64)
    np.cumsum(buckets, out=cell_bucket[1:])
    occupied = counts > 0
    lowest = np.zeros(len(counts), np.float32)
    highest = np.zeros(len(counts), np.float32)
    lowest[occupied] = offsets[starts[:-1][occupied]]
    highest[occupied] = offsets[starts[1:][occupied] - 1]
    span = highest.astype(np.float64) - lowest
    # float32, as the kernel reads it; the kernel's rounding is covered by its offset padding
    scale = np.where(span > 0, buckets / np.where(span > 0, span, 1.0), 0.0).astype(np.float32)
    # the bucket of every reference (non-decreasing within a cell: offsets are sorted), in chunks
    per_bucket_count = np.zeros(int(cell_bucket[-1]), np.int64)
    for first in range(0, int(starts[-1]), 1 << 22):
        last = min(first + (1 << 22), int(starts[-1]))
        owner = np.searchsorted(starts, np.arange(first, last), side="right") - 1
        k = np.floor((offsets[first:last].astype(np.float64) - lowest[owner]) * scale[owner])
        k = np.clip(k, 0, buckets[owner] - 1).astype(np.int64)
        per_bucket_count += np.bincount(cell_bucket[owner] + k, minlength=len(per_bucket_count))
        del owner, k
    bucket_start = np.zeros(len(per_bucket_count) + 1, np.int64)
    np.cumsum(per_bucket_count, out=bucket_start[1:])
    frames = empty_aligned((len(counts), 4), np.float32)
    frames[:, 0:2] = cell_frames[:, 0:2]
    # the scan's low end is (offset - spread), so its bucket is floor((offset - (lowest + spread)) * scale)
    frames[:, 2] = lowest + cell_frames[:, 2]
    frames[:, 3] = scale
    return frames, aligned(cell_bucket[:-1].astype(np.uint32)), aligned(bucket_start.astype(np.uint32))
