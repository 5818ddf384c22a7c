"""The Open Job Description template for Deadline Cloud (farm/deadline/), checked and run locally with Open Job
Description's reference tools (``openjd check``, ``openjd run``): the Export, RenderChunk and Merge steps give the
one-machine render of each frame, bit for bit."""
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from farm_paths import ROOT, VARIANT
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

OPENJD = shutil.which("openjd", path=str(Path(sys.executable).parent)) or shutil.which("openjd")
pytestmark = pytest.mark.skipif(OPENJD is None, reason="openjd-cli is not installed (make setup installs it)")
TEMPLATE = ROOT / "farm" / "deadline" / "scratch_iridescence_render.template.yaml"
COMMAND = Path(sys.executable).parent / "scratch-iridescence"


def test01_the_template_passes_open_job_descriptions_checks():
    result = subprocess.run([OPENJD, "check", str(TEMPLATE)], capture_output=True, text=True)
    assert result.returncode == 0 and "passes validation checks" in result.stdout, result.stdout + result.stderr


def test02_its_steps_run_locally_render_the_one_machine_frame_bit_for_bit(blend, reference_frames, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    result = subprocess.run([OPENJD, "run", str(TEMPLATE), "--step", "Merge", "--run-dependencies",
                             "-p", f"BlendFile={blend}", "-p", "Frames=2", "-p", "Chunks=3", "-p", f"OutputDir={out}",
                             "-p", f"Variant={VARIANT}", "-p", f"Command={COMMAND}"],
                            capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert sorted(p.name for p in (out / "work" / "frame_2").glob("part_*.exr")) == \
        ["part_1.exr", "part_2.exr", "part_3.exr"]
    assert "16 spp from 3 parts" in result.stdout
    assert read_exr(out / "frame_0002.exr").tobytes() == read_exr(reference_frames / "frame_0002.exr").tobytes()
