"""Progressive rendering: the chunks of a fixed sample schedule, summed into one image.

Chunks give progress updates, let a caller cancel within one chunk and bound
memory (one chunk holds ``pixels × chunk spp`` samples in flight).  With
Mitsuba's independent sampler, or the stratified ``multijitter`` of each chunk's
own seed, every chunk is an unbiased estimate, so the spp-weighted mean of the
chunks is an unbiased image (:func:`check_sampler` makes sure each chunk renders
the samples it weighs).

The schedule (:func:`~mitsuba_bridge.render.schedule.sample_schedule`) depends only on
spp, the pixel count and the seed, and the chunks are summed in one fixed order
(:class:`~mitsuba_bridge.render.schedule.PairwiseSum`), so the image is the same bit
for bit whatever the machine load.  Time only decides how often a caller shows
the running mean (:class:`Refresh`).
"""
from __future__ import annotations

import dataclasses
import functools
import time
from dataclasses import dataclass
from typing import Iterable, Iterator

import numpy as np

from .interrupts import RenderInterrupted
from .memory import NotEnoughMemory, check_memory
from .schedule import (MAX_SAMPLES_PER_PASS, Chunk, PairwiseSum, ScheduleError, part_range, pass_seed,
                       sample_schedule)

__all__ = ["Progress", "Refresh", "RenderPlan", "plan_render", "check_sampler", "check_film_memory", "render_passes",
           "render_chunks", "render_image",
           "film_pixels", "pass_seed",
           "sample_schedule", "Chunk", "MAX_SAMPLES_PER_PASS", "NotEnoughMemory", "ScheduleError"]


#: How :attr:`Progress.traced_note` begins (``make paper`` finds it in a render's output by it).
TRACED_NOTE_PREFIX = "Mitsuba Scratch: passes traced, not replayed"
TRACED_REASON_CHARS = 300  #: Dr.Jit's recording errors name every variable involved: the start says what failed


@dataclass(frozen=True)
class Progress:
    """State after one chunk.

    ``image`` is the running mean, (H, W, 4) float32 RGBA, row 0 at the top,
    computed when first asked for (a display that refreshes once a second pays
    for one mean a second, not one per chunk) from the sums held after this
    chunk, so it stays right after later chunks.  ``sums`` is the live
    accumulator (its tree nodes are what a part file stores).
    """

    index: int
    spp_done: int
    spp_total: int
    seconds: float
    chunk: Chunk | None = None
    sums: PairwiseSum | None = None
    partials: tuple = ()  #: the sums' partial images after this chunk (never modified in place)
    #: An image that is already the one to show (the interactive session's running mean or preview);
    #: when set, ``image`` is this array and the sums are not used.
    shown: np.ndarray | None = None
    #: Why this render's passes are traced again for every chunk instead of replayed from a recording
    #: (:class:`~mitsuba_bridge.render.freezing.FrozenRender` gave up: a plugin Dr.Jit cannot record); None
    #: while they replay or when freezing was not asked for.  Same image either way, only slower.
    traced_because: str | None = None

    @property
    def fraction(self) -> float:
        return self.spp_done / self.spp_total

    @property
    def finished(self) -> bool:
        return self.spp_done >= self.spp_total

    @property
    def traced_note(self) -> str | None:
        """One line for a console or log when the passes were traced (:attr:`traced_because`), else None."""
        if self.traced_because is None:
            return None
        reason = " ".join(self.traced_because.split())
        reason = reason if len(reason) <= TRACED_REASON_CHARS else reason[:TRACED_REASON_CHARS - 1] + "…"
        return f"{TRACED_NOTE_PREFIX} (same image, slower): {reason}"

    @functools.cached_property
    def image(self) -> np.ndarray:
        if self.shown is not None:
            return self.shown
        # (the sums are Dr.Jit arrays while rendering: folded there, read back once, divided here)
        return (np.asarray(PairwiseSum.fold(self.partials), dtype=np.float64) / self.spp_done).astype(np.float32)


class Refresh:
    """Says when a caller should show the running image again: at most every ``seconds``, and at the end.

    Only the display depends on it; the image itself never depends on time.
    """

    def __init__(self, seconds: float = 1.0):
        self.seconds = float(seconds)
        self._last: float | None = None

    def due(self, progress: Progress) -> bool:
        now = time.perf_counter()
        if progress.finished or self._last is None or now - self._last >= self.seconds:
            self._last = now
            return True
        return False


def film_pixels(scene) -> int:
    """Pixels of the scene's film (its crop window)."""
    width, height = (int(c) for c in scene.sensors()[0].film().crop_size())
    return width * height


def render_chunks(scene, chunks: Iterable[Chunk], spp_total: int, *, freeze: bool = True,
                  overlap: bool | None = None, render_spp: int | None = None) -> Iterator[Progress]:
    """Render the given ``chunks`` (consecutive ones of a schedule) in order and yield the running mean after each.

    ``spp_total`` is the sum of their spp (for ``fraction``); ``render_spp`` the whole render's samples per
    pixel where these chunks are a part of it (default ``spp_total``): the scratch BSDFs' footprint filter is
    sized for it (:func:`.filtering.set_footprint`), so parts average as the whole render does.  Stop iterating to
    cancel: no work is left behind but, with ``overlap``, the one pass already
    launched.  ``freeze``: record the first chunk of each
    size with ``dr.freeze`` and replay it for the others
    (:class:`~mitsuba_bridge.render.freezing.FrozenRender`: the same kernels, so the
    same image bit for bit, without tracing the integrator and the Python BSDF
    again for every chunk); a scene that cannot be recorded renders traced, and
    every later :attr:`Progress.traced_because` says why.  ``overlap`` (default: on a
    GPU variant: CUDA or Metal) launches the next chunk as soon as this one's image is on the host, so the
    GPU renders while the host adds the image to the sums and the caller shows it; the
    same images bit for bit (the launch only moves earlier).  Off on the CPU, where both
    would share the same cores.
    """
    from .filtering import set_footprint
    from .freezing import FrozenRender
    from ..device.variants import on_gpu

    chunks = list(chunks)
    indices = [chunk.index for chunk in chunks]
    if indices and indices != list(range(indices[0], indices[0] + len(indices))):
        raise ValueError("render_chunks needs consecutive chunks of one schedule (the sums follow their indices)")
    # the footprint filter's size follows the whole render's samples, never a chunk's (docs/model.md §11.2)
    set_footprint(scene, spp_total if render_spp is None else render_spp)
    if overlap is None:
        overlap = on_gpu()
    passes = FrozenRender(enabled=freeze)
    sums, done, start = PairwiseSum(chunks[0].index if chunks else 0), 0, time.perf_counter()
    launched = None  # the next chunk's image, already launched (overlap)
    for number, chunk in enumerate(chunks, start=1):
        result = launched if launched is not None else passes(scene, 0, chunk.spp, chunk.seed)
        sums.add(_contribution(result, chunk.spp))
        del result
        _finish(sums.partials())  # this chunk's kernels, its contribution and the sums it joined
        if scene.integrator().should_stop():  # a SIGINT while a traced or recorded pass ran (render_whole)
            raise RenderInterrupted("Mitsuba stopped the render early (interrupted)")
        launched = passes(scene, 0, chunks[number].spp, chunks[number].seed) \
            if overlap and number < len(chunks) else None
        done += chunk.spp
        yield Progress(number, done, spp_total, time.perf_counter() - start, chunk, sums, sums.partials(),
                       traced_because=passes.failure)


def _contribution(image, spp: int):
    """A chunk's ``float64(image) × spp`` as a Dr.Jit tensor, not yet evaluated.

    Exact (a float32 times an integer below 2**29 fits in a float64), so the
    same bits as NumPy's; the only rounding is in the fixed-order sums
    (:class:`PairwiseSum`, whose adds are Dr.Jit's too while the values are
    Dr.Jit arrays: IEEE float64 additions, the same bits as NumPy's).  Kept on
    the device, the sums cost the host nothing per chunk: reading every chunk's
    image back and adding it with NumPy (~10 ms at 720 × 450) left the
    render's worker threads spinning idle meanwhile (docs/rendering.md, What a
    chunk's size costs).  The image comes to the host only when it is shown.
    """
    import drjit as dr

    return dr.float64_array_t(type(image))(image) * float(spp)


def _finish(values) -> None:
    """Evaluate ``values`` (Dr.Jit arrays) and wait until they are computed."""
    import drjit as dr

    dr.eval(*values)
    dr.sync_thread()


@dataclass(frozen=True)
class RenderPlan:
    """What a render of a loaded scene will do: its film, its whole sample schedule and the chunks run here.

    ``chunks`` is :func:`sample_schedule` ``(spp, pixels, seed)`` (its GPU schedule on a GPU variant, CUDA or Metal);
    ``selected`` is all of it, or one part of a render split over machines (:meth:`part`), whose sums
    ``merge`` combines bit for bit.
    """

    width: int
    height: int
    spp: int
    seed: int
    chunks: list
    selected: list

    @property
    def samples(self) -> int:
        """Samples per pixel of the selected chunks."""
        return sum(chunk.spp for chunk in self.selected)

    def part(self, part: int, parts: int) -> "RenderPlan":
        """Part ``part`` (1-based) of ``parts`` of this render (:func:`~mitsuba_bridge.render.schedule.part_range`;
        its :class:`~mitsuba_bridge.render.schedule.ScheduleError` for impossible parts)."""
        run = part_range(part, parts, len(self.chunks))
        return dataclasses.replace(self, selected=self.chunks[run.start:run.stop])

    def check_memory(self):
        """The memory estimate of the selected chunks; raises :class:`NotEnoughMemory` when it does not fit."""
        return check_memory(self.width, self.height, self.selected)


def plan_render(scene, spp: int, *, seed: int = 0) -> RenderPlan:
    """The :class:`RenderPlan` of ``scene`` at ``spp`` samples per pixel, every chunk selected.

    Raises :class:`~mitsuba_bridge.render.schedule.ScheduleError` (a ``ValueError``) for impossible counts and for
    a sampler that would render other counts than the schedule's (:func:`check_sampler`).
    """
    from ..device.variants import on_gpu

    if spp < 1:
        raise ValueError("spp must be at least 1")
    width, height = (int(c) for c in scene.sensors()[0].film().crop_size())
    chunks = sample_schedule(spp, width * height, seed, gpu=on_gpu())
    check_sampler(scene, chunks)
    return RenderPlan(width, height, spp, seed, chunks, chunks)


def check_sampler(scene, chunks) -> None:
    """Raise :class:`~mitsuba_bridge.render.schedule.ScheduleError` when the scene's sampler would not render
    a chunk's spp as it is (Mitsuba's stratified samplers round counts up: ``ldsampler`` makes 1 spp 4), since
    the chunk's image is weighed by its spp.  The renderer writes only samplers that take every size of a schedule
    (:data:`~mitsuba_bridge.render.schedule.SAMPLER_SIZES`); a hand-written scene.xml may hold another."""
    sampler = scene.sensors()[0].sampler()
    for spp in sorted({chunk.spp for chunk in chunks}):
        probe = sampler.clone()
        probe.set_sample_count(spp)
        if int(probe.sample_count()) != spp:
            raise ScheduleError(f"the scene's sampler ({sampler.class_name()}) renders {int(probe.sample_count())} spp "
                                f"where a chunk of this render takes {spp}: use the independent or multijitter sampler")


def check_film_memory(width: int, height: int, spp: int, seed: int = 0):
    """The memory estimate of a ``width`` × ``height`` render at ``spp`` (the active variant's schedule), before any
    scene is loaded or image allocated; :class:`NotEnoughMemory` when it does not fit what is allowed."""
    from ..device.variants import on_gpu

    return check_memory(width, height, sample_schedule(spp, int(width) * int(height), seed, gpu=on_gpu()))


def render_passes(scene, spp: int, *, seed: int = 0) -> Iterator[Progress]:
    """Render ``scene`` with ``spp`` samples per pixel chunk by chunk, yielding the running mean after each.

    The chunks are :func:`plan_render`'s.  Stop iterating to cancel: no work is left behind.  Raises
    :class:`~mitsuba_bridge.render.memory.NotEnoughMemory` (before rendering) when the estimated memory
    exceeds what is free.
    """
    plan = plan_render(scene, spp, seed=seed)
    plan.check_memory()  # before any film is allocated
    return render_chunks(scene, plan.chunks, plan.spp, render_spp=plan.spp)


def render_image(scene, spp: int, *, seed: int = 0) -> np.ndarray:
    """The finished (H, W, 4) float32 image of :func:`render_passes` (the same bits on every run)."""
    progress = None
    for progress in render_passes(scene, spp, seed=seed):
        pass
    return progress.image
