"""A FIFO (or a device) where the command line reads a file: one ``error:`` line within a second, never a hang.

Each command runs in a thread; should it block on the FIFO, the test opens the
FIFO's other end (which releases the reader) and fails, instead of hanging.
"""
from __future__ import annotations

import os
import shutil
import threading
import time

import numpy as np
import pytest

from bridge_scenes import quad, simple_scene
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.cli.main import main
from scratch_iridescence.mitsuba_bridge.folder import export

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
LLVM = ["--variant", "llvm_ad_spectral"]


@pytest.fixture(scope="module")
def exported(variant, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fifo") / "good"
    plate = S.ScratchedMetal(scratches=scratch.random_scratches(10, seed=1), coherence_diameter_m=30e-6)
    export.export_folder(simple_scene(shapes=[S.Shape("plate", quad(1.0, "plate"), np.eye(4), "plate")],
                                      materials={"plate": plate}), S.RenderSettings(spp=2), folder)
    return folder


def run_with_fifos(argv: list[str], fifos: list, capsys) -> tuple[int, str, float]:
    """(status, stderr, seconds) of ``main(argv)``; a run still blocked after 5 s is released and fails the test."""
    outcome = {}

    def run():
        started = time.perf_counter()
        try:
            outcome["status"] = main(argv)
        except SystemExit as stop:
            outcome["status"] = stop.code
        outcome["seconds"] = time.perf_counter() - started

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout=5.0)
    if thread.is_alive():
        for fifo in fifos:  # release the blocked reader (opening the write end unblocks its open)
            os.close(os.open(fifo, os.O_RDWR))
        thread.join(timeout=10.0)
        pytest.fail(f"{argv[0]} blocked on a FIFO")
    return outcome["status"], capsys.readouterr().err.strip(), outcome["seconds"]


def one_error_line(status, err, seconds, *words):
    assert status not in (0, None), err
    assert err.startswith("error: ") and "\n" not in err and "Traceback" not in err, err
    assert all(word in err for word in words), err
    assert seconds < 1.0, seconds


def test_info_on_a_fifo_and_a_device(tmp_path, capsys):
    fifo = tmp_path / "plate.npz"
    os.mkfifo(fifo)
    one_error_line(*run_with_fifos(["info", str(fifo)], [fifo], capsys), "FIFO", "not a regular file")
    if os.path.exists("/dev/zero"):
        one_error_line(*run_with_fifos(["info", "/dev/zero"], [], capsys), "character device")
    one_error_line(*run_with_fifos(["info", str(tmp_path)], [], capsys), "is a folder")


@pytest.mark.parametrize("where", ["scene.xml", "scratches/plate.npz", "meshes/plate.ply"])
def test_render_of_a_folder_holding_a_fifo(exported, tmp_path, capsys, where):
    folder = tmp_path / "case"
    shutil.copytree(exported, folder)
    (folder / where).unlink()
    os.mkfifo(folder / where)
    argv = ["render", str(folder), "-o", str(tmp_path / "out.exr"), "-q", *LLVM]
    one_error_line(*run_with_fifos(argv, [folder / where], capsys), where.split("/")[-1], "FIFO")
    assert not (tmp_path / "out.exr").exists()


def test_render_and_merge_given_a_fifo(tmp_path, capsys, variant):
    fifo = tmp_path / "part.exr"
    os.mkfifo(fifo)
    one_error_line(*run_with_fifos(["render", str(fifo), "-o", str(tmp_path / "out.exr"), *LLVM], [fifo], capsys),
                   "FIFO")
    one_error_line(*run_with_fifos(["merge", str(fifo), "-o", str(tmp_path / "out.exr")], [fifo], capsys), "FIFO")
