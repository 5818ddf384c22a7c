"""The numpy side: segment table, UV grid of references, in-memory parameters."""
from __future__ import annotations

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf import tensors as memory
from scratch_iridescence.mitsuba_bridge.bsdf.tables.grid import MAX_PIECE_UV, TARGET_PER_CELL, build_tables, cell_references
from scratch_iridescence.mitsuba_bridge.scratch import Gaussian, Profile, ScratchFormatError, ScratchSet, random_scratches, subdivide


@pytest.fixture(scope="module")
def plate() -> ScratchSet:
    return random_scratches(400, seed=5, width=Gaussian(4e-6, 1.3e-6), depth=Gaussian(250e-9, 80e-9),
                            vertices=4, curvature=2.0, depth_variation=(1.1, 0.04), profile=Profile.TRIANGULAR)


def start_points(tables):
    rows = tables.segments.astype(np.float64)
    return rows[:, 0:2] + rows[:, 2:4], rows[:, 4:6]


def cells_of(tables):
    """Per piece, the set of cells that list it."""
    counts = np.diff(tables.cell_start.astype(np.int64))
    cell = np.repeat(np.arange(len(counts)), counts)
    listed = {}
    for c, piece in zip(cell, tables.references[:len(cell)]):
        listed.setdefault(int(piece), set()).add(int(c))
    return listed, cell


def test01_every_piece_is_listed_in_every_cell_it_crosses_once(plate):
    t = build_tables(plate)
    a, e = start_points(t)
    listed, cell = cells_of(t)
    assert len(listed) == t.piece_count
    # no cell lists a piece twice (the kernel evaluates a piece once per owning cell)
    pairs = cell.astype(np.int64) * t.piece_count + t.references[:len(cell)]
    assert len(np.unique(pairs)) == len(pairs)
    # dense points along every piece, nudged across by up to the dilation, fall in listed cells
    rng = np.random.default_rng(0)
    for piece in rng.choice(t.piece_count, 300, replace=False):
        s = np.linspace(0.0, 1.0, 257)[:, None]
        jitter = rng.uniform(-1, 1, (257, 2)) * 0.9 * t.margin * t.cell_size
        points = a[piece] + s * e[piece] + jitter
        uv = np.clip(np.floor((points - t.origin) / t.cell_size).astype(int), 0, np.array(t.shape) - 1)
        assert set((uv[:, 1] * t.shape[0] + uv[:, 0]).tolist()) <= listed[piece]
    assert np.abs(e).max() <= MAX_PIECE_UV * (1 + 1e-6)


def test01b_references_are_exact_for_a_diagonal_line():
    # a line from cell (0.5, 0.5) to (3.5, 2.5): exactly the cells it passes through
    h, origin, shape = 1.0, np.zeros(2), np.array([5, 4])
    cells, piece = cell_references(np.array([[0.5, 0.5]]), np.array([[3.5, 2.5]]), h, origin, shape, 0.0)
    expected = {(0, 0), (1, 0), (1, 1), (2, 1), (2, 2), (3, 2)}
    assert sorted(cells.tolist()) == sorted(v * 5 + u for u, v in expected) and np.all(piece == 0)


def test02_pieces_cover_the_scratches_exactly_once(plate):
    t = build_tables(plate)
    segments = subdivide(plate)
    kept = (segments.width > 0) & (segments.depth > 0)
    assert kept.sum() < len(segments)  # D[1.1, ...] pinches some pieces shut: they are dropped
    a, e = start_points(t)
    assert np.hypot(*e.T).sum() == pytest.approx(segments.length[kept].sum(), rel=1e-6)
    assert np.all(t.segments[:, 6] > 0) and np.all(t.segments[:, 7] < 0)  # µm widths; V-grooves negative


def test03_start_points_keep_float64_accuracy_as_float32_pairs():
    uv = np.array([[0.123456789012345, 0.987654321098765], [0.123456789112345, 0.987654321098765]])
    t = build_tables(ScratchSet.from_polylines([uv], width=1e-6, depth=1e-7))
    a = t.segments[0, 0:2].astype(np.float64) + t.segments[0, 2:4].astype(np.float64)
    assert np.abs(a - uv[0]).max() < 1e-14
    assert abs(t.segments[0, 4] - 1e-10) < 1e-16


def test04_empty_and_degenerate_sets_give_padded_tables():
    for scratches in (ScratchSet.empty(),
                      ScratchSet.from_polylines([np.array([[0.3, 0.3], [0.3, 0.3]])], width=1e-6, depth=1e-7)):
        t = build_tables(scratches)
        assert t.piece_count == 0 and t.segments.shape == (1, 8) and len(t.cell_start) == 2
        assert t.cell_start[-1] == 0 and t.references.shape == (1,)


def test05_cell_size_hint_is_rounded_up_to_a_power_of_two(plate):
    t = build_tables(plate, cell_size=0.003)
    assert t.cell_size == 2.0 ** -8


def test06_automatic_cell_size_keeps_occupied_cells_small(plate):
    t = build_tables(plate)
    starts = t.cell_start.astype(np.int64)
    counts = np.diff(starts)
    assert counts[counts > 0].mean() <= TARGET_PER_CELL * 1.1  # chosen on the unpadded crop
    assert t.piece_count <= 2 * len(subdivide(plate))  # pieces are no longer cut at cells


def test07_clustered_scratches_do_not_shrink_cells_below_their_spacing():
    # 12 parallel tracks 1.6e-5 apart: no cell size separates them better than the window would
    lines = [np.array([[0.2, 0.5 + k * 1.6e-5], [0.8, 0.5 + k * 1.6e-5]]) for k in range(12)]
    t = build_tables(ScratchSet.from_polylines(lines, width=1e-6, depth=1.2e-7))
    assert t.cell_size >= 1.0 / 256


def test07b_a_grating_sizes_its_cells_without_listing_its_grooves_at_finer_cells(monkeypatch):
    # Fig. 9's bands: 400 grooves at a 2.5e-5 pitch, 0.7 long.  Halving the cells down to the pitch and
    # doubling back (the search for sets of any directions) listed the grooves at every size on the way:
    # 3 s of the 3.4 s load.  Nearly parallel pieces at the largest allowed size stop the search there.
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import grid as tables

    y = 0.4 + 2.5e-5 * np.arange(400)
    grating = ScratchSet.from_polylines([np.array([[0.15, v], [0.85, v]]) for v in y], width=1e-6, depth=1e-6)
    listed_at = []
    real = tables.cell_references
    monkeypatch.setattr(tables, "cell_references", lambda a, b, h, *rest: listed_at.append(h) or real(a, b, h, *rest))
    t = build_tables(grating)
    assert t.cell_size == 2.0 ** -7  # half the longest piece (MAX_PIECE_UV): the size the full search ends at
    assert min(listed_at) == t.cell_size  # (no listing at finer cells)
    assert len(listed_at) == 1  # the spread test only (the table lists its references itself)


def test08_in_memory_values_round_trip_bit_for_bit(plate):
    values = memory.to_tensors(plate)
    assert set(values) == set(memory.KEYS)
    assert all(v.shape[0] == 1 for v in values.values())  # the leading axis of length 1
    assert memory.from_values(values) == plate
    flat = {key: np.asarray(value)[0] for key, value in values.items()}
    assert memory.from_values(flat) == plate


def test09_in_memory_values_name_the_bad_field(plate):
    values = {key: np.asarray(value)[0] for key, value in memory.to_tensors(plate).items()}
    with pytest.raises(ScratchFormatError, match="field 'seed'.*missing"):
        memory.from_values({k: v for k, v in values.items() if k != "scratch_seed"})
    with pytest.raises(ScratchFormatError, match="field 'width'"):
        memory.from_values(dict(values, scratch_width=-values["scratch_width"]))
    with pytest.raises(ScratchFormatError, match="field 'offsets'.*dtype"):
        memory.from_values(dict(values, scratch_offsets=values["scratch_offsets"].astype(np.float64)))


def test_each_cells_references_are_sorted_by_offset_as_a_float_comparison_orders_them():
    """The in-place sort by one uint64 key per reference (cell, then the offset's bits made
    order-preserving) against ``np.lexsort``: negative offsets, -0.0 beside 0.0, ties, cells of one and of
    many references, blocks that end mid-way."""
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import references as refs

    rng = np.random.default_rng(5)
    counts = rng.integers(0, 9, 400)
    cell_start = np.r_[0, np.cumsum(counts)].astype(np.uint32)
    offsets = rng.choice(np.array([-2.5, -1e-30, -0.0, 0.0, 1e-30, 0.75, 3.0], np.float32), cell_start[-1])
    offsets[::7] = rng.normal(size=len(offsets[::7])).astype(np.float32)
    references = np.arange(len(offsets), dtype=np.uint32)
    cell = np.repeat(np.arange(len(counts)), counts)
    expected = np.lexsort((offsets, cell))  # stable: equal offsets (-0.0 == 0.0) keep their order
    sorted_references, sorted_offsets = references.copy(), offsets.copy()
    refs._sort_cells_by_offset(sorted_references, sorted_offsets, cell_start, block=97)
    assert np.array_equal(sorted_references, references[expected])
    assert np.array_equal(sorted_offsets.view(np.uint32), offsets[expected].view(np.uint32))


def test_the_threaded_build_gives_the_one_threads_tables_bit_for_bit(plate, monkeypatch):
    """The pieces (chunks of whole scratches), the continuations, the reference passes and the per-cell
    sorts run on a few threads; their results are joined, added and written in chunk order, so the
    tables depend neither on the thread count nor on the chunk size (here: one chunk against ~100)."""
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import references as refs
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import grid as tables_module

    def build(chunk, threads):
        monkeypatch.setattr(refs, "CHUNK", chunk)
        monkeypatch.setattr(tables_module, "CHUNK", chunk)
        monkeypatch.setattr(refs, "BUILD_THREADS", threads)
        monkeypatch.setattr(refs.os, "cpu_count", lambda: 8)
        assert len(tables_module._scratch_chunks(plate)) == (1 if chunk > 10_000 else 400 // chunk + 1)
        tables = build_tables(plate)
        return [np.ascontiguousarray(getattr(tables, name)).tobytes()
                for name in ("segments", "references", "offsets", "cell_frames", "cell_start", "continuation")]

    one = build(1 << 16, 1)
    assert build(3, 4) == one  # 134 chunks of 3 scratches (12 vertices: both budgets cut alike)
    assert build(97, 4) == one and build(97, 1) == one


def test_ordered_map_keeps_the_order_loses_nothing_and_holds_a_few_results():
    """Every item once, results in the items' order whatever the threads' timing, and at most twice as
    many submitted-but-unread results as threads."""
    import threading
    import time

    from scratch_iridescence.mitsuba_bridge.bsdf.tables.references import ordered_map

    rng = np.random.default_rng(2)
    delays = rng.uniform(0, 2e-3, 101)
    started, lock = [], threading.Lock()

    def work(item):
        with lock:
            started.append(item)
        time.sleep(delays[item])
        return item * item

    read = 0
    for read, value in enumerate(ordered_map(work, range(101), threads=3), start=1):
        assert value == (read - 1) ** 2
        with lock:
            assert len(started) - read <= 2 * 3
    assert read == 101 and sorted(started) == list(range(101))
