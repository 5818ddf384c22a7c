"""Fuzzing the tables cache's reader (mitsuba_bridge/bsdf/tables/cache_file.py, disk_cache.py): a mutated file is a
``CacheFileError`` (a miss) or exactly what was written, never another exception and never a large allocation.

Byte mutations (bit flips, truncations, inserted and overwritten bytes) hit the magic, the signature, the header
or the data; structural mutations re-sign a header whose identity, array directory or records are wrong (as a bug
in the writer would), so that the checks behind the signature are reached too.  Through ``disk_cache.load_tables``
the same files are a warning and a miss.  The seed is fixed; the fast subset runs in ``make test``, the long run
under ``make test-slow``.
"""
from __future__ import annotations

import hashlib
import hmac
import io
import json
import logging

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.bsdf.tables import cache_file, disk_cache

SEED = 20261209
SECRET = bytes(range(32))
IDENTITY = {"key": "ab" * 20, "options": "(0.0, False, True, True)", "code": "c0de" * 16}
MAX_BYTES = 1 << 20


def original() -> tuple[bytes, dict, dict]:
    rng = np.random.default_rng(1)
    arrays = {"tables.segments": rng.random((40, 8)).astype(np.float32),
              "tables.references": np.arange(77, dtype=np.uint32),
              "tables.cell_start": np.arange(10, dtype=np.uint32), "scan.bucketed": np.array([True]),
              "cache.a": rng.random((40, 2)), "empty": np.zeros((0, 4), np.float32)}
    records = {"tables": {"segments": ["array", None], "origin": ["value", [0.0, 0.25]]}, "cache": {"crossings": [
        "value", False]}}
    stream = io.BytesIO()
    cache_file.write(stream, SECRET, IDENTITY, records, arrays)
    return stream.getvalue(), records, arrays


def read(data: bytes, tmp_path):
    path = tmp_path / "entry.scratch-tables"
    path.write_bytes(data)
    with open(path, "rb") as stream:
        return cache_file.read(stream, SECRET, IDENTITY, MAX_BYTES)


def byte_mutation(data: bytes, rng) -> bytes:
    kind = int(rng.integers(4))
    if kind == 0:
        mutated = bytearray(data)
        for _ in range(int(rng.integers(1, 4))):
            mutated[int(rng.integers(len(data)))] ^= 1 << int(rng.integers(8))
        return bytes(mutated)
    if kind == 1:
        return data[:int(rng.integers(len(data)))]
    where = int(rng.integers(len(data) + 1))
    run = rng.bytes(int(rng.integers(1, 24)))
    return data[:where] + run + data[where:] if kind == 2 else data[:where] + run + data[where + len(run):]


def resigned(data: bytes, edit) -> bytes:
    """The file with its header edited by ``edit`` and signed again with the right secret."""
    start = len(cache_file.MAGIC) + 32
    length = int.from_bytes(data[start:start + 8], "little")
    header = json.loads(data[start + 8:start + 8 + length])
    edit(header)
    text = json.dumps(header).encode()
    return (cache_file.MAGIC + hmac.new(SECRET, text, hashlib.sha256).digest() + len(text).to_bytes(8, "little")
            + text + data[start + 8 + length:])


def structural_mutation(data: bytes, rng) -> bytes:
    weird = [-1, 0, 2 ** 62, 2 ** 31, 3.5, "x", None, [], {}, [1, 2], "|O", "<U8", "V16", ">f8", "<c16", "float128"]

    def edit(header):
        kind = int(rng.integers(4))
        if kind == 0:  # an array directory entry (a name: none at all, or another entry's; a renamed array is a
            # consistent file of other arrays, which the records then miss: test02)
            entry = header["arrays"][int(rng.integers(len(header["arrays"])))]
            field = int(rng.integers(5))
            names = [-1, None, [], "", header["arrays"][0][0] if entry is not header["arrays"][0] else
                     header["arrays"][1][0]]
            shapes = [-1, 3.5, "x", None, {}, [-3], [1 << 40], [2, 3, 5]]  # (none holds the entry's bytes)
            entry[field] = names[int(rng.integers(len(names)))] if field == 0 else \
                shapes[int(rng.integers(len(shapes)))] if field == 2 else weird[int(rng.integers(len(weird)))]
        elif kind == 1:  # identity and layout fields
            header[str(rng.choice(["key", "options", "code", "layout", "marker", "content"]))] = \
                weird[int(rng.integers(len(weird)))]
        elif kind == 2:  # the directory itself
            header["arrays"] = weird[int(rng.integers(len(weird)))] if rng.random() < 0.5 else \
                header["arrays"][::-1]
        else:  # an entry whose shape claims far more data than the file holds
            entry = header["arrays"][int(rng.integers(len(header["arrays"])))]
            entry[2], entry[4] = [1 << 40], (1 << 40) * np.dtype(entry[1]).itemsize
    return resigned(data, edit)


def run_fuzz(tmp_path, count: int) -> dict:
    data, records, arrays = original()
    read_records, read_arrays, _ = read(data, tmp_path)
    assert read_records == records and all(np.array_equal(read_arrays[k], v) for k, v in arrays.items())
    rng = np.random.default_rng(SEED)
    found = {}
    for case in range(count):
        mutated = structural_mutation(data, rng) if case % 3 == 2 else byte_mutation(data, rng)
        try:
            got_records, got_arrays, _ = read(mutated, tmp_path)
        except cache_file.CacheFileError:
            result = "refused"
        else:
            same = got_records == records and got_arrays.keys() == arrays.keys() and all(
                got_arrays[k].dtype == v.dtype and np.array_equal(got_arrays[k], v) for k, v in arrays.items())
            result = "same" if same else "different"
        found[result] = found.get(result, 0) + 1
        assert result != "different", case
    return found


def test01_mutated_cache_files_are_refused_or_read_exactly(tmp_path):
    found = run_fuzz(tmp_path, 600)
    assert found.get("refused", 0) > 500, found


def test02_through_the_cache_a_mutated_file_is_a_warning_and_a_miss(tmp_path, monkeypatch, caplog):
    """Mutated copies of a real entry, read by ``load_tables``: a miss each time, never an exception."""
    import gc

    from scratch_iridescence.mitsuba_bridge.bsdf import persistent
    from test_disk_cache import grating, load

    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(tmp_path / "root"))
    monkeypatch.setattr(disk_cache, "MIN_BUILD_SECONDS", 0.0)
    persistent.forget()
    load(grating(), coherent=False)
    gc.collect()
    (path,) = (tmp_path / "root" / "tables").glob("*.scratch-tables")
    data = path.read_bytes()
    secret = (tmp_path / "root" / "tables" / "secret.key").read_bytes()
    header_start = len(cache_file.MAGIC) + 32
    header = json.loads(data[header_start + 8:header_start + 8 + int.from_bytes(data[header_start:header_start + 8],
                                                                               "little")])
    rng = np.random.default_rng(SEED)
    hits = disk_cache.statistics()["hits"]
    for case in range(40):
        path.write_bytes(byte_mutation(data, rng))
        with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
            assert disk_cache.load_tables(bytes.fromhex(header["key"]), None, header["options"]) is None, case
    assert disk_cache.statistics()["hits"] == hits and "is not used" in caplog.text
    path.write_bytes(data)  # the intact file still serves
    assert disk_cache.load_tables(bytes.fromhex(header["key"]), grating(), header["options"]) is not None
    assert secret == (tmp_path / "root" / "tables" / "secret.key").read_bytes()


@pytest.mark.slow
def test03_the_long_run(tmp_path):
    found = run_fuzz(tmp_path, 20_000)
    assert found.get("refused", 0) > 17_000, found


def test04_the_block_digest_does_not_depend_on_how_the_data_arrives():
    """Blocks straddling the pieces handed over (arrays, read chunks, padding) are hashed as one stream."""
    data = np.random.default_rng(3).integers(0, 256, 3 * cache_file._BLOCK + 12345, dtype=np.uint8)
    expected = hashlib.sha256(cache_file._BLOCK.to_bytes(8, "little"))
    for start in range(0, len(data), cache_file._BLOCK):
        expected.update(hashlib.sha256(data[start:start + cache_file._BLOCK].tobytes()).digest())
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        cuts = np.sort(rng.integers(0, len(data), int(rng.integers(1, 40))))
        with cache_file._BlockDigest() as digest:
            for piece in np.split(data, cuts):
                digest.update(memoryview(piece))
            assert digest.hexdigest() == expected.hexdigest()
