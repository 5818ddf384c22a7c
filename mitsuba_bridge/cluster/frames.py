"""An animation on a Dask cluster: each frame exported once by a worker, then its chunks as tasks.

``render-frames shot.blend --frames 1-240 -o out/frame_####.exr --cluster ADDRESS``:
the driver sends the .blend to the workers (once, content-addressed, as a
scene), and for each frame a worker exports it with pip's ``bpy``
(:func:`.tasks.export_frame`) into its scene cache; Dask copies the exported
folder to the other workers that lack it, and the frame's chunks run as tasks
like a single image's (:meth:`.driver.Cluster.render`).  Frames overlap: the
next frames are exported while the current ones render, at most
``window`` frames at a time, earlier frames first (Dask priorities), and each
frame is written as soon as its last chunk arrives.
"""
from __future__ import annotations

import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from . import tasks
from .driver import Cluster, ClusterError
from .progress import ClusterProgress
from .scenes import pack_file

__all__ = ["render_frames_on_cluster"]


@dataclass
class _Export:
    frame: int
    export: object          #: future of the frame's SceneBundle (on the worker that exported it)
    described: object       #: future of (digest, bytes, SceneFacts)


def render_frames_on_cluster(cluster: Cluster, blend, frames: list[int], write: Callable[[int, np.ndarray], Path], *,
                             variant: str = "auto", spp: int | None = None, seed: int | None = None,
                             progress: ClusterProgress | None = None, window: int | None = None) -> int:
    """Render ``frames`` of ``blend`` on the cluster; ``write(frame, image)`` stores each finished frame.

    Returns the number of frames written.  Each frame equals the one-machine render of its exported
    folder, bit for bit.
    """
    from distributed import as_completed

    workers = cluster.check_workers()
    variant, resources = cluster.choose_variant(variant, workers)
    blend_bundle = pack_file(blend)
    blend_ref = cluster.ship(blend_bundle, workers, progress, what=f"{Path(blend).name}")
    window = window or max(2, len(workers))
    waiting = list(frames)
    exports: dict = {}       # future -> _Export (the describe future is what completes)
    renders: dict = {}       # future -> (_Frame, run, _Export)
    frames_left: dict = {}   # frame number -> (_Frame, _Export)
    written = chunks_written = 0
    queue = as_completed()
    total = len(frames)
    order = {frame: number for number, frame in enumerate(frames)}

    def export_next():
        while waiting and len(exports) + len(frames_left) < window:
            frame = waiting.pop(0)
            priority = total - order[frame]  # earlier frames first
            export = cluster.client.submit(tasks.export_frame, blend_ref, Path(blend).name, frame, cluster.identity,
                                           priority=priority, pure=False,
                                           key=f"scratch-export-{frame}-{secrets.token_hex(4)}")
            described = cluster.client.submit(tasks.describe_bundle, export, variant, cluster.identity,
                                              resources=resources, priority=priority, pure=False,
                                              key=f"scratch-describe-{frame}-{secrets.token_hex(4)}")
            exports[described] = _Export(frame, export, described)
            queue.add(described)

    try:
        export_next()
        for future in queue:
            if future in exports:
                item = exports.pop(future)
                digest, size_bytes, facts = cluster._result(future)
                scene = cluster.ship(None, cluster.workers(), progress, digest=digest, size_bytes=size_bytes,
                                     source=item.export, what=f"frame {item.frame}")
                frame = cluster.frame(f"frame{item.frame}", scene, facts, variant, spp, seed, len(workers),
                                      priority=total - order[item.frame])
                frames_left[item.frame] = (frame, item)
                if progress is not None:
                    progress.grow(frame.job.chunk_count)
                for task, (frame_, run) in cluster.submit(frame, resources).items():
                    renders[task] = (frame_, run, item)
                    queue.add(task)
                continue
            frame, run, item = renders.pop(future)
            if future.status == "error" and isinstance(future.exception(), tasks.SceneMissing):
                retry = cluster.resubmit(frame, run, resources, future.exception(), None, source=item.export,
                                         progress=progress)
                renders[retry] = (frame, run, item)
                queue.add(retry)
                continue
            result = cluster._result(future)
            future.release()
            for node, value in result.node_sums().items():
                frame.reducer.add(node, value)
            if progress is not None:
                progress.update(sum(f.reducer.chunks_done for f, _ in frames_left.values()) + chunks_written)
            if frame.reducer.finished:
                image = (frame.reducer.total() / frame.job.spp).astype(np.float32)
                path = write(item.frame, image)
                written += 1
                chunks_written += frame.job.chunk_count
                del frames_left[item.frame]
                item.export.release()
                if progress is not None:
                    progress.message(f"wrote {path} (frame {item.frame}, {written} of {total})")
                export_next()
    except KeyboardInterrupt:
        cancelled = cluster.cancel(list(renders) + list(exports) + [item.export for item in exports.values()])
        if progress is not None:
            progress.message(f"cancelled {cancelled} task(s) on the cluster; {written} of {total} frames written")
        raise
    if written != total:
        raise ClusterError(f"only {written} of {total} frames were rendered")
    return written

