"""The scratch tables' disk cache (mitsuba_bridge/bsdf/tables/disk_cache.py): a new BSDF of a set built before (by
another process, here a BSDF that is gone) reads its tables instead of building them, the same to the last
bit; damaged files, full or read-only folders and a size limit never fail a load."""
from __future__ import annotations

import dataclasses
import gc
import logging

import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.bsdf import persistent
from scratch_iridescence.mitsuba_bridge.bsdf.tables import disk_cache
import shading


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder that every build is written to (the tests' sets build in milliseconds)."""
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(tmp_path / "root"))
    folder = tmp_path / "root" / disk_cache.SUBFOLDER
    monkeypatch.delenv("SCRATCH_IRIDESCENCE_CACHE_MB", raising=False)
    monkeypatch.setattr(disk_cache, "MIN_BUILD_SECONDS", 0.0)
    persistent.forget()
    return folder


def grating(tracks=40, pitch=2.5e-6, seed=0):
    """Parallel grooves (periodic families, offset buckets: every array the cache stores)."""
    y = 0.5 + pitch * np.arange(tracks) / 0.01
    lines = [np.array([[0.3, v], [0.7, v]]) for v in y]
    return scratch.ScratchSet.from_polylines(lines, width=1e-6, depth=1e-6)


def load(scratches, **options):
    return mi.load_dict(scratch_bsdf.plugin_dict(scratches, unit_scale=0.01, **options))


def arrays_of(bsdf) -> dict:
    """Every numpy array of the BSDF's tables, and the Grid's Dr.Jit arrays as numpy."""
    found = {f"tables.{f.name}": getattr(bsdf.tables, f.name) for f in dataclasses.fields(bsdf.tables)}
    found.update({f"grid.{f.name}": np.asarray(getattr(bsdf.grid, f.name)) for f in dataclasses.fields(bsdf.grid)
                  if getattr(bsdf.grid, f.name) is not None and not isinstance(getattr(bsdf.grid, f.name),
                                                                                (bool, int))})
    return found


def evaluate(bsdf, count=4000):
    rng = np.random.default_rng(3)
    si = shading.interaction(count, shading.direction(30, 80))
    si.uv = mi.Point2f(shading.floats(rng.uniform(0.45, 0.55, count)), shading.floats(rng.uniform(0.49, 0.52, count)))
    wo = mi.warp.square_to_uniform_hemisphere(mi.Point2f(shading.floats(rng.random(count)),
                                                         shading.floats(rng.random(count))))
    value, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, wo)
    return np.asarray(value), np.asarray(pdf)


def built_then_read(scratches, **options):
    """(first BSDF's arrays and values, second BSDF's) with the first one gone before the second loads."""
    first = load(scratches, **options)
    before = arrays_of(first), evaluate(first), str(first)
    del first
    gc.collect()
    second = load(scratches, **options)
    return before, (arrays_of(second), evaluate(second), str(second))


@pytest.mark.parametrize("options", [{"coherent": False}, {"coherent": True, "crossings": "height_field"}],
                         ids=["incoherent", "height_field"])
def test01_a_set_built_once_is_read_back_the_same_to_the_last_bit(cache, options):
    counts = disk_cache.statistics()
    (arrays, values, text), (read_arrays, read_values, read_text) = built_then_read(grating(), **options)
    now = disk_cache.statistics()
    assert (now["writes"] - counts["writes"], now["hits"] - counts["hits"]) == (1, 1)
    assert len(list(cache.glob("*.scratch-tables"))) == 1
    assert read_arrays.keys() == arrays.keys() and "grid.family_frames" in arrays
    for name, value in arrays.items():
        read = read_arrays[name]
        if isinstance(value, np.ndarray):
            assert read.dtype == value.dtype and read.shape == value.shape and np.array_equal(read, value), name
        else:  # None, the grid's origin and shape, the cell size
            assert read == value and type(read) is type(value), name
    assert read_text == text and "periodic families=0" not in text
    for a, b in zip(values, read_values):
        assert a.tobytes() == b.tobytes() and np.abs(a).max() > 0


def test02_other_options_or_other_code_miss(cache, monkeypatch):
    scratches = grating()
    load(scratches, coherent=False)
    gc.collect()
    load(scratches, coherent=True)  # another model: another build, another file
    gc.collect()
    assert len(list(cache.glob("*.scratch-tables"))) == 2
    monkeypatch.setattr(disk_cache, "_fingerprint", "edited source")  # as after an edit of bsdf/*.py
    counts = disk_cache.statistics()
    load(scratches, coherent=False)
    assert disk_cache.statistics()["hits"] == counts["hits"]
    assert len(list(cache.glob("*.scratch-tables"))) == 3


@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty"])
def test03_a_damaged_file_is_a_miss_and_is_replaced(cache, damage, caplog):
    scratches = grating()
    arrays, values, _ = built_then_read(scratches, coherent=False)[0]
    gc.collect()
    (path,) = cache.glob("*.scratch-tables")
    data = path.read_bytes()
    path.write_bytes({"truncated": data[: len(data) // 2], "garbage": bytes(range(256)) * 50, "empty": b""}[damage])
    counts = disk_cache.statistics()
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        bsdf = load(scratches, coherent=False)
    assert "is not used" in caplog.text and str(path) in caplog.text
    now = disk_cache.statistics()
    refused = now["damaged"] + now["foreign"] - counts["damaged"] - counts["foreign"]
    assert refused == 1 and now["writes"] == counts["writes"] + 1
    for a, b in zip(evaluate(bsdf), values):
        assert a.tobytes() == b.tobytes()
    del bsdf
    gc.collect()
    counts = disk_cache.statistics()
    load(scratches, coherent=False)  # the rewritten file serves the next BSDF (none of the old one is alive)
    assert disk_cache.statistics()["hits"] == counts["hits"] + 1


def test04_off_unwritable_or_full_never_fails_a_load(cache, monkeypatch, tmp_path, caplog):
    scratches = grating()
    expected = evaluate(load(scratches, coherent=False))
    gc.collect()
    for setting in ("off", "OFF"):
        monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", setting)
        assert disk_cache.directory() is None
    blocked = tmp_path / "a file where the folder should be"
    blocked.write_text("not a folder")
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(blocked / "root"))
    counts = disk_cache.statistics()
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        bsdf = load(grating(tracks=41), coherent=False)
    assert disk_cache.statistics()["failed_writes"] == counts["failed_writes"] + 1
    assert "could not write" in caplog.text and blocked.read_text() == "not a folder"
    assert np.abs(evaluate(bsdf)[0]).max() > 0
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(cache.parent))

    def read_only(*arguments, **keywords):  # a cache folder shared read-only (root ignores chmod here)
        raise PermissionError("read-only file system")

    monkeypatch.setattr(disk_cache.os, "utime", read_only)
    counts = disk_cache.statistics()
    assert all(a.tobytes() == b.tobytes() for a, b in zip(evaluate(load(scratches, coherent=False)), expected))
    assert disk_cache.statistics()["hits"] == counts["hits"] + 1 and len(list(cache.glob("*.scratch-tables"))) == 1
    assert not list(cache.glob(".*.tmp"))  # no half-written file left


def test05_the_size_limit_removes_the_least_recently_used_files(cache, monkeypatch):
    import os
    import time

    sets = [grating(tracks=30 + k) for k in range(3)]
    for k, scratches in enumerate(sets):
        load(scratches, coherent=False)
        gc.collect()
        for index, path in enumerate(sorted(cache.glob("*.scratch-tables"), key=lambda p: p.stat().st_mtime)):
            os.utime(path, (time.time() - 100 + index, time.time() - 100 + index))  # distinct ages
    files = sorted(cache.glob("*.scratch-tables"), key=lambda p: p.stat().st_mtime)
    assert len(files) == 3
    # room for what is there: the next write (a smaller set) removes the oldest file, and only that one
    limit = sum(p.stat().st_size for p in files) - 1
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_MB", str(limit / 2 ** 20))
    load(grating(tracks=20), coherent=False)
    left = set(cache.glob("*.scratch-tables"))
    assert files[0] not in left and files[1] in left and files[2] in left and len(left) == 3
    assert sum(p.stat().st_size for p in left) <= disk_cache.limit_bytes()


def test_the_code_fingerprint_covers_every_table_and_kernel_module():
    """A change to any module that builds or reads the tables (subfolders included) is a new cache key."""
    sources = disk_cache.fingerprinted_sources()
    folders = {source.parent.name for source in sources}
    assert {"bsdf", "tables", "maths", "periodic", "heightfield", "scratch"} <= folders, folders
    assert any(source.parent.name == "tables" and source.name == "grid.py" for source in sources)
