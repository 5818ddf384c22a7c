"""Cluster fixtures: a fresh scene cache per run (inherited by every worker process), small exported scenes.

Dask's workers here are real processes (``LocalCluster(processes=True)``, or ``dask scheduler`` and
``dask worker`` started from the command line); renders use the LLVM variant, as the bridge's tests.
"""
import atexit
import contextlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

pytest.importorskip("distributed")

_SCENES_CACHE = tempfile.mkdtemp(prefix="scratch-scene-cache-")
os.environ["SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR"] = _SCENES_CACHE
atexit.register(shutil.rmtree, _SCENES_CACHE, ignore_errors=True)

VARIANT = "llvm_ad_spectral"
ROOT = Path(__file__).resolve().parents[3]


@contextlib.contextmanager
def worker_sys_path():
    """Start worker processes without the checkout's parent folder on their path.

    The repository root is a package (the extension), so pytest puts its parent folder first on
    ``sys.path``, and spawned workers inherit it: any folder there named like a standard module
    (a sibling checkout called ``platform``) would shadow that module in every worker.
    """
    parent = str(ROOT.parent)
    saved = list(sys.path)
    sys.path[:] = [entry for entry in sys.path if os.path.abspath(entry or ".") != parent]
    try:
        yield
    finally:
        sys.path[:] = saved


def export_scene(folder, *, film=(32, 24), light=(1.0, 1.0, 1.0)):
    """A lit grey floor exported to ``folder`` (different ``light`` values give different scenes)."""
    from bridge_scenes import simple_scene
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.folder import export

    description = simple_scene(film=S.Film(*film), lights=[S.PointLight((0, 0, 2), light)],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    export.export_folder(description, S.RenderSettings(spp=4), folder)
    return folder


def one_process_render(folder, output, spp, seed):
    """The one-machine render of the ``render`` command (the reference every cluster render must equal)."""
    from scratch_iridescence.mitsuba_bridge.cli.main import main
    from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

    assert main(["render", str(folder), "-o", str(output), "--spp", str(spp), "--seed", str(seed), "-q",
                 "--variant", VARIANT]) == 0
    return read_exr(output)


@pytest.fixture(scope="module")
def scene_folder(variant, tmp_path_factory):
    return export_scene(tmp_path_factory.mktemp("cluster") / "scene")
