"""Renders on a real ``LocalCluster`` of worker processes: the one-process image bit for bit, the scene sent
once, a worker killed mid-render (SIGKILL) costing only its task."""
import os
import signal
import threading
import time

import pytest

from cluster_scenes import VARIANT, export_scene, one_process_render, worker_sys_path
from scratch_iridescence.mitsuba_bridge.cluster import scenes, tasks
from scratch_iridescence.mitsuba_bridge.cluster.driver import LOCAL_WORKER_CONFIG, Cluster, local_cluster
from scratch_iridescence.mitsuba_bridge.cluster.identity import software_identity

SPP, SEED = 31, 3  # 32 x 24 pixels: nine chunks (7 of 4 spp, then 2 and 1): an uneven tree


@pytest.fixture(scope="module")
def cluster(variant):
    from distributed import Client

    with worker_sys_path():
        local = local_cluster(2)  # what --cluster local:2 starts
    with local, Client(local) as client:
        yield Cluster(client, software_identity())


@pytest.fixture(scope="module", params=["multijitter", "independent"])
def sampled_scene(variant, tmp_path_factory, request):
    """The test scene exported with each of the renderer's samplers, and its one-process render."""
    folder = export_scene(tmp_path_factory.mktemp(request.param) / "scene", sampler=request.param)
    return folder, one_process_render(folder, folder.parent / "one.exr", SPP, SEED)


@pytest.mark.parametrize("chunks_per_task", [None, 4])
def test01_the_cluster_renders_the_one_process_image_bit_for_bit(cluster, sampled_scene, chunks_per_task):
    scene_folder, reference = sampled_scene
    result = cluster.render(scenes.pack_folder(scene_folder), variant=VARIANT, spp=SPP, seed=SEED,
                            chunks_per_task=chunks_per_task)
    assert result.chunk_count == 9 and result.tasks == (9 if chunks_per_task is None else 3)
    assert result.image.tobytes() == reference.tobytes()


def test02_a_scene_reaches_each_worker_once(cluster, tmp_path):
    bundle = scenes.pack_folder(export_scene(tmp_path / "new", light=(1.0, 0.5, 0.25)))
    workers = len(cluster.workers())
    before = sum(counts["bytes"] for counts in cluster.client.run(tasks.transfer_counts).values())
    sent = cluster.scene_bytes_sent
    first = cluster.render(bundle, variant=VARIANT, spp=8, seed=1)
    assert cluster.scene_bytes_sent - sent == workers * bundle.size_bytes
    received = sum(counts["bytes"] for counts in cluster.client.run(tasks.transfer_counts).values())
    assert received - before == workers * bundle.size_bytes
    second = cluster.render(bundle, variant=VARIANT, spp=8, seed=1)
    assert cluster.scene_bytes_sent - sent == workers * bundle.size_bytes  # nothing more
    assert sum(counts["bytes"] for counts in cluster.client.run(tasks.transfer_counts).values()) == received
    assert second.image.tobytes() == first.image.tobytes()


def worker_settings(keys):
    import dask

    return {key: dask.config.get(key) for key in keys}


def test02b_local_workers_run_without_dasks_profiler(cluster):
    """The nannies hand the driver's settings to the worker processes: no stack sampling every 10 ms."""
    settings = cluster.client.run(worker_settings, list(LOCAL_WORKER_CONFIG))
    assert len(settings) == 2 and all(found == LOCAL_WORKER_CONFIG for found in settings.values()), settings


@pytest.mark.slow
def test03_a_worker_killed_mid_render_costs_only_its_task(cluster, tmp_path):
    from distributed import get_task_stream

    # 96 x 80 pixels: chunks of 1024 spp (7.9 M samples, seconds each on one core), four of them.
    folder = export_scene(tmp_path / "big", film=(96, 80))
    spp, seed = 4096, 5
    reference = one_process_render(folder, tmp_path / "one.exr", spp, seed)
    outcome, killed = {}, []

    def render():
        outcome["result"] = cluster.render(scenes.pack_folder(folder), variant=VARIANT, spp=spp, seed=seed)

    with get_task_stream(cluster.client) as stream:
        thread = threading.Thread(target=render)
        thread.start()
        deadline, seen = time.time() + 300, {}
        while not killed and time.time() < deadline and thread.is_alive():
            # A worker that has been rendering a chunk for a second (a chunk takes longer, even on a fast
            # machine): kill it mid-task.
            for address, keys in cluster.client.processing().items():
                for key in keys:
                    if "scratch-chunks" in str(key) and time.time() - seen.setdefault(key, time.time()) > 1.0:
                        pid = cluster.client.run(os.getpid, workers=[address])[address]
                        os.kill(pid, signal.SIGKILL)
                        killed.append(address)
                        break
                if killed:
                    break
            time.sleep(0.2)
        thread.join(timeout=600)
    assert killed, "no worker was rendering"
    assert outcome["result"].image.tobytes() == reference.tobytes()
    finished = [t for t in stream.data if "scratch-chunks" in str(t["key"])]
    # Each task finished once; the one the worker was rendering ran again elsewhere. (A result that finished
    # on the worker in the instant before the kill, before the driver took it, would be rendered again.)
    assert outcome["result"].tasks <= len(finished) <= outcome["result"].tasks + 1
