"""Tables extended by appended scratches equal a fresh build at the same cell size, bit for bit."""
import dataclasses

import numpy as np

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.bsdf.tables.incremental import update_tables
from scratch_iridescence.mitsuba_bridge.bsdf.tables.grid import build_tables
from scratch_iridescence.mitsuba_bridge.scratch import ScratchSet

ARRAYS = ("segments", "references", "offsets", "cell_frames", "cell_start", "crossing_start", "crossing_partner",
          "crossing_along", "continuation")


def plate(count, seed, region=((0.05, 0.05), (0.95, 0.95))):
    return scratch.random_scratches(count, seed=seed, width=scratch.Gaussian(4e-6, 1.3e-6),
                                    depth=scratch.Gaussian(250e-9, 80e-9), depth_variation=(1.1, 0.04),
                                    length=(0.2, 0.6), region=region)


def assert_same(tables, reference):
    for name in ARRAYS:
        assert np.array_equal(getattr(tables, name), getattr(reference, name)), name
    assert (tables.origin, tables.cell_size, tables.shape, tables.piece_count, tables.margin) == \
        (reference.origin, reference.cell_size, reference.shape, reference.piece_count, reference.margin)


def test_appended_strokes_extend_the_tables_exactly_as_a_fresh_build_at_that_cell_size():
    scratches = plate(1500, 1)
    cache = update_tables(None, scratches)
    searched = cache.tables.cell_size
    assert not cache.incremental
    assert_same(cache.tables, build_tables(scratches))
    # more pieces than one CHUNK after a few strokes would need 65 536: the chunked direction sums
    # are exercised by the 3 000-scratch bench; here strokes of 1, 2 and 5 scratches, one crossing many cells
    for index, count in enumerate((1, 2, 5)):
        stroke = plate(count, 100 + index, region=((0.2, 0.2), (0.8, 0.8)))
        scratches = ScratchSet.concatenate([scratches, stroke])
        cache = update_tables(cache, scratches)
        assert cache.incremental
        assert_same(cache.tables, build_tables(scratches, searched))


def test_sets_over_one_chunk_of_pieces_sum_cell_directions_in_the_same_chunks():
    scratches = plate(2200, 3)  # ~85 000 pieces: two chunks of the reference pass
    cache = update_tables(None, scratches)
    assert cache.tables.piece_count > 65536
    scratches = ScratchSet.concatenate([scratches, plate(3, 4, region=((0.3, 0.3), (0.7, 0.7)))])
    cache = update_tables(cache, scratches)
    assert cache.incremental
    assert_same(cache.tables, build_tables(scratches, cache.tables.cell_size))


def test_other_changes_are_full_builds():
    scratches = plate(300, 5, region=((0.3, 0.3), (0.7, 0.7)))
    cache = update_tables(None, scratches)
    # a stroke outside the grid's box: a full build, still at the kept cell size
    outside = ScratchSet.concatenate([scratches, plate(1, 6, region=((0.9, 0.9), (0.99, 0.99)))])
    extended = update_tables(cache, outside)
    assert not extended.incremental
    assert_same(extended.tables, build_tables(outside, cache.tables.cell_size))
    # erased scratches (a shorter set) and another hint: the automatic or hinted build
    fewer = scratches.select(np.arange(200))
    assert_same(update_tables(cache, fewer).tables, build_tables(fewer))
    assert_same(update_tables(cache, outside, 1 / 64).tables, build_tables(outside, 1 / 64))
    # an appended scratch without pieces that scatter (zero length) keeps the tables
    one = plate(1, 7)
    flat = dataclasses.replace(one, uv=np.repeat(one.uv[:1], len(one.uv), axis=0))
    same = update_tables(cache, ScratchSet.concatenate([scratches, flat]))
    assert same.incremental and same.tables is cache.tables


def test_sets_over_the_cache_limit_are_always_built_in_full(monkeypatch):
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import incremental

    scratches = plate(300, 8)
    monkeypatch.setattr(incremental, "MAX_CACHED_PIECES", 100)  # 300 scratches give thousands of pieces
    cache = update_tables(None, scratches)
    assert cache.a is None
    more = ScratchSet.concatenate([scratches, plate(2, 9, region=((0.3, 0.3), (0.7, 0.7)))])
    extended = update_tables(cache, more)
    assert not extended.incremental
    assert_same(extended.tables, build_tables(more))


def test_with_crossing_pairs_strokes_extend_the_pair_list_exactly_as_a_fresh_build():
    """crossings = "height_field": the old pairs are renumbered and the stroke's own looked for in the cells
    its pieces touch; pairs, their order and their parameters equal a fresh build's bit for bit."""
    scratches = plate(400, 7, region=((0.3, 0.3), (0.7, 0.7)))
    cache = update_tables(None, scratches, crossings=True)
    kept = cache.tables.cell_size
    assert not cache.incremental and cache.tables.crossing_count > 100
    assert_same(cache.tables, build_tables(scratches, crossings=True))
    for index, count in enumerate((1, 3, 6)):  # strokes crossing many scratches (and, the last, themselves)
        before = cache.tables.crossing_count
        scratches = ScratchSet.concatenate([scratches, plate(count, 20 + index, region=((0.35, 0.35), (0.65, 0.65)))])
        cache = update_tables(cache, scratches, crossings=True)
        assert cache.incremental and cache.crossings and cache.tables.crossing_count > before
        assert_same(cache.tables, build_tables(scratches, kept, crossings=True))


def test_switching_the_crossings_option_is_a_full_build():
    scratches = plate(200, 7, region=((0.3, 0.3), (0.7, 0.7)))
    stroke = ScratchSet.concatenate([scratches, plate(3, 8, region=((0.4, 0.4), (0.6, 0.6)))])
    additive = update_tables(None, scratches)
    switched = update_tables(additive, stroke, crossings=True)
    assert not switched.incremental and switched.tables.crossing_count > 0
    assert_same(switched.tables, build_tables(stroke, crossings=True))
    back = update_tables(update_tables(None, scratches, crossings=True), stroke)
    assert not back.incremental and back.tables.crossing_count == 0
    assert_same(back.tables, build_tables(stroke))


def test_continuations_of_strokes_equal_a_fresh_builds_where_a_stroke_runs_on_from_a_scratch(monkeypatch):
    """How far each groove runs straight on (``continuation``): the old pieces' runs are kept and a
    stroke's own found, unless a stroke's end meets an old piece's end (then all are found again); either
    way a fresh build's, bit for bit."""
    def even(count, seed, region):  # no width or depth noise: the pieces of a scratch join
        return scratch.random_scratches(count, seed=seed, width=scratch.Constant(2e-6), depth=scratch.Constant(2e-7),
                                        length=(0.05, 0.1), region=region)

    scratches = even(300, 11, ((0.3, 0.3), (0.7, 0.7)))
    cache = update_tables(None, scratches)
    kept = cache.tables.cell_size
    assert np.count_nonzero(cache.tables.continuation) > 0
    inner = np.all((scratches.uv > 0.4) & (scratches.uv < 0.6), axis=1).reshape(-1, 2).all(axis=1)
    one = scratches.select(np.flatnonzero(inner)[:1])  # far inside the grid's box: strokes from it extend
    start, end = one.uv[0], one.uv[-1]
    strokes = (
        dataclasses.replace(one, uv=np.array([end, end + 0.2 * (end - start)])),  # on from its end
        dataclasses.replace(one, uv=np.array([start, start + [0.05, 0.02]])),  # from its start, elsewhere
        dataclasses.replace(one, uv=np.array([start - 0.2 * (end - start), start])),  # into both starts
        even(2, 12, ((0.4, 0.4), (0.6, 0.6))),  # elsewhere: long pieces split, each runs on
    )
    from scratch_iridescence.mitsuba_bridge.bsdf.tables import incremental

    searched = []  # pieces each extension searched for joins
    original = incremental.continuations
    monkeypatch.setattr(incremental, "continuations", lambda a, *rest: (searched.append(len(a)), original(a, *rest))[1])
    for stroke, all_again in zip(strokes, (True, False, True, False)):
        scratches = ScratchSet.concatenate([scratches, stroke])
        before = cache.tables.continuation
        searched.clear()
        cache = update_tables(cache, scratches)
        assert cache.incremental
        assert searched == [cache.tables.piece_count if all_again else cache.tables.piece_count - len(before)]
        assert_same(cache.tables, build_tables(scratches, kept))
        assert np.count_nonzero(cache.tables.continuation) > np.count_nonzero(before)
