"""A scheduler and workers started from the command line (``dask scheduler``, ``dask worker``), and the
``render --cluster tcp://...`` command against them: the one-process image, refused workers, Ctrl-C.

Slow: every worker process takes seconds to start and compiles its kernels once.
"""
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cluster_scenes import VARIANT, export_scene, one_process_render
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr
from scratch_iridescence.mitsuba_bridge.render.schedule import sample_schedule

pytestmark = pytest.mark.slow
HERE = Path(__file__).resolve().parent
DASK = str(Path(sys.executable).parent / "dask")


def _start(arguments, folder, name):
    log = open(folder / f"{name}.log", "w")
    return subprocess.Popen([DASK, *arguments], cwd=folder, stdout=log, stderr=subprocess.STDOUT)


def _scheduler_address(address_file: Path, deadline: float) -> str:
    """The address ``dask scheduler`` writes into its scheduler file, once the file is whole (it is written in
    place, not renamed: it exists, empty, for a moment first)."""
    while True:
        try:
            return json.loads(address_file.read_text())["address"]
        except (OSError, ValueError, KeyError):
            if time.time() > deadline:
                raise
            time.sleep(0.2)


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dask")
    address_file = folder / "scheduler.json"
    process = _start(["scheduler", "--scheduler-file", str(address_file), "--port", "0", "--no-dashboard",
                      "--host", "127.0.0.1"], folder, "scheduler")
    address = _scheduler_address(address_file, deadline=time.time() + 60)
    from distributed import Client

    with Client(address) as client:
        yield address, folder, client
    process.send_signal(signal.SIGINT)
    process.wait(timeout=30)


def worker(scheduler, name, *extra, wait=True, env=None):
    """A ``dask worker`` process (the caller stops it), registered before this returns (unless ``wait`` is False)."""
    address, folder, client = scheduler
    count = len(client.scheduler_info(n_workers=-1)["workers"])
    log = open(folder / f"{name}.log", "w")
    process = subprocess.Popen([DASK, "worker", address, "--nthreads", "1", "--no-dashboard", "--name", name, *extra],
                               cwd=folder, stdout=log, stderr=subprocess.STDOUT, env=env)
    if wait:
        client.wait_for_workers(count + 1, timeout=60)
    return process


def stop(scheduler, process):
    _, _, client = scheduler
    count = len(client.scheduler_info(n_workers=-1)["workers"])
    process.send_signal(signal.SIGTERM)
    process.wait(timeout=30)
    deadline = time.time() + 30
    while len(client.scheduler_info(n_workers=-1)["workers"]) >= count and time.time() < deadline:
        time.sleep(0.2)


def render(address, folder, output, *extra, **popen):
    return subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(folder), "-o",
                           str(output), "--cluster", address, "--variant", VARIANT, *extra],
                          capture_output=True, text=True, timeout=600, **popen)


@pytest.fixture(scope="module")
def workers(scheduler):
    started = [worker(scheduler, "plain-1"), worker(scheduler, "plain-2")]
    yield started
    for process in started:
        stop(scheduler, process)


def test01_command_line_workers_render_the_one_process_image(scheduler, workers, scene_folder, tmp_path):
    reference = one_process_render(scene_folder, tmp_path / "one.exr", 31, 3)
    result = render(scheduler[0], scene_folder, tmp_path / "cluster.exr", "--spp", "31", "--seed", "3")
    assert result.returncode == 0, result.stderr
    assert "9 chunks as 9 tasks on 2 workers" in result.stdout
    assert read_exr(tmp_path / "cluster.exr").tobytes() == reference.tobytes()
    again = render(scheduler[0], scene_folder, tmp_path / "again.exr", "--spp", "31", "--seed", "3")
    assert "already on all 2 workers: nothing sent" in again.stdout, again.stdout


@pytest.mark.parametrize("preload, message", [
    ("hide_package.py", "cannot import scratch_iridescence (No module named 'scratch_iridescence'): install the same "
                        "version on every worker: pip install 'scratch-iridescence[cluster]==0.1.0'"),
    ("other_mitsuba.py", "runs other software than this machine (mitsuba 3.9.0 vs 3.9.1): its chunks might not "
                         "merge bit for bit; install scratch-iridescence 0.1.0"),
])
def test02_a_worker_without_the_package_or_with_other_software_is_refused(scheduler, workers, scene_folder, tmp_path,
                                                                         preload, message):
    odd = worker(scheduler, f"odd-{preload}", "--preload", str(HERE / preload))
    try:
        result = render(scheduler[0], scene_folder, tmp_path / "refused.exr")
    finally:
        stop(scheduler, odd)
    error = result.stderr.strip()
    assert result.returncode == 1 and "\n" not in error and error.startswith("error: worker tcp://"), error
    assert message in error, error
    assert not (tmp_path / "refused.exr").exists()


def test03_ctrl_c_cancels_the_render_on_the_cluster(scheduler, workers, tmp_path):
    # 64 chunks of 256 spp (seconds each here): a fast machine is still far from done after 3 s; the render is
    # cancelled, so the rest never runs
    folder = export_scene(tmp_path / "big", film=(128, 96))
    count = len(sample_schedule(16384, 128 * 96))
    process = subprocess.Popen([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(folder),
                                "-o", str(tmp_path / "out.exr"), "--cluster", scheduler[0], "--variant", VARIANT,
                                "--spp", "16384"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               # (a test run started in the background inherits SIGINT ignored: Ctrl-C would be lost)
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    for line in process.stdout:
        if "tasks on 2 workers" in line:
            break
    time.sleep(3.0)  # the workers are rendering their first chunks
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert "interrupted: nothing was written" in err, (out, err)
    # Every task not finished when Ctrl-C came is cancelled; on a fast machine some finished in the 3 s before it
    # (done, with or without their progress line yet), so the count is the chunks less those, never zero.
    cancelled = re.search(r"cancelled (\d+) task\(s\) on the cluster", out)
    done = [int(n) for n in re.findall(rf"(\d+)/{count} chunks", out)]
    assert cancelled and 1 <= int(cancelled.group(1)) <= count - max(done, default=0), (out, err)
    assert not (tmp_path / "out.exr").exists()
    client = scheduler[2]
    deadline = time.time() + 60  # a task already rendering finishes its chunk (seconds), nothing else runs
    while time.time() < deadline:
        left = client.run_on_scheduler(lambda dask_scheduler: [str(k) for k in dask_scheduler.tasks
                                                               if "scratch-chunks" in str(k)])
        if not left and not any(client.processing().values()):
            break
        time.sleep(0.5)
    assert not left and not any(client.processing().values())


def test04_a_worker_that_joins_mid_render_without_the_scene_gets_it_and_renders_the_same_bits(scheduler, workers,
                                                                                             tmp_path):
    folder = export_scene(tmp_path / "big", film=(128, 96), light=(0.5, 1.0, 1.0))  # chunks of seconds each
    reference = one_process_render(folder, tmp_path / "one.exr", 4096, 2)
    process = subprocess.Popen([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(folder),
                                "-o", str(tmp_path / "out.exr"), "--cluster", scheduler[0], "--variant", VARIANT,
                                "--spp", "4096", "--seed", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    for line in process.stdout:
        if "tasks on 2 workers" in line:
            break
    # Its own, empty scene cache: as a machine that joins the cluster while the render runs.
    late = worker(scheduler, "late", wait=False,
                  env={**os.environ, "SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR": str(tmp_path / "late-cache")})
    try:
        out, err = process.communicate(timeout=900)
    finally:
        stop(scheduler, late)
    assert process.returncode == 0, err
    assert "joined without scene" in out, out  # the late worker was given a task, and the scene with it
    assert read_exr(tmp_path / "out.exr").tobytes() == reference.tobytes()
