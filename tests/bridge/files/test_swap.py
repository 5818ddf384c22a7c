"""Re-exports are the old export or the new one, even killed (kill -9) at any rename; killed writers' litter goes.

The kill test runs a real re-export in a child process whose ``os.replace`` sends
itself SIGKILL at its k-th call, for every k up to the number of renames a
re-export makes, then checks that the folder holds the old or the new export,
whole, after the next render's load (``check_folder``, as ``render`` and
``load_folder`` run it) or after the next export.
"""
from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import quad, simple_scene
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.files import atomic, swap
from scratch_iridescence.mitsuba_bridge.folder import export

ROOT = Path(__file__).resolve().parents[3]

#: The child: the new export, with os.replace killing the process at its k-th call (k = argv[3]).
_CHILD = """
import os, pickle, signal, sys
from scratch_iridescence.mitsuba_bridge.render.activation import activate
from scratch_iridescence.mitsuba_bridge.folder import export
activate("llvm_ad_spectral")
with open(sys.argv[1], "rb") as stream:
    description, settings = pickle.load(stream)
kill_at, calls, real_replace = int(sys.argv[3]), [0], os.replace
def replace(source, target, **keywords):
    calls[0] += 1
    if calls[0] == kill_at:
        os.kill(os.getpid(), signal.SIGKILL)
    return real_replace(source, target, **keywords)
os.replace = replace
export.export_folder(description, settings, sys.argv[2])
print("renames", calls[0])
"""


def plate_scene(count: int, seed: int, colour: float):
    plate = S.ScratchedMetal(scratches=scratch.random_scratches(count, seed=seed, vertices=3),
                             coherence_diameter_m=30e-6)
    return simple_scene(shapes=[S.Shape("plate", quad(1.0, "plate"), np.eye(4), "plate")],
                        materials={"plate": plate}, world=S.ConstantWorld((colour,) * 3))


def exported(folder: Path) -> dict:
    """Every file of the export (hidden litter excluded) and its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and not any(part.startswith(".") for part in p.relative_to(folder).parts)}


def hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.fixture(scope="module")
def versions(tmp_path_factory, variant):
    """The old and new exports (different scratches, meshes and scene.xml) and their reference contents."""
    base = tmp_path_factory.mktemp("versions")
    descriptions = {"old": plate_scene(20, 1, 0.3), "new": plate_scene(30, 2, 0.7)}
    references = {}
    for name, description in descriptions.items():
        export.export_folder(description, S.RenderSettings(spp=2), base / name)
        references[name] = exported(base / name)
    assert references["old"].keys() == references["new"].keys()
    assert all(references["old"][key] != references["new"][key] for key in references["old"] if "ply" not in key)
    pickled = base / "new.pickle"
    pickled.write_bytes(pickle.dumps((descriptions["new"], S.RenderSettings(spp=2))))
    return descriptions, references, pickled


def killed_re_export(tmp_path, versions, kill_at: int) -> tuple[Path, subprocess.CompletedProcess]:
    descriptions, references, pickled = versions
    folder = tmp_path / f"k{kill_at}"
    export.export_folder(descriptions["old"], S.RenderSettings(spp=2), folder)
    (folder / "notes.txt").write_text("the user's")
    result = subprocess.run([sys.executable, "-c", _CHILD, str(pickled), str(folder), str(kill_at)],
                            capture_output=True, text=True, cwd=ROOT, timeout=300)
    return folder, result


# (a child process killed at each of the renames in turn: ~30 s here; test02 kills two of them in make test;
# under the slow marker)
@pytest.mark.slow
def test01_a_re_export_killed_at_any_rename_is_old_or_new_after_the_next_render(variant, tmp_path, versions):
    _, references, _ = versions
    completed = killed_re_export(tmp_path, versions, 10 ** 6)[1]  # never killed: how many renames there are
    assert completed.returncode == 0, completed.stderr
    renames = int(completed.stdout.split()[-1])
    assert renames >= 8  # the files written, the journal, four entries out and in
    outcomes = []
    for kill_at in range(1, renames + 1):
        folder, result = killed_re_export(tmp_path, versions, kill_at)
        assert result.returncode == -signal.SIGKILL, (kill_at, result.stderr)
        export.check_folder(folder)  # what `render` and load_folder run before Mitsuba reads anything
        content = exported(folder)
        state = "new" if content == {**references["new"], "notes.txt": b"the user's"} else \
            "old" if content == {**references["old"], "notes.txt": b"the user's"} else "mixed"
        assert state != "mixed", (kill_at, sorted(content))
        assert swap.JOURNAL not in hidden(folder)
        outcomes.append(state)
    # the kills before the journal leave the old export, those after it the new one (completed)
    assert outcomes[0] == "old" and outcomes[-1] == "new" and outcomes == sorted(outcomes, reverse=True)
    last = tmp_path / f"k{renames}"
    assert export.load_folder(last).shapes()  # and Mitsuba loads the completed export


def test02_the_next_export_completes_or_discards_a_killed_one_and_removes_its_litter(variant, tmp_path, versions):
    descriptions, references, _ = versions
    for kill_at in (2, 7):  # (of 8 renames: in the files written before the journal; in the swap)
        folder, result = killed_re_export(tmp_path, versions, kill_at)
        assert result.returncode == -signal.SIGKILL, result.stderr
        export.export_folder(descriptions["old"], S.RenderSettings(spp=2), folder)
        assert exported(folder) == {**references["old"], "notes.txt": b"the user's"}
        assert hidden(folder) == [], kill_at  # no journal, building folder, old entries or temporary file


def test03_a_journal_that_cannot_be_completed_is_one_clear_error(tmp_path):
    folder = tmp_path / "export"
    folder.mkdir()
    (folder / "scene.xml").write_text("<scene/>")
    (folder / swap.JOURNAL).write_text(json.dumps({"building": "../../etc", "trash": ".export-x.old",
                                                   "entries": ["scene.xml"], "new": ["scene.xml"]}))
    with pytest.raises(swap.SwapRecoveryError, match="damaged swap journal"):
        export.check_folder(folder)
    assert (folder / "scene.xml").read_text() == "<scene/>"


def test04_killed_saves_leave_temporaries_that_the_next_save_removes(tmp_path):
    target = tmp_path / "set.npz"
    scratches = scratch.random_scratches(5, seed=3)
    code = f"""
import os, signal
from scratch_iridescence.mitsuba_bridge import scratch
os.replace = lambda *a, **k: os.kill(os.getpid(), signal.SIGKILL)
scratch.save(scratch.random_scratches(5, seed=3), {str(target)!r})
"""
    for _ in range(2):
        killed = subprocess.run([sys.executable, "-c", code], capture_output=True, cwd=ROOT, timeout=120)
        assert killed.returncode == -signal.SIGKILL
    litter = sorted(p.name for p in tmp_path.iterdir())  # (the second killed save removed the first one's)
    assert len(litter) == 1 and litter[0].startswith(".set.npz.") and litter[0].endswith(".tmp")
    (tmp_path / ".other.npz.0123abcd.tmp").write_bytes(b"another file's temporary: not this save's")
    scratch.save(scratches, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == [".other.npz.0123abcd.tmp", "set.npz"]
    assert scratch.load(target).count == 5


def test05_a_temporary_file_being_written_is_never_taken_for_litter(tmp_path):
    target = tmp_path / "image.exr"
    with atomic.replacing_file(target) as temporary:
        temporary.write_bytes(b"being written by this process")
        assert atomic.remove_stale_temporaries(tmp_path, "image.exr") == 0  # locked: a live writer
        assert temporary.read_bytes() == b"being written by this process"
    assert target.read_bytes() == b"being written by this process"


def test06_a_killed_render_s_temporary_image_goes_with_the_next_render_to_the_same_file(tmp_path):
    from scratch_iridescence.mitsuba_bridge.files.images import write_image

    code = f"""
import os, signal
import numpy as np
from scratch_iridescence.mitsuba_bridge.files.images import write_image
os.replace = lambda *a, **k: os.kill(os.getpid(), signal.SIGKILL)
write_image({str(tmp_path / "out.exr")!r}, np.zeros((4, 4, 4), np.float32))
"""
    killed = subprocess.run([sys.executable, "-c", code], capture_output=True, cwd=ROOT, timeout=120)
    assert killed.returncode == -signal.SIGKILL
    (litter,) = tmp_path.iterdir()
    assert litter.name.startswith(".out.exr.") and litter.name.endswith(".tmp.exr") and litter.stat().st_size > 0
    write_image(tmp_path / "out.exr", np.ones((4, 4, 4), np.float32))
    assert [p.name for p in tmp_path.iterdir()] == ["out.exr"]
