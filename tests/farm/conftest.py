"""Farm job definitions run locally: an animated .blend made with pip's bpy, and its frames rendered on one machine
(the reference every farm job's merged frames must equal, bit for bit)."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("bpy")

from farm_paths import HERE, ROOT, VARIANT  # noqa: E402


@pytest.fixture(scope="session")
def blend(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("shot") / "shot.blend"
    subprocess.run([sys.executable, str(HERE / "moving_square.py"), str(path)], check=True, capture_output=True)
    return path


@pytest.fixture(scope="session")
def reference_frames(blend, tmp_path_factory) -> Path:
    """Frames 1 and 2 rendered on this machine (render-frames)."""
    out = tmp_path_factory.mktemp("reference")
    subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render-frames", str(blend), "--frames",
                    "1-2", "-o", str(out / "frame_####.exr"), "--variant", VARIANT, "-q"], check=True,
                   capture_output=True)
    return out


@pytest.fixture(scope="session")
def blender_user(tmp_path_factory) -> Path:
    """A Blender user folder whose user_default extension repository holds this checkout (as if installed)."""
    folder = tmp_path_factory.mktemp("blender-user")
    repository = folder / "extensions" / "user_default"
    repository.mkdir(parents=True)
    os.symlink(ROOT, repository / "scratch_iridescence")
    return folder
