"""Cluster fixtures: a fresh scene cache per run (inherited by every worker process), small exported scenes.

Dask's workers here are real processes (``LocalCluster(processes=True)``, or ``dask scheduler`` and
``dask worker`` started from the command line); renders use the LLVM variant, as the bridge's tests.
"""
import atexit
import os
import shutil
import tempfile

import pytest

pytest.importorskip("distributed")

_SCENES_CACHE = tempfile.mkdtemp(prefix="scratch-scene-cache-")
os.environ["SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR"] = _SCENES_CACHE
atexit.register(shutil.rmtree, _SCENES_CACHE, ignore_errors=True)

from cluster_scenes import export_scene  # noqa: E402


@pytest.fixture(scope="module")
def scene_folder(variant, tmp_path_factory):
    return export_scene(tmp_path_factory.mktemp("cluster") / "scene")
