"""What runs on a Dask worker: the scene's facts, a run of chunks of the fixed schedule, a frame's export.

Each function is a Dask task (plain arguments in, plain results out).  A worker
process keeps what repeats between tasks: its scene folders on disk
(:mod:`.scenes`), the last loaded scenes in memory (so a render's tasks load
their scene once per worker), the scratch tables in their caches
(:mod:`...bsdf.persistent` in memory, :mod:`...bsdf.tables.disk_cache` on disk)
and Dr.Jit's compiled kernels.  Renders in one worker process take turns
(``--nthreads 1`` is what a render worker wants: Dr.Jit already uses every core).
"""
from __future__ import annotations

import collections
import os
import threading
import time
from dataclasses import dataclass

import numpy as np

from .identity import SoftwareIdentity, software_identity
from .scenes import SceneBundle, cached_scene, store_bundle

__all__ = ["SceneRef", "SceneFacts", "RenderJob", "TaskResult", "SceneMissing", "WorkerMismatch", "RenderCancelled",
           "worker_identity", "has_scene", "store_from_memory", "describe_scene", "render_node", "export_frame",
           "describe_bundle", "transfer_counts", "THREADS_VARIABLE"]

#: Dr.Jit threads of a worker's renders (``--cluster local:N`` sets it to cores / N); unset: all cores.
THREADS_VARIABLE = "SCRATCH_IRIDESCENCE_RENDER_THREADS"
#: Loaded scenes a worker keeps in memory (the frames of an animation come one after the other).
KEPT_SCENES = 2

_render_turn = threading.Lock()
_loaded: "collections.OrderedDict[tuple[str, str], tuple]" = collections.OrderedDict()
_received = {"bundles": 0, "bytes": 0}


@dataclass(frozen=True)
class SceneRef:
    """A scene folder by its digest (:mod:`.scenes`): every worker finds it in its cache."""

    digest: str


@dataclass(frozen=True)
class SceneFacts:
    """What the driver needs to schedule a render: the film, the scene's own spp and seed, the variant."""

    width: int
    height: int
    spp: int
    seed: int
    variant: str
    gpu: bool


@dataclass(frozen=True)
class RenderJob:
    """Everything a chunk task needs besides its chunks; the same for every task of a render."""

    scene: SceneRef
    variant: str
    spp: int
    seed: int
    chunk_count: int
    schedule: str          #: :func:`...render.parts.schedule_digest` of the driver's schedule
    identity: SoftwareIdentity
    cancel_event: str      #: name of the ``distributed.Event`` the driver sets on Ctrl-C


@dataclass(frozen=True)
class TaskResult:
    """A task's tree nodes: ``{(level, index): value}``; a single chunk comes as its float32 image and spp
    (``float64(image) × spp`` is its contribution exactly, half the bytes of the float64 sum)."""

    nodes: dict
    worker: str
    seconds: float
    traced_note: str | None = None

    def node_sums(self) -> dict:
        """``{Node: float64 array}``, as :meth:`...render.schedule.PairwiseSum.node_sums` gave them on the worker."""
        from ..render.schedule import Node

        sums = {}
        for (level, index), value in self.nodes.items():
            if isinstance(value, tuple):  # (float32 image, spp) of one chunk
                image, spp = value
                value = image.astype(np.float64) * float(spp)
            sums[Node(level, index)] = value
        return sums


class SceneMissing(Exception):
    """This worker lacks the scene: it joined after the scene was sent (the driver sends it and retries)."""

    def __init__(self, digest: str, worker: str):
        super().__init__(digest, worker)
        self.digest, self.worker = digest, worker

    def __str__(self):
        return f"worker {self.worker} has no copy of scene {self.digest[:12]}"


class WorkerMismatch(Exception):
    """This worker's software differs from the driver's: its chunks might not merge bit for bit."""

    def __init__(self, worker: str, differences: list):
        super().__init__(worker, differences)
        self.worker, self.differences = worker, differences

    def __str__(self):
        return f"worker {self.worker} runs other software than this machine: {', '.join(self.differences)}"


class RenderCancelled(Exception):
    """The driver cancelled the render (Ctrl-C) while this task ran; it stopped between two chunks."""


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return f"pid {os.getpid()}"


def worker_identity() -> SoftwareIdentity:
    """This worker's software (``client.run`` asks every worker before a render)."""
    return software_identity()


def has_scene(digest: str) -> bool:
    """Is this scene already in this worker's cache? (``client.run`` asks every worker before sending it.)"""
    return cached_scene(digest) is not None


def transfer_counts() -> dict:
    """Scene bundles this worker process received and unpacked, and their bytes (for benchmarks)."""
    return dict(_received)


def _check(identity: SoftwareIdentity) -> None:
    differences = identity.differences(software_identity())
    if differences:
        raise WorkerMismatch(_worker_address(), differences)


def scene_folder(scene: SceneRef):
    """The scene's folder on this worker (the driver stored it in every worker's cache before the render)."""
    folder = cached_scene(scene.digest)
    if folder is None:
        raise SceneMissing(scene.digest, _worker_address())
    return folder


def store_from_memory(key: str, dask_worker=None) -> int:
    """Run on a worker that holds a :class:`~.scenes.SceneBundle` under ``key`` (scattered or replicated
    there): unpack it into the cache; returns the bytes received."""
    bundle: SceneBundle = dask_worker.data[key]
    store_bundle(bundle)
    _received["bundles"] += 1
    _received["bytes"] += bundle.size_bytes
    return bundle.size_bytes


def _activate(variant: str) -> str:
    from ..render.activation import activate

    threads = os.environ.get(THREADS_VARIABLE)
    if threads:
        import drjit as dr

        dr.set_thread_count(int(threads))
    return activate(variant)


def _scene(scene: SceneRef, variant: str):
    """(Mitsuba scene, its facts), loaded once per worker and kept for the next tasks."""
    key = (scene.digest, variant)
    if key in _loaded:
        _loaded.move_to_end(key)
        return _loaded[key]
    from ..device.variants import on_gpu
    from ..folder.export import SCENE_FILE, load_folder, scene_seed

    folder = scene_folder(scene)
    variant = _activate(variant)
    loaded = load_folder(folder)
    sensor = loaded.sensors()[0] if loaded.sensors() else None
    if sensor is None:
        raise ValueError(f"{SCENE_FILE}: the scene has no sensor (camera)")
    width, height = (int(c) for c in sensor.film().crop_size())
    facts = SceneFacts(width, height, int(sensor.sampler().sample_count()), scene_seed(folder / SCENE_FILE),
                       variant, on_gpu())
    _loaded[key] = (loaded, facts)
    while len(_loaded) > KEPT_SCENES:
        _loaded.popitem(last=False)
    return loaded, facts


def describe_scene(scene: SceneRef, variant: str, identity: SoftwareIdentity) -> SceneFacts:
    """Load the scene on this worker (kept for its chunks) and say what the driver needs to schedule it."""
    _check(identity)
    with _render_turn:
        return _scene(scene, variant)[1]


def _cancelled(name: str) -> bool:
    from distributed import Event, get_client

    return Event(name, client=get_client()).is_set()


def render_node(job: RenderJob, first: int, stop: int) -> TaskResult:
    """Render chunks ``first .. stop - 1`` of the job's schedule; returns their tree nodes' sums."""
    from ..render.parts import schedule_digest
    from ..render.passes import plan_render, render_chunks

    _check(job.identity)
    started = time.perf_counter()
    with _render_turn:
        scene, facts = _scene(job.scene, job.variant)
        plan = plan_render(scene, job.spp, seed=job.seed)
        if len(plan.chunks) != job.chunk_count or schedule_digest(plan.chunks) != job.schedule:
            raise ValueError(f"worker {_worker_address()} would render another schedule ({facts.variant}, "
                             f"{len(plan.chunks)} chunks): one render takes one variant's schedule")
        selected = plan.chunks[first:stop]
        from ..render.memory import check_memory
        check_memory(plan.width, plan.height, selected)
        progress = None
        # A single chunk is traced: recording it (dr.freeze) would cost more than it saves, and both give the
        # same bits (the same kernels; docs/rendering.md, How it works).
        for progress in render_chunks(scene, selected, sum(chunk.spp for chunk in selected),
                                      freeze=len(selected) > 1):
            if progress.index < len(selected) and _cancelled(job.cancel_event):
                raise RenderCancelled(f"cancelled after {progress.index} of {len(selected)} chunks")
        nodes = {}
        for node, value in progress.sums.node_sums(job.chunk_count).items():
            if node.level == 0:  # one chunk: image × spp exactly, so image = value / spp exactly
                spp = selected[node.index - first].spp
                nodes[(0, node.index)] = ((value / spp).astype(np.float32), spp)
            else:
                nodes[(node.level, node.index)] = value
        return TaskResult(nodes, _worker_address(), time.perf_counter() - started, progress.traced_note)


def export_frame(blend: SceneRef, blend_name: str, frame: int, identity: SoftwareIdentity) -> SceneBundle:
    """Export ``frame`` of the cached .blend into this worker's scene cache; returns the folder's bundle
    (the driver has Dask copy it to the workers that render the frame's chunks)."""
    import tempfile

    from ..files.frames import frame_path
    from ..folder.blend import export_frames
    from .scenes import pack_folder

    _check(identity)
    folder = scene_folder(blend)
    with tempfile.TemporaryDirectory(prefix=f"frame{frame}-") as building:
        pattern = f"{building}/scene_########"
        export_frames(folder / blend_name, str(frame), pattern)
        bundle = pack_folder(frame_path(pattern, frame))
    store_bundle(bundle)
    return bundle


def describe_bundle(bundle: SceneBundle, variant: str, identity: SoftwareIdentity) -> tuple:
    """(digest, bytes, :class:`SceneFacts`) of an exported frame; runs where the bundle is."""
    store_bundle(bundle)
    return bundle.digest, bundle.size_bytes, describe_scene(SceneRef(bundle.digest), variant, identity)
