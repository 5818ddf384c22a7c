"""Benchmark: rendering over Dask (``render --cluster``) against one process, on this machine.

1. **Overhead**: the exported scratched plate (3 000 scratches, the one of bench_schedule.py) rendered by
   ``render FOLDER`` in one process and by ``render FOLDER --cluster local:2`` (two worker processes of one
   render thread each, which share the machine's cores), each a fresh command (wall time: start, load,
   render, write), alternately, with Dr.Jit's kernel cache warm for both; and, as the split without Dask,
   ``render --chunk 1/2`` and ``--chunk 2/2`` at once followed by ``merge``.  Target: the cluster's wall time
   within 1.15 x the one process's for a render of 30 s or more; the images must be the same bits.
2. **Per-task overhead**: 400 empty tasks through a two-worker LocalCluster (submit, run, result),
   per task and worker.
3. **Scene bytes per worker**: a fresh scene cache, one render, then the same render again.
4. **Scheduling at 64 workers**: 64 worker processes on this machine (forked from this one, on a scheduler
   started with ``dask scheduler``; without the profiler and with a slow system monitor, since 64 idle workers
   sharing two cores would otherwise load them as no farm machine's own worker does); each task sleeps a fixed time
   standing in for a chunk and returns a chunk-sized image, which the driver adds as the renders do
   (:class:`NodeReducer`).  Efficiency = ideal time (tasks x sleep / 64) / wall time; target >= 90 %.

The machine is shared with other sessions: compare the ratios of one run, not the absolute times.

Run: ``.venv/bin/python tests/bench/bench_cluster.py [--spp 384] [--rounds 1] [--skip-64]``
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "bridge"))
sys.path.insert(0, str(ROOT / "tests" / "bridge" / "builder"))


def export_plate(folder: Path, size: int) -> Path:
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge import scratch
    from scratch_iridescence.mitsuba_bridge.folder import export
    from scratch_iridescence.mitsuba_bridge.render.activation import activate
    from test_scratched import metal, plate_scene

    activate("llvm_ad_spectral")
    scratches = scratch.random_scratches(3000, seed=5, width=scratch.Gaussian(4e-6, 1.3e-6), length=(0.2, 0.6),
                                         depth=scratch.Gaussian(250e-9, 80e-9), depth_variation=(1.1, 0.04))
    description = plate_scene(metal(scratches))
    description = S.SceneDescription(film=S.Film(size, size), camera=description.camera, shapes=description.shapes,
                                     materials=description.materials, world=description.world)
    export.export_folder(description, S.RenderSettings(), folder)
    return folder


def command(folder, output, spp, *extra) -> tuple[float, float]:
    """(wall seconds, CPU seconds) of one ``render`` command; the CPU time includes the worker processes of a
    ``local:N`` cluster (children of the command, waited for), so it resists the shared machine's load."""
    before, start = os.times(), time.perf_counter()
    subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(folder), "-o",
                    str(output), "--spp", str(spp), "--variant", "llvm_ad_spectral", "-q", *extra], check=True,
                   capture_output=True)
    after = os.times()
    return time.perf_counter() - start, (after.children_user + after.children_system
                                         - before.children_user - before.children_system)


def split_commands(folder, work: Path, spp: int) -> tuple[float, float]:
    """(wall, CPU seconds) of ``render --chunk 1/2`` and ``--chunk 2/2`` run at once, then ``merge``: the same
    split over two processes without Dask."""
    before, start = os.times(), time.perf_counter()
    base = [sys.executable, "-m", "scratch_iridescence.mitsuba_bridge"]
    parts = [subprocess.Popen(base + ["render", str(folder), "-o", str(work / f"part_{k}.exr"), "--spp", str(spp),
                                      "--variant", "llvm_ad_spectral", "-q", "--chunk", f"{k}/2"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for k in (1, 2)]
    assert all(part.wait() == 0 for part in parts)
    subprocess.run(base + ["merge", str(work / "part_1.exr"), str(work / "part_2.exr"), "-o", str(work / "split.exr")],
                   check=True, capture_output=True)
    after = os.times()
    return time.perf_counter() - start, (after.children_user + after.children_system
                                         - before.children_user - before.children_system)


def overhead(folder: Path, work: Path, spp: int, rounds: int) -> None:
    command(folder, work / "warm.exr", 4)  # kernels of this scene compiled once (both runs then find them cached)
    command(folder, work / "warm2.exr", 4, "--cluster", "local:2")
    from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

    ones, clusters, splits = [], [], []
    for _ in range(rounds):  # alternately, so that all meet the same load
        ones.append(command(folder, work / "one.exr", spp))
        clusters.append(command(folder, work / "cluster.exr", spp, "--cluster", "local:2"))
        splits.append(split_commands(folder, work, spp))
    same = (work / "one.exr").read_bytes() == (work / "cluster.exr").read_bytes()
    same_split = read_exr(work / "one.exr").tobytes() == read_exr(work / "split.exr").tobytes()
    wall = [min(w for w, _ in runs) for runs in (ones, clusters, splits)]
    cpu = [min(c for _, c in runs) for runs in (ones, clusters, splits)]
    print(f"1. overhead (best of {rounds}): wall one process {wall[0]:.1f} s, --cluster local:2 {wall[1]:.1f} s: "
          f"{wall[1] / wall[0]:.3f} x (target <= 1.15); CPU {cpu[0]:.1f} s vs {cpu[1]:.1f} s: {cpu[1] / cpu[0]:.3f} x; "
          f"same bits: {same}\n   two --chunk K/2 processes at once + merge, no Dask: wall {wall[2]:.1f} s "
          f"({wall[2] / wall[0]:.3f} x), CPU {cpu[2]:.1f} s ({cpu[2] / cpu[0]:.3f} x); same pixels: {same_split}")


def noop(value):
    return value


def per_task_overhead(count: int = 400) -> None:
    from distributed import Client, LocalCluster, wait

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        wait([client.submit(noop, i, pure=False) for i in range(20)])
        start = time.perf_counter()
        futures = [client.submit(noop, i, pure=False) for i in range(count)]
        client.gather(futures)
        seconds = time.perf_counter() - start
    print(f"2. per-task overhead: {count} empty tasks on 2 workers in {seconds:.2f} s: "
          f"{1e3 * seconds * 2 / count:.1f} ms per task and worker")


def scene_bytes(folder: Path, spp: int) -> None:
    os.environ["SCRATCH_IRIDESCENCE_SCENE_CACHE_DIR"] = tempfile.mkdtemp(prefix="bench-scene-cache-")
    from distributed import Client, LocalCluster

    from scratch_iridescence.mitsuba_bridge.cluster import scenes, tasks
    from scratch_iridescence.mitsuba_bridge.cluster.driver import Cluster
    from scratch_iridescence.mitsuba_bridge.cluster.identity import software_identity

    bundle = scenes.pack_folder(folder)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as local, \
            Client(local) as client:
        cluster = Cluster(client, software_identity())
        received = []
        for _ in range(2):
            cluster.render(bundle, variant="llvm_ad_spectral", spp=spp, seed=0)
            received.append({w: c["bytes"] for w, c in client.run(tasks.transfer_counts).items()})
    first = sorted(received[0].values())
    second = [received[1][w] - received[0][w] for w in sorted(received[0])]
    print(f"3. scene bytes per worker: bundle {bundle.size_bytes / 1e6:.2f} MB; first render {first}, "
          f"repeated render {second}")


def sleeping_chunk(index: int, seconds: float, pixels: int):
    import time as clock

    import numpy as np

    clock.sleep(seconds)
    return index, np.full((pixels, 4), index, np.float32)


def run_forked_worker(address: str, name: str) -> None:
    """One worker process: a Dask ``Worker`` of one thread on the scheduler at ``address``, until it is closed."""
    import asyncio

    from distributed import Worker

    async def serve():
        async with Worker(address, nthreads=1, name=name, memory_limit=0, dashboard=False,
                          silence_logs=40) as worker:
            await worker.finished()

    asyncio.run(serve())


def fork_workers(address: str, count: int) -> list[int]:
    """``count`` worker processes forked from this one, which has imported Dask once but started no thread or
    event loop yet: on two shared cores, 64 workers that each start a fresh Python and import Dask (with a nanny
    process each, as ``LocalCluster`` does) took longer than 15 minutes; forked, they are up in seconds."""
    pids = []
    for number in range(count):
        pid = os.fork()
        if pid == 0:  # the worker: never returns into the benchmark
            status = 0
            try:
                run_forked_worker(address, f"sleeper-{number}")
            except BaseException:
                status = 1
            os._exit(status)
        pids.append(pid)
    return pids


def sixty_four_workers(workers: int, seconds: float, per_worker: int, pixels: int) -> None:
    import json
    import signal

    import numpy as np
    import dask
    from distributed import Client, as_completed, wait

    from scratch_iridescence.mitsuba_bridge.cluster.driver import LOCAL_WORKER_CONFIG  # no Mitsuba, no thread

    # Patient connections on a shared machine (Dask's defaults give up after 30 s): in this process, the forked
    # workers (they inherit it) and the scheduler (by environment, as Dask reads its configuration).
    patience = {"distributed.comm.timeouts.connect": "300s", "distributed.comm.timeouts.tcp": "300s"}
    # 64 workers share two cores here, where on a farm each has its machine: the workers leave out what costs
    # CPU while they idle (the profiler's stack samples every 10 ms, as local:N workers do; the system monitor's
    # twice a second), or 64 of them would keep the cores busy by themselves (45 ms CPU per second each, measured).
    lean = {**LOCAL_WORKER_CONFIG, "distributed.admin.system-monitor.interval": "10s",
            "distributed.admin.system-monitor.disk": False}
    dask.config.set({**patience, **lean})
    environment = {**os.environ, **{"DASK_" + key.upper().replace(".", "__").replace("-", "_"): value
                                    for key, value in patience.items()}}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as work:
        scheduler_file = Path(work) / "scheduler.json"
        scheduler = subprocess.Popen([str(Path(sys.executable).parent / "dask"), "scheduler", "--host", "127.0.0.1",
                                      "--port", "0", "--no-dashboard", "--scheduler-file", str(scheduler_file)],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=environment)
        pids = []
        try:
            while not scheduler_file.exists():
                time.sleep(0.2)
            time.sleep(0.2)  # the file is written whole, but give it the moment
            address = json.loads(scheduler_file.read_text())["address"]
            pids = fork_workers(address, workers)  # before this process starts any thread (the client's loop)
            from scratch_iridescence.mitsuba_bridge.cluster.reduce import NodeReducer
            from scratch_iridescence.mitsuba_bridge.render.schedule import Node

            with Client(address) as client:
                client.wait_for_workers(workers, timeout=900)
                up = time.perf_counter() - started
                wait([client.submit(noop, i, pure=False) for i in range(workers)])
                count = workers * per_worker
                reducer = NodeReducer(count)
                start = time.perf_counter()
                futures = [client.submit(sleeping_chunk, i, seconds, pixels, pure=False) for i in range(count)]
                for future in as_completed(futures):
                    index, image = future.result()
                    future.release()
                    reducer.add(Node(0, index), image.astype(np.float64))
                wall = time.perf_counter() - start
                client.retire_workers(close_workers=True)
        finally:
            for pid in pids:
                try:
                    os.kill(pid, signal.SIGTERM)
                except ProcessLookupError:
                    pass
            for pid in pids:
                os.waitpid(pid, 0)
            scheduler.terminate()
            scheduler.wait()
    ideal = count * seconds / workers
    print(f"4. {workers} worker processes (forked; up in {up:.0f} s): {count} tasks of {seconds:.1f} s sleep + a "
          f"{pixels * 16 / 1e6:.2f} MB image each in {wall:.1f} s, ideal {ideal:.1f} s: efficiency "
          f"{100 * ideal / wall:.1f} % (target >= 90 %)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--spp", type=int, default=384, help="of the overhead render (30 s or more in one process)")
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--workers", type=int, default=64)
    parser.add_argument("--sleep", type=float, default=2.0, help="seconds per simulated chunk")
    parser.add_argument("--skip-64", action="store_true")
    parser.add_argument("--only-overhead", action="store_true")
    parser.add_argument("--only-64", action="store_true")
    args = parser.parse_args()
    if args.only_64:
        return sixty_four_workers(args.workers, args.sleep, 8, 128 * 96)
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        folder = export_plate(work / "plate", args.size)
        overhead(folder, work, args.spp, args.rounds)
        if args.only_overhead:
            return
        per_task_overhead()
        scene_bytes(folder, 8)
    if not args.skip_64:
        sixty_four_workers(args.workers, args.sleep, 8, 128 * 96)


if __name__ == "__main__":
    main()
