"""The driver of a render on a Dask cluster: connect, check the workers, ship the scene, run and merge the chunks.

``render FOLDER -o OUT --cluster ADDRESS`` runs here.  The fixed sample schedule
(:mod:`...render.schedule`) is cut into tasks of aligned tree nodes
(:func:`.reduce.task_nodes`); each task renders its chunks on a worker
(:func:`.tasks.render_node`) and the driver adds the returned node sums as they
arrive (:class:`.reduce.NodeReducer`): the image is the one-machine render's,
bit for bit, whichever worker rendered what and in which order.

What Dask gives: placement, peer-to-peer transfer of the scene to workers that
lack it, and resilience: a task whose worker dies is rescheduled on another
(Dask's ``allowed-failures``, 3 by default, before it gives up), and since the
driver takes every result as soon as it is ready, a dead worker costs only the
task it was rendering.  What is refused up front, each in one line
(:class:`ClusterError`): a scheduler that cannot be reached, no workers, a worker
without the package or with other software (:mod:`.identity`), a mix of GPU and
CPU workers for an ``auto`` variant (two schedules: the render would not be the
one-machine render of either).
"""
from __future__ import annotations

import contextlib
import logging
import os
import re
import secrets
import time
from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from ..errors import ScratchUserError
from . import tasks
from .identity import DISTRIBUTION, SoftwareIdentity, software_identity
from .progress import ClusterProgress
from .reduce import NodeReducer, task_nodes
from .scenes import SceneBundle

__all__ = ["ClusterError", "connect", "local_cluster", "LOCAL_WORKER_CONFIG", "Cluster", "MAX_TASKS_PER_WORKER",
           "GPU_RESOURCE"]

#: Tasks per worker above which chunks are grouped (a schedule of 2**20 chunks is not 2**20 tasks).
MAX_TASKS_PER_WORKER = 64
#: The Dask worker resource that marks a GPU worker (``dask worker --resources GPU=1``).
GPU_RESOURCE = "GPU"
#: How long to wait for a first worker (a SLURM job may still be starting them).
WORKER_WAIT_S = float(os.environ.get("SCRATCH_IRIDESCENCE_WORKER_WAIT_S", 60))


class ClusterError(ScratchUserError):
    """A render on a cluster that cannot start or finish; the message says what to do."""


#: Dask settings of ``local:N``, whose workers share the driver's cores: no statistical profiler (it samples every
#: thread's stack every 10 ms, about half of an idle worker's CPU time, and a render task's stack says nothing the
#: progress lines do not); the nannies' memory checks once a second instead of ten times, the system monitor's
#: every 2 s instead of 0.5 s (measured idle: 94 ms of CPU per second for a driver and two workers with Dask's
#: defaults but the profiler, 67 ms with these).
LOCAL_WORKER_CONFIG = {"distributed.worker.profile.enabled": False,
                       "distributed.worker.memory.monitor-interval": "1s",
                       "distributed.admin.system-monitor.interval": "2s"}


def local_cluster(workers: int):
    """The ``LocalCluster`` of ``--cluster local:N``: ``workers`` processes of one task thread each."""
    import dask
    from distributed import LocalCluster

    threads = max(1, (os.cpu_count() or 1) // workers)
    # One render thread per worker process (Dr.Jit has its own pool), sized to share the cores.  The nannies
    # hand the configuration they were made under to their worker processes.
    with dask.config.set(LOCAL_WORKER_CONFIG):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                            silence_logs=logging.ERROR, env={tasks.THREADS_VARIABLE: str(threads)})


@contextlib.contextmanager
def connect(address: str) -> Iterator["Cluster"]:
    """A :class:`Cluster` for ``address``: ``local:N`` (a ``LocalCluster`` of N worker processes, closed at the end)
    or a scheduler address (``tcp://host:8786``, as ``dask scheduler`` or dask-jobqueue print it)."""
    try:
        from distributed import Client
    except ImportError as error:
        raise ClusterError(f"--cluster needs Dask ({error}): pip install '{DISTRIBUTION}[cluster]'") from None
    local = None
    if address.startswith("local:"):
        try:
            workers = int(address.split(":", 1)[1])
        except ValueError:
            workers = 0
        if workers < 1:
            raise ClusterError(f"--cluster {address}: expected local:N with N >= 1 worker processes")
        local = local_cluster(workers)
        client = Client(local)
    else:
        try:
            client = Client(address, timeout="20s")
        except (OSError, TimeoutError, ValueError) as error:
            raise ClusterError(f"cannot reach the Dask scheduler at {address}: {error}") from None
    try:
        yield Cluster(client, software_identity())
    finally:
        client.close()
        if local is not None:
            local.close()


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split())
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


@dataclass
class RenderedImage:
    """A finished render: its (H, W, 4) float32 image and what rendered it."""

    image: np.ndarray
    variant: str
    chunk_count: int
    tasks: int
    seconds: float
    traced_note: str | None = None


@dataclass
class _Frame:
    """One image in flight on the cluster: its tasks and the sums they returned so far."""

    label: str
    scene: tasks.SceneRef
    facts: tasks.SceneFacts
    job: tasks.RenderJob
    runs: list
    reducer: NodeReducer
    priority: int
    started: float = field(default_factory=time.perf_counter)
    traced_note: str | None = None


class Cluster:
    """A connected Dask client with the checks and the bookkeeping of this package's renders."""

    def __init__(self, client, identity: SoftwareIdentity):
        self.client = client
        self.identity = identity
        self.cancel_event = f"scratch-iridescence-cancel-{secrets.token_hex(6)}"
        self.scene_bytes_sent = 0  #: bundle bytes this driver sent (scatter) so far
        self._checked: set[str] = set()
        self._warming: list = []

    # ---- workers
    def workers(self) -> dict:
        """``{address: resources}`` of the workers now connected (waits for a first one)."""
        try:
            self.client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        except TimeoutError:
            raise ClusterError(f"no Dask worker joined the scheduler within {WORKER_WAIT_S:.0f} s (start some: "
                               f"dask worker {self.client.scheduler.address} --nthreads 1)") from None
        return {address: dict(info.get("resources") or {})
                for address, info in self.client.scheduler_info(n_workers=-1)["workers"].items()}

    def check_workers(self) -> dict:
        """The workers, each checked once: the package importable, the same software as here."""
        workers = self.workers()
        new = [address for address in workers if address not in self._checked]
        if new:
            answers = self.client.run(tasks.worker_identity, workers=new, on_error="return")
            for address, answer in sorted(answers.items()):
                if isinstance(answer, BaseException):
                    # Dask wraps what failed to unpickle there: the module's name is all that matters.
                    missing = re.search(r"No module named '([\w.]+)'", str(answer))
                    what = (f"cannot import {missing.group(1).split('.')[0]} (No module named '{missing.group(1)}')"
                            if missing else f"failed the software check ({_one_line(answer)})")
                    raise ClusterError(f"worker {address} {what}: install the same version on every worker: "
                                       f"pip install '{DISTRIBUTION}[cluster]=={self.identity.version}'")
                differences = self.identity.differences(answer)
                if differences:
                    raise ClusterError(f"worker {address} runs other software than this machine "
                                       f"({', '.join(differences)}): its chunks might not merge bit for bit; install "
                                       f"{self.identity} there")
            self._checked.update(new)
        return workers

    def choose_variant(self, requested: str, workers: dict) -> tuple[str, dict | None]:
        """(variant, task resources): GPU workers render a GPU variant's schedule, the others a CPU one's.

        ``auto`` takes ``cuda_ad_spectral`` when every worker offers a ``GPU`` resource and
        ``llvm_ad_spectral`` when none does; a mix is refused: CPU and GPU chunks round differently and
        follow different schedules, so one render must use one kind.
        """
        gpus = sorted(a for a, resources in workers.items() if resources.get(GPU_RESOURCE, 0) >= 1)
        if requested == "auto":
            if gpus and len(gpus) < len(workers):
                raise ClusterError(
                    f"the cluster mixes {len(gpus)} GPU worker(s) and {len(workers) - len(gpus)} CPU worker(s): one "
                    f"render takes one schedule (CPU and GPU chunks differ in their bits); pass --variant "
                    f"cuda_ad_spectral (GPU workers only) or --variant llvm_ad_spectral (every worker on its CPU)")
            requested = "cuda_ad_spectral" if gpus else "llvm_ad_spectral"
        if requested.startswith("cuda"):
            if not gpus:
                raise ClusterError(f"--variant {requested} needs GPU workers (dask worker --resources GPU=1); "
                                   "this cluster has none")
            return requested, {GPU_RESOURCE: 1}
        return requested, None

    # ---- scenes
    def ship(self, bundle: SceneBundle | None, workers, progress: ClusterProgress | None = None, *,
             digest: str | None = None, size_bytes: int = 0, source=None, what: str = "scene") -> tasks.SceneRef:
        """Store the scene in the cache of every worker that lacks it; nothing is sent to the others.

        ``source`` is a future already holding the bundle on the cluster (a frame a worker exported, whose
        ``digest`` and ``size_bytes`` are given instead of ``bundle``): Dask copies it worker to worker.
        Otherwise this driver sends ``bundle``.
        """
        digest = bundle.digest if bundle is not None else digest
        size_bytes = bundle.size_bytes if bundle is not None else size_bytes
        have = self.client.run(tasks.has_scene, digest, workers=list(workers))
        lacking = sorted(address for address, present in have.items() if not present)
        if not lacking:
            if progress:
                progress.message(f"{what} {digest[:12]} is already on all {len(have)} workers: nothing sent")
            return tasks.SceneRef(digest)
        self._send(bundle, lacking, source)
        if progress:
            progress.message(f"{what} {digest[:12]} ({size_bytes / 1e6:.2f} MB) sent to {len(lacking)} of "
                             f"{len(have)} workers")
        return tasks.SceneRef(digest)

    def _send(self, bundle: SceneBundle | None, workers: list, source=None) -> None:
        if source is not None:
            self.client.replicate([source], workers=workers)
            held = source
        else:
            held = self.client.scatter(bundle, workers=workers, broadcast=True, hash=False)
            self.scene_bytes_sent += bundle.size_bytes * len(workers)
        try:
            self.client.run(tasks.store_from_memory, held.key, workers=workers)
        finally:
            if source is None:
                held.release()

    def describe(self, scene: tasks.SceneRef, variant: str, resources: dict | None, workers=()) -> tasks.SceneFacts:
        """The scene's facts from the first of ``workers`` to load it: every one of them loads it at once
        (each keeps it for its chunks), so no worker loads it later on the render's critical path."""
        from distributed import as_completed

        futures = [self.client.submit(tasks.describe_scene, scene, variant, self.identity, resources=resources,
                                      pure=False, workers=[address] if address else None,
                                      key=f"scratch-describe-{secrets.token_hex(6)}")
                   for address in (list(workers) or [None])]
        first = next(as_completed(futures))
        self._warming = futures  # the others finish loading meanwhile; released with the render
        return self._result(first)

    def _result(self, future):
        try:
            return future.result()
        except (tasks.WorkerMismatch, tasks.SceneMissing) as error:
            raise ClusterError(str(error)) from None
        except ScratchUserError as error:
            raise ClusterError(f"a worker refused the render: {error}") from None
        except (OSError, RuntimeError, ValueError, MemoryError) as error:
            raise ClusterError(f"a worker failed: {_one_line(error)}") from None
        except Exception as error:  # KilledWorker: the task took down every worker it ran on
            if type(error).__name__ == "KilledWorker":  # distributed.scheduler.KilledWorker
                raise ClusterError(f"a task was lost with its worker every time it ran, as often as Dask's "
                                   f"allowed-failures permits: {_one_line(error)}") from None
            raise

    # ---- rendering
    def chunks_per_task(self, chunk_count: int, workers: int, requested: int | None = None) -> int:
        """One chunk per task (a lost worker costs one chunk), grouped by powers of two only beyond
        :data:`MAX_TASKS_PER_WORKER` tasks per worker."""
        if requested:
            return requested
        size = 1
        while chunk_count / size > MAX_TASKS_PER_WORKER * max(workers, 1):
            size *= 2
        return size

    def frame(self, label: str, scene: tasks.SceneRef, facts: tasks.SceneFacts, variant: str, spp: int | None,
              seed: int | None, workers: int, *, priority: int = 0, chunks_per_task: int | None = None) -> _Frame:
        """A :class:`_Frame` ready to submit: the schedule of ``facts`` (the GPU one on a GPU variant)."""
        from ..render.parts import schedule_digest
        from ..render.schedule import ScheduleError, sample_schedule

        spp = spp or facts.spp
        seed = facts.seed if seed is None else seed
        try:
            chunks = sample_schedule(spp, facts.width * facts.height, seed, gpu=facts.gpu)
        except ScheduleError as error:
            raise ClusterError(str(error)) from None
        size = self.chunks_per_task(len(chunks), workers, chunks_per_task)
        job = tasks.RenderJob(scene, variant, spp, seed, len(chunks), schedule_digest(chunks), self.identity,
                              self.cancel_event)
        return _Frame(label, scene, facts, job, task_nodes(len(chunks), size), NodeReducer(len(chunks)), priority)

    def submit(self, frame: _Frame, resources: dict | None) -> dict:
        """Submit a frame's tasks; ``{future: (frame, run)}``."""
        futures = {}
        for number, run in enumerate(frame.runs):
            future = self.client.submit(tasks.render_node, frame.job, run.start, run.stop, resources=resources,
                                        priority=frame.priority, pure=False,
                                        key=f"scratch-chunks-{frame.label}-{run.start}-{secrets.token_hex(4)}")
            futures[future] = (frame, run)
        return futures

    def resubmit(self, frame: _Frame, run: range, resources: dict | None, missing: tasks.SceneMissing,
                 bundle: SceneBundle | None, source=None, progress: ClusterProgress | None = None):
        """A task whose worker lacked the scene (it joined late): send the scene there, then the task again."""
        self._send(bundle, [missing.worker], source)
        if progress is not None:
            progress.message(f"worker {missing.worker} joined without scene {missing.digest[:12]}: sent it there")
        return self.client.submit(tasks.render_node, frame.job, run.start, run.stop, resources=resources,
                                  priority=frame.priority, pure=False,
                                  key=f"scratch-chunks-{frame.label}-{run.start}-{secrets.token_hex(4)}")

    def cancel(self, futures) -> int:
        """Ctrl-C: tell running tasks to stop after their chunk and cancel every task not yet finished."""
        from distributed import Event

        pending = [future for future in futures if not future.done()]
        with contextlib.suppress(Exception):
            Event(self.cancel_event, client=self.client).set()
        with contextlib.suppress(Exception):
            self.client.cancel(pending, force=True)
        return len(pending)

    def render(self, folder_bundle: SceneBundle, *, variant: str = "auto", spp: int | None = None,
               seed: int | None = None, chunks_per_task: int | None = None,
               progress: ClusterProgress | None = None, on_planned=None) -> RenderedImage:
        """Render one exported scene on the cluster; the image equals the one-machine render bit for bit."""
        from distributed import as_completed

        workers = self.check_workers()
        variant, resources = self.choose_variant(variant, workers)
        scene = self.ship(folder_bundle, workers, progress)
        facts = self.describe(scene, variant, resources, [a for a, r in workers.items()
                                                          if resources is None or r.get(GPU_RESOURCE, 0) >= 1])
        frame = self.frame("frame", scene, facts, variant, spp, seed, len(workers), chunks_per_task=chunks_per_task)
        if on_planned is not None:
            on_planned(frame, len(workers))
        if progress is not None:
            progress.grow(frame.job.chunk_count)
        started = time.perf_counter()
        futures = self.submit(frame, resources)
        try:
            queue = as_completed(list(futures))
            for future in queue:
                frame_, run = futures.pop(future)
                if future.status == "error" and isinstance(future.exception(), tasks.SceneMissing):
                    retry = self.resubmit(frame_, run, resources, future.exception(), folder_bundle,
                                          progress=progress)
                    futures[retry] = (frame_, run)
                    queue.add(retry)
                    continue
                result = self._result(future)
                future.release()
                frame_.traced_note = frame_.traced_note or result.traced_note
                for node, value in result.node_sums().items():
                    frame_.reducer.add(node, value)
                if progress is not None:
                    progress.update(frame_.reducer.chunks_done)
        except KeyboardInterrupt:
            cancelled = self.cancel(list(futures))
            with contextlib.suppress(Exception):
                self.client.cancel(self._warming, force=True)
            if progress is not None:
                progress.message(f"cancelled {cancelled} task(s) on the cluster")
            raise
        finally:
            self._warming = []
        image = (frame.reducer.total() / frame.job.spp).astype(np.float32)
        return RenderedImage(image, facts.variant, frame.job.chunk_count, len(frame.runs),
                             time.perf_counter() - started, frame.traced_note)

