"""``python -m scratch_iridescence.mitsuba_bridge info`` on damaged files: one ``error:`` line each, exit status 1, no traceback."""
import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from damaged_files import overflowing_offsets_file

from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.cli.main import main

ROOT = Path(__file__).resolve().parents[3]




def flipped_crc_protected_byte() -> bytes:
    data = scratch.dumps(scratch.random_scratches(30, seed=2), compress=True)
    position = data.index(b"uv.npy") + 100
    return data[:position] + bytes([data[position] ^ 0x01]) + data[position + 1:]


DAMAGED = {
    "offsets.npz": (overflowing_offsets_file, "field 'offsets'"),
    "crc.npz": (flipped_crc_protected_byte, "field 'uv'"),
    "junk.npz": (lambda: scratch.dumps(scratch.random_scratches(3, seed=1)) + b"junk", "trailing bytes"),
    "v01.npz": (lambda: _with_format("scratch-iridescence/01"), "field 'format'"),
}


def _with_format(text: str) -> bytes:
    arrays = scratch.random_scratches(3, seed=1).as_dict()
    stream = io.BytesIO()
    np.savez(stream, format=np.array(text), **arrays)
    return stream.getvalue()


@pytest.mark.parametrize("name", sorted(DAMAGED))
def test_info_reports_a_damaged_file_in_one_line(tmp_path, capsys, name):
    build, expected = DAMAGED[name]
    path = tmp_path / name
    path.write_bytes(build())
    assert main(["info", str(path)]) == 1
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: ") and expected in lines[0]
    assert captured.out == ""


def test_info_goes_on_after_a_damaged_file(tmp_path, capsys):
    good = scratch.save(scratch.random_scratches(7, seed=3), tmp_path / "good.npz")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(overflowing_offsets_file())
    missing = tmp_path / "missing.npz"
    assert main(["info", str(bad), str(missing), str(good)]) == 1
    captured = capsys.readouterr()
    assert f"{good}: ScratchSet(7 scratches" in captured.out
    assert captured.err.count("error: ") == 2 and "Traceback" not in captured.err


def test_info_in_a_fresh_process_prints_no_traceback(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(overflowing_offsets_file())
    done = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "info", str(bad)], capture_output=True,
                          text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 1 and "Traceback" not in done.stderr and "field 'offsets'" in done.stderr
