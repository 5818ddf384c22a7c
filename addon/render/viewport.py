"""The Rendered viewport: a worker thread owns the Mitsuba session, Blender's main thread only posts and draws.

Main thread (``view_update``, ``view_draw``): reads the depsgraph and the 3D
view, turns what changed into :class:`~mitsuba_bridge.render.session.Update` records, posts them and
draws the newest image.  It never waits for Mitsuba: posting takes a lock
held only for list swaps.  Worker thread: applies the posted updates to its
:class:`mitsuba_bridge.render.session.Session` between passes (a pending full
build drops the updates queued before it; only the last camera counts) and
renders one pass (on the CPU one strip of a pass) at a time until the session
has its samples, then sleeps until the next update; it posts an image when a
pass is complete.  After a preview it waits ``LINGER_SECONDS`` for the next
change, so that continuous orbiting shows previews, not stale full passes.
The image on screen stays until a newer one exists, also while a rebuild
compiles.

Only a real window exercises the drawing (``gpu`` raises in background mode):
:meth:`ViewportRender.draw` uploads the image as an ``RGBA16F`` texture and
draws it inside ``bind_display_space_shader``/``unbind_display_space_shader``,
so Blender's colour management (view transform, look, exposure) applies as
for Cycles.

A process that exits while a worker renders would tear Dr.Jit down under the
running kernel (C++ ``std::terminate``: "terminate called without an active
exception", the process aborts): :func:`_end_workers_at_exit` stops every worker
and waits for its pass before the interpreter shuts down.
"""
from __future__ import annotations

import atexit
import threading
import time
import traceback
from collections import deque

import numpy as np

from ...mitsuba_bridge.errors import ScratchUserError
from ...mitsuba_bridge.render.session import Change, Session, Update
from ...mitsuba_bridge.scene import Film
from . import sync
from .backend import MITSUBA_MISSING
from .frame import combined_rect
from .turns import viewport_turn
from .view import border_crop, view_camera

__all__ = ["ViewportRender", "coalesce"]

#: Main-thread durations kept for the statistics (seconds per view_update / view_draw call).
TIMING_WINDOW = 256
#: After a preview pass the worker waits this long for the next change before it starts a
#: full-resolution pass, which cannot be interrupted: while the user keeps orbiting or dragging,
#: only quick previews are rendered (as in Cycles).
LINGER_SECONDS = 0.05
#: How long an exiting process waits for a worker's pass in flight (a scene build can take this long).
EXIT_WAIT_SECONDS = 60.0

#: (viewport, worker thread) of every worker alive, for :func:`_end_workers_at_exit`.
_workers: set = set()
_workers_lock = threading.Lock()


def _end_workers_at_exit() -> None:
    """Stop every viewport worker and wait for its pass in flight (``atexit``: before the interpreter and
    then Dr.Jit's C++ state are torn down; the session's import above loaded ``drjit`` first, so this also
    runs before any exit handler of Dr.Jit's, ``atexit`` calling them in reverse order)."""
    with _workers_lock:
        workers = list(_workers)
    for viewport, _ in workers:
        viewport.stop()
    for _, thread in workers:
        thread.join(EXIT_WAIT_SECONDS)


atexit.register(_end_workers_at_exit)


def coalesce(updates: list) -> list:
    """The updates worth applying, in order: nothing before the last build, only the last camera and film."""
    builds = [i for i, update in enumerate(updates) if update.change is Change.BUILD]
    if builds:
        updates = updates[builds[-1]:]
    views = (Change.CAMERA, Change.FILM)
    last = {update.change: i for i, update in enumerate(updates) if update.change in views}
    return [u for i, u in enumerate(updates) if u.change not in views or last[u.change] == i]


class ViewportRender:
    """One viewport's render: the worker thread, the sync state and the texture of the newest image."""

    def __init__(self):
        self._lock = threading.Condition()
        self._pending: list = []
        self._stopping = False
        self._latest = None  #: newest Progress
        self._rect = None  #: its pixels as the texture wants them (rows bottom-up, RGBA), made by the worker
        self._crop = None  #: the film's crop window (x, y, w, h from the top-left) of that image, if any
        self._version = 0  #: bumped with every new image
        self._finished = False
        self._error: str | None = None
        self._stats: dict = {}
        self._thread: threading.Thread | None = None
        # main thread only
        self.state: sync.SyncState | None = None
        self._view = None  #: (Camera, Film) last posted
        self._texture = None
        self._texture_version = -1
        self.draw_error: str | None = None  #: the last drawing failure (gpu is unavailable in background mode)
        self.main_thread_seconds: deque = deque(maxlen=TIMING_WINDOW)

    # ------------------------------------------------------------------ main thread
    def post(self, updates: list) -> None:
        """Hand updates to the worker (never blocks on rendering)."""
        if not updates:
            return
        with self._lock:
            self._pending += updates
            self._finished = False
            self._lock.notify()
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="mitsuba-scratch-viewport", daemon=True)
            with _workers_lock:
                _workers.add((self, self._thread))
            self._thread.start()

    def view_update(self, context, depsgraph) -> None:
        """Sync the depsgraph's changes (the body of ``RenderEngine.view_update``)."""
        began = time.perf_counter()
        try:
            view = self._region_view(context, depsgraph.scene)
            failed = self.latest()[3] is not None  # a failed session starts again from a full build
            updates = [] if self.state is None or failed else sync.classify(depsgraph, self.state)
            if self.state is None or failed or any(update.change is Change.BUILD for update in updates):
                updates = [self._build(depsgraph, view)]
            self.post(updates)
        except Exception as error:  # never let a sync error reach Blender as a crash
            _print_bug(error)
            self._set_error(_message(error))
        finally:
            self.main_thread_seconds.append(time.perf_counter() - began)

    def _build(self, depsgraph, view):
        from .gather import gather_scene, gather_settings

        scene = depsgraph.scene
        description = gather_scene(depsgraph, view=view)
        self.state = sync.snapshot(depsgraph, description)
        self._view = view
        render = scene.scratch_iridescence
        return Update(Change.BUILD, (description, gather_settings(scene), int(render.viewport_samples),
                                     int(render.viewport_start_divisor), bool(render.viewport_freeze)))

    @staticmethod
    def _region_view(context, scene):
        region, region_data = context.region, context.region_data
        camera = view_camera(region_data.view_matrix, region_data.window_matrix, region_data.is_perspective)
        size = (max(1, region.width), max(1, region.height))
        crop = None
        # Camera view with a render border renders only the border, as Cycles does
        if (getattr(region_data, "view_perspective", None) == "CAMERA" and scene.render.use_border
                and scene.camera is not None):
            frame = [scene.camera.matrix_world @ corner for corner in scene.camera.data.view_frame(scene=scene)]
            render = scene.render
            crop = border_crop([tuple(corner) for corner in frame], region_data.view_matrix, region_data.window_matrix,
                               (render.border_min_x, render.border_min_y, render.border_max_x, render.border_max_y),
                               size)
        film = Film(*size, crop=crop, filter=scene.scratch_iridescence.film_filter,
                    transparent=bool(scene.render.film_transparent))
        return camera, film

    def view_changes(self, context, scene) -> list:
        """Updates for a changed view (camera, region size) since the last call."""
        camera, film = view = self._region_view(context, scene)
        if self._view is None:
            return []
        old_camera, old_film = self._view
        updates = []
        if not sync.same(film, old_film):
            updates.append(Update(Change.FILM, (film,)))
        if not sync.same(camera, old_camera):
            updates.append(Update(Change.CAMERA, (camera,)))
        self._view = view
        return updates

    def latest(self):
        """(Progress or None, version, finished, error, stats) of the newest image."""
        with self._lock:
            return self._latest, self._version, self._finished, self._error, dict(self._stats)

    def view_draw(self, engine, context, depsgraph) -> None:
        """Post view changes and draw the newest image (the body of ``RenderEngine.view_draw``)."""
        began = time.perf_counter()
        try:
            scene = depsgraph.scene
            self.post(self.view_changes(context, scene))
            progress, version, finished, error, stats = self.latest()
            if error:
                engine.update_stats("", error)
            elif progress is not None:
                engine.update_stats("", f"Mitsuba | Sample {progress.spp_done}/{progress.spp_total}")
            if progress is not None:
                with self._lock:
                    rect = self._rect
                self.draw(engine, scene, context.region, progress, version, rect)
            if not finished:
                engine.tag_redraw()  # keep drawing while the worker refines
        except Exception as error:  # a drawing error must not end in Blender's face every frame
            if self.draw_error is None:
                traceback.print_exc()
            self.draw_error = f"{type(error).__name__}: {error}"
        finally:
            self.main_thread_seconds.append(time.perf_counter() - began)

    def draw(self, engine, scene, region, progress, version, rect) -> None:
        """Upload (when new) and draw the image with Blender's display transform.

        ``rect`` is ``progress.image`` flipped to rows bottom-up, flat RGBA float32 (the worker makes it,
        so the main thread only copies it into the texture).
        """
        import gpu
        from gpu_extras.presets import draw_texture_2d

        if version != self._texture_version:
            height, width = progress.image.shape[:2]
            pixels = gpu.types.Buffer("FLOAT", rect.size, rect)
            self._texture = gpu.types.GPUTexture((width, height), format="RGBA16F", data=pixels)
            self._texture_version = version
        gpu.state.blend_set("ALPHA_PREMULT")
        engine.bind_display_space_shader(scene)
        with self._lock:
            crop = self._crop
        if crop is None:
            draw_texture_2d(self._texture, (0, 0), region.width, region.height)
        else:  # the render border: at its place, the rest of the region stays the viewport's background
            x, y, w, h = crop
            draw_texture_2d(self._texture, (x, region.height - y - h), w, h)
        engine.unbind_display_space_shader()
        gpu.state.blend_set("NONE")

    def stop(self) -> None:
        """Ask the worker to close the session and end (returns at once; the worker ends after its pass)."""
        with self._lock:
            self._stopping = True
            self._pending = []
            self._lock.notify()

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the worker to end (tests and scripts; the engine never waits). True when it has."""
        if self._thread is not None:
            self._thread.join(timeout)
            return not self._thread.is_alive()
        return True

    def _set_error(self, message: str) -> None:
        with self._lock:
            self._error = message

    # ------------------------------------------------------------------ worker thread
    def _run(self) -> None:
        try:
            self._work()
        finally:
            with _workers_lock:
                _workers.discard((self, threading.current_thread()))

    def _work(self) -> None:
        session, linger, posted = None, False, None
        try:
            while True:
                with self._lock:
                    if linger and not self._pending and not self._stopping:
                        self._lock.wait(LINGER_SECONDS)
                    while not self._stopping and not self._pending and (session is None or session.finished):
                        self._lock.wait()
                    if self._stopping:
                        return
                    todo, self._pending = self._pending, []
                try:
                    with viewport_turn():  # not while F12 renders (turns.py)
                        session = self._apply(session, coalesce(todo))
                        progress = None
                        if session is not None and not session.finished:
                            progress = session.step(0.0)
                            linger = session.showing_preview
                    # a strip of a CPU pass leaves the image as it was: nothing new to convert and post
                    if progress is not None and progress is not posted:
                        posted = progress
                        rect = combined_rect(progress.image, session.description.film.transparent).ravel()
                        with self._lock:
                            self._latest, self._rect, self._version = progress, rect, self._version + 1
                            self._crop = session.description.film.crop
                            self._finished, self._error = session.finished, None
                            self._stats = session.stats
                except Exception as error:
                    _print_bug(error)
                    if session is not None:
                        with viewport_turn():
                            session.close()
                    session = None  # the next posted build starts afresh
                    with self._lock:
                        self._error = _message(error)
                        self._finished = True
        finally:
            if session is not None:
                with viewport_turn():
                    session.close()

    @staticmethod
    def _apply(session, updates):
        for update in updates:
            if update.change is Change.BUILD:
                description, settings, samples, divisor, freeze = update.args
                if session is not None:
                    session.close()
                    session = None
                session = Session(description, settings, samples=samples, start_divisor=divisor, freeze=freeze)
            elif session is not None:
                session.apply(update)
        return session


def _message(error: Exception) -> str:
    if isinstance(error, ImportError):
        return MITSUBA_MISSING.format(error=error)
    if isinstance(error, ScratchUserError):  # the user's to fix (tables that cannot fit): the message says how
        return f"Mitsuba Scratch viewport: {error}"
    return f"Mitsuba Scratch viewport: {type(error).__name__}: {error}"


def _print_bug(error: Exception) -> None:
    """The traceback in the console, unless ``error`` is a user error (shown in the viewport, nothing to debug)."""
    if not isinstance(error, ScratchUserError):
        traceback.print_exception(error)


def stats_of(viewport: ViewportRender) -> dict:
    """Session statistics and main-thread timings (max and median seconds) of a viewport."""
    stats = viewport.latest()[4]
    timings = np.array(viewport.main_thread_seconds) if viewport.main_thread_seconds else np.zeros(1)
    return {**stats, "main_thread_max_s": float(timings.max()), "main_thread_median_s": float(np.median(timings))}
