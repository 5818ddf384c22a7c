"""The tables cache trusts only what it wrote for the set asked for (mitsuba_bridge/bsdf/tables/disk_cache.py,
cache_file.py): planted files (another set's tables, scaled or NaN tables, a symbolic link, a file signed with
another secret) are a warning and the right values; a folder of the user's files is never touched; settings
are parsed safely; a full disk during a write is one warning; inside Blender the folder is the extension's."""
from __future__ import annotations

import gc
import json
import logging
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.bsdf import persistent
from scratch_iridescence.mitsuba_bridge.bsdf.tables import cache_file, disk_cache
from test_disk_cache import evaluate, grating, load

ROOT = Path(__file__).resolve().parents[4]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(tmp_path / "root"))
    monkeypatch.delenv("SCRATCH_IRIDESCENCE_CACHE_MB", raising=False)
    monkeypatch.setattr(disk_cache, "MIN_BUILD_SECONDS", 0.0)
    persistent.forget()
    return tmp_path / "root" / disk_cache.SUBFOLDER


def files(folder: Path) -> set[Path]:
    return set(folder.glob("*.scratch-tables"))


def written_by(cache: Path, scratches) -> tuple[Path, tuple]:
    """Load ``scratches`` (its file written), return its file and the values a BSDF of its own tables gives."""
    before = files(cache)
    bsdf = load(scratches, coherent=False)
    values = evaluate(bsdf)
    del bsdf
    gc.collect()
    (path,) = files(cache) - before
    return path, values


def same(values, expected) -> bool:
    return all(a.tobytes() == b.tobytes() for a, b in zip(values, expected)) and np.abs(values[0]).max() > 0


def read_file(path: Path) -> tuple[dict, int]:
    """The header of a cache file (read as anyone can, without the secret) and where its data starts."""
    data = path.read_bytes()
    start = len(cache_file.MAGIC) + 32
    length = int.from_bytes(data[start:start + 8], "little")
    return json.loads(data[start + 8:start + 8 + length]), start + 8 + length


def edit_floats(path: Path, change) -> None:
    """Apply ``change`` to every float array of the file in place, leaving its header (and signature) as it was."""
    header, data_start = read_file(path)
    data = bytearray(path.read_bytes())
    for name, dtype, shape, offset, nbytes in header["arrays"]:
        if np.dtype(dtype).kind == "f" and nbytes:
            where = slice(data_start + offset, data_start + offset + nbytes)
            data[where] = change(np.frombuffer(bytes(data[where]), dtype=dtype)).astype(dtype).tobytes()
    path.write_bytes(bytes(data))


PLANTS = {
    "another set's tables": lambda own, other: shutil.copyfile(other, own),
    "another set's tables, linked": lambda own, other: (own.unlink(), own.symlink_to(other)),
    "scaled x10": lambda own, other: edit_floats(own, lambda values: values * 10),
    "NaN": lambda own, other: edit_floats(own, lambda values: np.full_like(values, np.nan)),
}
WARNINGS = {"another set's tables": "holds the tables of another scratch set",
            "another set's tables, linked": "is a symbolic link, not a regular file",
            "scaled x10": "damaged or altered data", "NaN": "damaged or altered data"}


@pytest.mark.parametrize("plant", list(PLANTS))
def test01_a_planted_file_is_a_warning_and_the_right_values(cache, caplog, plant):
    own, expected = written_by(cache, grating(tracks=41))
    other, _ = written_by(cache, grating(tracks=37, pitch=3e-6))
    other_bytes = other.read_bytes()
    PLANTS[plant](own, other)
    counts = disk_cache.statistics()
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        bsdf = load(grating(tracks=41), coherent=False)
    assert WARNINGS[plant] in caplog.text and str(own) in caplog.text, caplog.text
    assert disk_cache.statistics()["hits"] == counts["hits"]
    assert same(evaluate(bsdf), expected)
    # the planted file is replaced by the set's own (a regular file; the other set's file untouched) ...
    assert own.is_file() and not own.is_symlink() and other.read_bytes() == other_bytes
    del bsdf
    gc.collect()
    counts = disk_cache.statistics()
    assert same(evaluate(load(grating(tracks=41), coherent=False)), expected)
    assert disk_cache.statistics()["hits"] == counts["hits"] + 1  # ... which the next render reads


def test02_a_file_signed_with_another_secret_is_refused_whatever_it_holds(cache, caplog):
    own, expected = written_by(cache, grating(tracks=41))
    header, _ = read_file(own)
    with open(own, "rb") as stream:  # what a forger would need the secret for; here the test reads it
        secret = (cache / "secret.key").read_bytes()
        meta, arrays, _ = cache_file.read(stream, secret, {"key": header["key"]}, 1 << 30)
    scaled = {name: value * 10 if value.dtype.kind == "f" else value for name, value in arrays.items()}
    identity = {field: header[field] for field in ("key", "options", "code")}
    with open(own, "wb") as stream:  # a consistent file: identity, records, digest, all but the secret
        cache_file.write(stream, os.urandom(32), identity, meta, scaled)
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        bsdf = load(grating(tracks=41), coherent=False)
    assert "its signature does not match the folder's secret" in caplog.text
    assert same(evaluate(bsdf), expected)


def test03_another_user_s_secret_or_one_others_may_read_turns_the_cache_off(cache, caplog):
    own, expected = written_by(cache, grating(tracks=41))
    secret = cache / "secret.key"
    os.chmod(secret, 0o644)
    counts = disk_cache.statistics()
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        bsdf = load(grating(tracks=41), coherent=False)
    assert "belongs to another user or others may read it" in caplog.text
    assert same(evaluate(bsdf), expected) and disk_cache.statistics()["hits"] == counts["hits"]
    os.chmod(secret, 0o600)
    if os.geteuid() == 0:  # (only root can give a file away)
        os.chown(secret, 4321, 4321)
        del bsdf
        gc.collect()
        disk_cache._warned.clear()
        with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
            assert same(evaluate(load(grating(tracks=41), coherent=False)), expected)
        assert disk_cache.statistics()["hits"] == counts["hits"]


def test04_a_folder_of_the_user_s_files_is_never_touched(tmp_path, monkeypatch, caplog):
    """Pointed at a folder of scratch files, with a size limit that keeps nothing: only its own subfolder changes."""
    user = tmp_path / "my scratches"
    user.mkdir()
    for k in range(3):
        scratch.save(scratch.random_scratches(5, seed=k), user / f"set{k}.npz")
    (user / ".hidden.npz.0123abcd.tmp").write_bytes(b"looks like a temporary file, is the user's")
    before = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in user.iterdir()}
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(user))
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_MB", "0")
    monkeypatch.setattr(disk_cache, "MIN_BUILD_SECONDS", 0.0)
    for tracks in (30, 31, 32):
        load(grating(tracks=tracks), coherent=False)
        gc.collect()
    assert {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in user.iterdir() if p.name != "tables"} == before
    own = {p.name for p in (user / "tables").iterdir()}
    assert {"CACHEDIR.TAG", "secret.key"} < own and len(own) == 3  # and the newest file (limit 0 keeps one)
    # a "tables" folder the user made holds their files: it is not used, and nothing in it changes
    mine = tmp_path / "theirs"
    (mine / "tables").mkdir(parents=True)
    (mine / "tables" / "grid.npz").write_bytes(b"the user's")
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(mine))
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        load(grating(tracks=33), coherent=False)
    assert "holds files the cache did not write (grid.npz)" in caplog.text
    assert [p.name for p in (mine / "tables").iterdir()] == ["grid.npz"]


def test04b_the_first_version_s_cache_folder_is_taken_over_and_a_look_alike_is_not(cache, caplog, monkeypatch):
    """The default folder of the cache's first version (``<40 hex>.npz`` files holding a ``meta.json``, killed
    writes' ``.writing-*.tmp``, no tag) is this cache's now: its files go with the first write, without a warning.
    A file of the same name that the first version could not have written keeps the folder the user's."""
    cache.mkdir(parents=True)
    for k in range(3):  # (as the first version wrote them: np.savez of the arrays and a meta.json record)
        np.savez(cache / f"{k:040x}.npz", **{"meta.json": np.array('{"format": 1}'), "tables.segments": np.zeros(4)})
    (cache / ".writing-ab12_x9z.tmp").write_bytes(b"a killed write")
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        own, expected = written_by(cache, grating(tracks=41))
    assert "did not write" not in caplog.text
    assert {p.name for p in cache.iterdir()} == {"CACHEDIR.TAG", "secret.key", own.name}
    assert same(evaluate(load(grating(tracks=41), coherent=False)), expected)
    # the same names in an untagged folder, one of them a user's array file: nothing is used or removed
    look_alike = cache.parent / "look-alike" / disk_cache.SUBFOLDER
    look_alike.mkdir(parents=True)
    np.savez(look_alike / f"{1:040x}.npz", data=np.arange(3))
    np.savez(look_alike / f"{2:040x}.npz", **{"meta.json": np.array("{}")})
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(look_alike.parent))
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        load(grating(tracks=43), coherent=False)
    assert f"holds files the cache did not write ({1:040x}.npz)" in caplog.text
    assert sorted(p.name for p in look_alike.iterdir()) == [f"{1:040x}.npz", f"{2:040x}.npz"]


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e400", "junk", "-5", ""])
def test05_a_size_limit_that_is_not_a_size_means_the_default_with_a_warning(monkeypatch, caplog, value):
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_MB", value)
    disk_cache._warned.discard(("limit", value))
    with caplog.at_level(logging.WARNING, logger=disk_cache.__name__):
        assert disk_cache.limit_bytes() == disk_cache.DEFAULT_LIMIT_MB * 2 ** 20
        assert disk_cache.limit_bytes() == disk_cache.DEFAULT_LIMIT_MB * 2 ** 20
    assert caplog.text.count("is not a size in MB") == 1  # once per value, not per render
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_MB", "1.5")
    assert disk_cache.limit_bytes() == int(1.5 * 2 ** 20)


def test06_a_full_disk_during_a_write_is_one_warning_and_no_traceback(tmp_path):
    """A file-size limit makes every write past 4 KiB fail as a full disk does (the write call fails midway)."""
    code = f"""
import gc, resource, signal, sys
sys.path[:0] = [{str(Path(__file__).parent)!r}, {str(Path(__file__).parents[1])!r}]
from scratch_iridescence.mitsuba_bridge.render.activation import activate
activate("llvm_ad_spectral")
from scratch_iridescence.mitsuba_bridge.bsdf.tables import disk_cache
from test_disk_cache import grating, load
disk_cache.MIN_BUILD_SECONDS = 0.0
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a failed write, not a killed process
resource.setrlimit(resource.RLIMIT_FSIZE, (4096, resource.RLIM_INFINITY))
bsdf = load(grating(), coherent=False)
print("pieces", bsdf.tables.piece_count, disk_cache.statistics()["failed_writes"])
del bsdf
gc.collect()
"""
    env = {**os.environ, "SCRATCH_IRIDESCENCE_CACHE_DIR": str(tmp_path / "root")}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["pieces", result.stdout.split()[1], "1"] and int(result.stdout.split()[1]) > 0
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    ours = [line for line in lines if "scratch tables cache" in line]
    assert len(ours) == 1 and "could not write" in ours[0] and "File too large" in ours[0], result.stderr
    assert "Traceback" not in result.stderr and "ZipFile" not in result.stderr and "Exception" not in result.stderr
    assert sorted(p.name for p in (tmp_path / "root" / "tables").iterdir()) == ["CACHEDIR.TAG", "secret.key"]


def test07_the_host_s_folder_replaces_the_platform_default_and_the_environment_wins(tmp_path, monkeypatch):
    monkeypatch.delenv("SCRATCH_IRIDESCENCE_CACHE_DIR")
    environment = dict(os.environ)
    try:
        disk_cache.set_root(tmp_path / "extension user folder")
        assert disk_cache.directory() == tmp_path / "extension user folder" / "tables"
        monkeypatch.setenv("SCRATCH_IRIDESCENCE_CACHE_DIR", str(tmp_path / "farm"))
        assert disk_cache.directory() == tmp_path / "farm" / "tables"
        monkeypatch.delenv("SCRATCH_IRIDESCENCE_CACHE_DIR")
        disk_cache.set_root(None)
        assert disk_cache.directory().parent.name == "scratch-iridescence"
        assert dict(os.environ) == environment
    finally:
        disk_cache.set_root(None)


def test08_the_code_version_changes_with_any_module_that_builds_tables(tmp_path):
    package = Path(disk_cache.__file__).resolve().parents[2]
    copy = tmp_path / "mitsuba_bridge"
    for folder in ("bsdf", "scratch"):
        shutil.copytree(package / folder, copy / folder, ignore=shutil.ignore_patterns("__pycache__"))
    assert disk_cache._source_digest(copy) == disk_cache.code_fingerprint()
    for edited in ("bsdf/tables/grid.py", "bsdf/maths/window.py", "scratch/scratchset.py"):
        original = (copy / edited).read_bytes()
        (copy / edited).write_bytes(original + b"\n# an edit\n")
        assert disk_cache._source_digest(copy) != disk_cache.code_fingerprint(), edited
        (copy / edited).write_bytes(original)
