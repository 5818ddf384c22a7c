"""The pieces of a cluster render that need no cluster: node sums in any order, scene bundles, the variant rule."""
import io
import zipfile

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.cluster import scenes
from scratch_iridescence.mitsuba_bridge.cluster.driver import Cluster, ClusterError
from scratch_iridescence.mitsuba_bridge.cluster.reduce import NodeReducer, task_nodes
from scratch_iridescence.mitsuba_bridge.render.schedule import PairwiseSum, tree_nodes


@pytest.mark.parametrize("count", [1, 2, 3, 7, 9, 16, 33])
@pytest.mark.parametrize("per_task", [1, 2, 4])
def test01_node_sums_in_any_order_equal_one_machines_sum_bit_for_bit(count, per_task):
    rng = np.random.default_rng(count * 10 + per_task)
    # Values whose sums round differently in another order (magnitudes spread over 12 decades).
    contributions = [rng.standard_normal((3, 5, 4)) * 10.0 ** rng.integers(-6, 6) for _ in range(count)]
    one_machine = PairwiseSum()
    for value in contributions:
        one_machine.add(value)
    runs = task_nodes(count, per_task)
    for order in (range(len(runs)), reversed(range(len(runs))), rng.permutation(len(runs))):
        reducer = NodeReducer(count)
        for number in order:
            run = runs[number]
            part = PairwiseSum(run.start)
            for i in run:
                part.add(contributions[i])
            for node, value in part.node_sums(count).items():
                reducer.add(node, value)
        assert reducer.finished and reducer.chunks_done == count
        assert reducer.total().tobytes() == one_machine.total().tobytes()


def test02_tasks_are_aligned_tree_nodes():
    assert [list(r) for r in task_nodes(9, 4)] == [[0, 1, 2, 3], [4, 5, 6, 7], [8]]
    assert all(len(tree_nodes(run, 9)) == 1 for run in task_nodes(9, 4))
    with pytest.raises(ValueError, match="power of two"):
        task_nodes(9, 3)


def test03_a_node_added_twice_is_refused():
    reducer = NodeReducer(4)
    from scratch_iridescence.mitsuba_bridge.render.schedule import Node
    reducer.add(Node(0, 1), np.zeros(2))
    with pytest.raises(ValueError, match="overlaps"):
        reducer.add(Node(1, 0), np.zeros(2))
    with pytest.raises(KeyError, match="3 of 4 chunks are missing"):
        reducer.total()


def test04_a_bundle_unpacks_to_the_same_files_under_its_digest(scene_folder, tmp_path, monkeypatch):
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR", str(tmp_path / "cache"))
    bundle = scenes.pack_folder(scene_folder)
    assert scenes.pack_folder(scene_folder) == bundle  # the same bytes every time: content-addressed
    assert scenes.cached_scene(bundle.digest) is None
    folder = scenes.store_bundle(bundle)
    assert folder == tmp_path / "cache" / bundle.digest
    for path in scene_folder.rglob("*"):
        if path.is_file():
            assert (folder / path.relative_to(scene_folder)).read_bytes() == path.read_bytes()
    assert scenes.store_bundle(bundle) == folder and scenes.cached_scene(bundle.digest) == folder


def test05_a_bundle_that_lies_about_its_content_is_refused(scene_folder, tmp_path, monkeypatch):
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR", str(tmp_path / "cache"))
    bundle = scenes.pack_folder(scene_folder)
    with pytest.raises(scenes.BundleError, match="unpacked into files of digest"):
        scenes.store_bundle(scenes.SceneBundle("0" * 64, bundle.data))
    stream = io.BytesIO()
    with zipfile.ZipFile(stream, "w") as archive:
        archive.writestr("../escape.txt", "x")
    with pytest.raises(scenes.BundleError, match="would leave the scene folder"):
        scenes.store_bundle(scenes.SceneBundle("1" * 64, stream.getvalue()))
    assert not (tmp_path / "escape.txt").exists()
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == []  # nothing half-stored


def test06_least_recently_used_scenes_leave_a_full_cache(scene_folder, tmp_path, monkeypatch):
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR", str(tmp_path / "cache"))
    first = scenes.pack_folder(scene_folder)
    size_mb = sum(p.stat().st_size for p in scene_folder.rglob("*") if p.is_file()) / 1e6
    monkeypatch.setenv("SCRATCH_IRIDESCENCE_SCENE_CACHE_MB", str(1.5 * size_mb))
    scenes.store_bundle(first)
    other = tmp_path / "other.blend"
    other.write_bytes(b"x" * int(size_mb * 1e6))
    second = scenes.pack_file(other)
    scenes.store_bundle(second)
    assert scenes.cached_scene(first.digest) is None and scenes.cached_scene(second.digest) is not None


@pytest.mark.parametrize("requested, workers, expected", [
    ("auto", {"a": {}, "b": {}}, ("llvm_ad_spectral", None)),
    ("auto", {"a": {"GPU": 1}, "b": {"GPU": 2}}, ("cuda_ad_spectral", {"GPU": 1})),
    ("llvm_ad_spectral", {"a": {"GPU": 1}, "b": {}}, ("llvm_ad_spectral", None)),
    ("cuda_ad_spectral", {"a": {"GPU": 1}, "b": {}}, ("cuda_ad_spectral", {"GPU": 1})),
])
def test07_one_render_takes_one_kind_of_worker(requested, workers, expected):
    assert Cluster.choose_variant(None, requested, workers) == expected


@pytest.mark.parametrize("requested, workers, message", [
    ("auto", {"a": {"GPU": 1}, "b": {}}, "mixes 1 GPU worker(s) and 1 CPU worker(s)"),
    ("cuda_ad_spectral", {"a": {}}, "needs GPU workers"),
])
def test08_a_render_that_would_mix_schedules_is_refused(requested, workers, message):
    with pytest.raises(ClusterError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Cluster.choose_variant(None, requested, workers)


class _Stream:
    def __init__(self, tty):
        self.text, self.tty = "", tty

    def write(self, text):
        self.text += text

    def flush(self):
        pass

    def isatty(self):
        return self.tty


def test09_progress_is_a_line_per_update_in_a_log_and_one_redrawn_bar_on_a_terminal():
    from scratch_iridescence.mitsuba_bridge.cluster.progress import ClusterProgress

    log, terminal = _Stream(False), _Stream(True)
    for stream in (log, terminal):
        progress = ClusterProgress(4, stream=stream, interval_s=0.0)
        for done in range(1, 5):
            progress.update(done)
        progress.message("wrote out.exr")
    assert [line.split()[0] for line in log.text.splitlines()[:4]] == ["1/4", "2/4", "3/4", "4/4"]
    assert log.text.count("\r") == 0 and log.text.splitlines()[-1] == "wrote out.exr"
    assert terminal.text.count("\r") == 4 and terminal.text.count("\n") == 2  # the bar's end, the message
    assert "[##############################] " in terminal.text and "100.0 %" in terminal.text
