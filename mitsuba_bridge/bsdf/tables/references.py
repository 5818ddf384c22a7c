"""The references of a UV grid to the pieces crossing its cells, sorted by offset (numpy only).

See :mod:`.tables` for what the kernel reads and why.  Here: which cells a
straight piece crosses (:func:`cell_references`), the cells' dominant normals
and each reference's offset along them, the counting sort into CSR order and the
per-cell sort by offset, and 64-byte aligned buffers for the upload.
"""
from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

__all__ = ["cell_references", "sorted_references", "doubled_angles", "normals", "offsets_in_cell",
           "expand", "aligned", "empty_aligned", "aligned_array", "ordered_map", "CHUNK", "BUILD_THREADS"]

#: Pieces processed at a time.
CHUNK = 1 << 16
#: Most threads a table build uses (numpy releases the GIL in its loops; each chunk is independent).
BUILD_THREADS = 4


def cell_references(a, b, h, origin, shape, margin):
    """``(cell, piece)`` for every grid cell that piece ``a[i] → b[i]`` passes within ``margin`` cells of.

    Exact for straight pieces: the piece is cut at the (dilated) column
    boundaries and each part lists the rows its v-range covers.  Cells are
    clipped to the grid and never repeat for one piece.
    """
    nu, nv = int(shape[0]), int(shape[1])
    ga, gb = (a - origin) / h, (b - origin) / h
    u_lo, u_hi = np.minimum(ga[:, 0], gb[:, 0]), np.maximum(ga[:, 0], gb[:, 0])
    col0 = np.clip(np.floor(u_lo - margin), 0, nu - 1).astype(np.int64)
    col1 = np.clip(np.floor(u_hi + margin), 0, nu - 1).astype(np.int64)
    piece, col = expand(col0, col1 - col0 + 1)
    # the part of the piece inside the dilated column, and its v-range
    s0 = np.maximum(u_lo[piece], col - margin)
    s1 = np.minimum(u_hi[piece], col + 1 + margin)
    # rows gathered with np.take: several times faster than fancy indexing (numpy 1.26)
    du, start, end = (np.take(x, piece, axis=0) for x in (gb - ga, ga, gb))
    steep = np.abs(du[:, 0]) <= 1e-12 * np.maximum(np.abs(du[:, 1]), 1e-300)
    slope = np.where(steep, 0.0, du[:, 1] / np.where(steep, 1.0, du[:, 0]))
    va = start[:, 1] + (s0 - start[:, 0]) * slope
    vb = start[:, 1] + (s1 - start[:, 0]) * slope
    v_min, v_max = np.minimum(start[:, 1], end[:, 1]), np.maximum(start[:, 1], end[:, 1])
    v_lo = np.where(steep, v_min, np.clip(np.minimum(va, vb), v_min, v_max))
    v_hi = np.where(steep, v_max, np.clip(np.maximum(va, vb), v_min, v_max))
    row0 = np.clip(np.floor(v_lo - margin), 0, nv - 1).astype(np.int64)
    row1 = np.clip(np.floor(v_hi + margin), 0, nv - 1).astype(np.int64)
    part, row = expand(row0, row1 - row0 + 1)
    return row * nu + col[part], piece[part]


def expand(first, counts):
    """``(owner, first[owner] + k)`` for k < counts[owner]: a vectorised nested loop."""
    owner = np.repeat(np.arange(len(first)), counts)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
    return owner, first[owner] + k


def sorted_references(a, b, h, origin, shape, margin):
    """``references``, ``offsets`` and ``cell_frames`` grouped by cell, and ``cell_start``.

    Three chunked passes: the first counts the references per cell and sums
    their directions (doubled angles: a line and its reverse agree), the
    second writes every reference straight to its place with the offset of
    its in-cell part along the cell's normal, the third sorts each cell's
    references by offset, a block of cells at a time.  Only the final tables
    are ever held in full.  The chunks' work runs on a few threads
    (:func:`ordered_map`); what they return is added and written in chunk
    order, so the tables are the same bit for bit on any number of threads.
    """
    cell_count = int(shape[0] * shape[1])
    counts = np.zeros(cell_count, dtype=np.int64)
    doubled = np.zeros((2, cell_count))

    def count(part):
        cells, piece = cell_references(a[part], b[part], h, origin, shape, margin)
        return np.bincount(cells, minlength=cell_count), doubled_angles(a[part], b[part], cells, piece, cell_count)

    for chunk_counts, chunk_doubled in ordered_map(count, _chunks(len(a))):
        counts += chunk_counts
        doubled += chunk_doubled
    frames = empty_aligned((cell_count, 4), np.float32)
    frames[:, 0:2] = normals(doubled)
    frames[:, 2:] = 0.0
    del doubled
    normal = frames[:, 0:2].astype(np.float64)

    cell_start = empty_aligned(cell_count + 1, np.uint32)
    cell_start[0] = 0
    np.cumsum(counts, out=cell_start[1:])
    cursor = cell_start[:-1].astype(np.int64)
    total = max(int(cell_start[-1]), 1)
    references = empty_aligned(total, np.uint32)
    offsets = empty_aligned(total, np.float32)
    references[:1], offsets[:1] = 0, 0.0
    spread = np.zeros(cell_count)

    def place(part):
        """The chunk's references grouped by cell, each with its rank in its cell's run."""
        cells, piece = cell_references(a[part], b[part], h, origin, shape, margin)
        low, extent = offsets_in_cell((a[part] - origin) / h, (b[part] - origin) / h, cells, piece,
                                       normal, shape, margin)
        order = np.argsort(cells, kind="stable")
        cells = cells[order]
        runs = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]])  # start of each cell's run in the chunk
        first = np.repeat(runs, np.diff(np.r_[runs, len(cells)]))  # (a searchsorted of cells in itself: 5x slower)
        return (cells, np.arange(len(cells)) - first, piece[order] + part.start, low[order], cells[runs],
                np.maximum.reduceat(extent[order], runs), np.bincount(cells, minlength=cell_count))

    for cells, rank, piece, low, run_cells, run_extent, chunk_counts in ordered_map(place, _chunks(len(a))):
        destination = cursor[cells] + rank
        references[destination] = piece
        offsets[destination] = low
        spread[run_cells] = np.maximum(spread[run_cells], run_extent)
        cursor += chunk_counts
    # float32 offsets are rounded down (a lower bound never excludes a piece): widen the spread by an ulp
    frames[:, 2] = spread * (1.0 + 1e-6) + 1e-6
    _sort_cells_by_offset(references, offsets, cell_start)
    return references, offsets, frames, cell_start


def ordered_map(function, items, threads: int | None = None):
    """``function(item)`` for each of ``items`` on up to ``threads`` threads (default
    :data:`BUILD_THREADS`, at most the cores), yielded in the items' order; at most twice as many results
    as threads wait at a time, so memory stays a few chunks' worth."""
    threads = max(1, min(threads or BUILD_THREADS, os.cpu_count() or 1))
    items = list(items)
    if threads == 1 or len(items) < 2:  # a stroke's few pieces: no pool to start
        yield from map(function, items)
        return
    items = iter(items)
    with ThreadPoolExecutor(max_workers=threads) as pool:
        pending = [pool.submit(function, item) for item in itertools.islice(items, 2 * threads)]
        while pending:
            result = pending.pop(0).result()
            pending.extend(pool.submit(function, item) for item in itertools.islice(items, 1))
            yield result


def doubled_angles(a, b, cells, piece, cell_count):
    """Per cell, the sum of (cos 2φ, sin 2φ) of its pieces' directions (a line and its reverse agree)."""
    e = np.take(b - a, piece, axis=0)
    norm = np.maximum(np.einsum("ij,ij->i", e, e), 1e-300)
    return np.stack([np.bincount(cells, (e[:, 0] ** 2 - e[:, 1] ** 2) / norm, minlength=cell_count),
                     np.bincount(cells, 2.0 * e[:, 0] * e[:, 1] / norm, minlength=cell_count)])


def normals(doubled):
    """Unit normals (n_u, n_v) of the cells' dominant directions."""
    angle = 0.5 * np.arctan2(doubled[1], doubled[0])
    return np.stack([-np.sin(angle), np.cos(angle)], axis=1)


def offsets_in_cell(ga, gb, cells, piece, normal, shape, margin):
    """Lowest offset (float32, rounded down) and offset extent of each reference's in-cell part, in cells.

    The part of the piece inside the dilated cell [u - m, u + 1 + m] × [v - m, v + 1 + m]
    (Liang–Barsky clipping), measured from the cell's corner.
    """
    nu = int(shape[0])
    corner = np.stack([cells % nu, cells // nu], axis=1).astype(np.float64)
    start, direction = np.take(ga, piece, axis=0) - corner, np.take(gb - ga, piece, axis=0)
    t0, t1 = np.zeros(len(piece)), np.ones(len(piece))
    for axis in range(2):
        d = direction[:, axis]
        moving = np.abs(d) > 1e-300
        safe = np.where(moving, d, 1.0)
        enter = (-margin - start[:, axis]) / safe
        leave = (1.0 + margin - start[:, axis]) / safe
        t0 = np.where(moving, np.maximum(t0, np.minimum(enter, leave)), t0)
        t1 = np.where(moving, np.minimum(t1, np.maximum(enter, leave)), t1)
    empty = t0 > t1  # only by rounding (the cell lists the piece): keep the whole piece
    t0, t1 = np.where(empty, 0.0, t0), np.where(empty, 1.0, t1)
    n = np.take(normal, cells, axis=0)
    k0 = np.einsum("ij,ij->i", start + t0[:, None] * direction, n)
    k1 = np.einsum("ij,ij->i", start + t1[:, None] * direction, n)
    low, high = np.minimum(k0, k1), np.maximum(k0, k1)
    low32 = low.astype(np.float32)  # stored as a lower bound: rounded down
    low32 = np.where(low32 > low, np.nextafter(low32, np.float32(-np.inf)), low32)
    return low32, high - low32.astype(np.float64)


def _sort_cells_by_offset(references, offsets, cell_start, block=1 << 22):
    """Sort each cell's references by offset, in place, a block of whole cells at a time.

    One stable argsort of a uint64 key per block, the cell in the high half and the offset's float32
    bits made order-preserving in the low half: the order of ``np.lexsort((offsets, cell))``, in
    less time (the cells come in order, runs that the stable sort merges; the CD's tables 18 → 14 s).
    The blocks are disjoint, so they sort on a few threads (:func:`ordered_map`).
    """
    starts = cell_start.astype(np.int64)
    blocks, first_cell = [], 0
    while first_cell < len(starts) - 1:
        last_cell = int(np.searchsorted(starts, starts[first_cell] + block, side="right")) - 1
        last_cell = min(max(last_cell, first_cell + 1), len(starts) - 1)
        if starts[last_cell] > starts[first_cell]:
            blocks.append((first_cell, last_cell))
        first_cell = last_cell

    def sort(cells):
        first_cell, last_cell = cells
        lo, hi = starts[first_cell], starts[last_cell]
        counts = np.diff(starts[first_cell:last_cell + 1])
        cell = np.repeat(np.arange(len(counts), dtype=np.uint64), counts)
        order = np.argsort((cell << np.uint64(32)) | _sortable_bits(offsets[lo:hi]), kind="stable")
        references[lo:hi] = references[lo:hi][order]
        offsets[lo:hi] = offsets[lo:hi][order]

    for _ in ordered_map(sort, blocks):
        pass


def _sortable_bits(values):
    """uint64 keys of float32 ``values`` that order as the values do (-0.0 and 0.0 alike, no NaN)."""
    bits = (values + np.float32(0.0)).view(np.uint32)  # (+ 0: -0.0 becomes 0.0, as a float comparison has it)
    negative = (bits >> np.uint32(31)).astype(bool)
    return np.where(negative, ~bits, bits | np.uint32(1 << 31)).astype(np.uint64)


def _chunks(count):
    for start in range(0, count, CHUNK):
        yield slice(start, min(start + CHUNK, count))


ALIGNMENT = 64


def empty_aligned(shape, dtype) -> np.ndarray:
    """``np.empty`` starting on a 64-byte boundary (see :func:`aligned`)."""
    dtype = np.dtype(dtype)
    size = int(np.prod(shape)) * dtype.itemsize
    raw = np.empty(size + ALIGNMENT, dtype=np.uint8)
    offset = (-raw.ctypes.data) % ALIGNMENT
    return raw[offset:offset + size].view(dtype).reshape(shape)


def aligned(array: np.ndarray) -> np.ndarray:
    """``array`` as a contiguous array on a 64-byte boundary (the array itself when it already is).

    Dr.Jit's CPU backend maps numpy memory without copying, and emits different
    (packet or element) gathers depending on its alignment.
    """
    array = np.ascontiguousarray(array)
    if array.ctypes.data % ALIGNMENT == 0:
        return array
    result = empty_aligned(array.shape, array.dtype)
    result[...] = array
    return result


def aligned_array(kind, array: np.ndarray):
    """A Dr.Jit array ``kind`` (``mi.Float``, ``mi.UInt32``) of ``array``, 64-byte aligned.

    On the CPU Dr.Jit maps numpy's memory without copying, and the alignment
    decides whether it emits packet gathers: the kernels would then differ (and
    miss the kernel cache) from one upload to the next, wherever ``malloc`` put
    the buffer.  An unaligned array is copied into an aligned buffer first.
    """
    return kind(aligned(array))
