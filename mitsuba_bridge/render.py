"""Progressive rendering: many short ``mi.render`` passes averaged into one image.

Short passes give progress updates, let a caller cancel within one pass and
bound memory (one pass holds ``pixels × pass spp`` samples in flight).  With
Mitsuba's independent sampler every pass is an unbiased estimate, so the
spp-weighted mean of the passes is exactly the image one long render gives.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Iterator

import numpy as np

__all__ = ["Progress", "render_passes", "render_image", "pass_seed", "plan_pass"]

#: Samples in flight per pass; beyond this LLVM and CUDA only use more memory.
MAX_SAMPLES_PER_PASS = 1 << 22


@dataclass(frozen=True)
class Progress:
    """State after one pass; ``image`` is the running mean, (H, W, 4) float32 RGBA, row 0 at the top."""

    index: int
    spp_done: int
    spp_total: int
    seconds: float
    image: np.ndarray

    @property
    def fraction(self) -> float:
        return self.spp_done / self.spp_total

    @property
    def finished(self) -> bool:
        return self.spp_done >= self.spp_total


def pass_seed(seed: int, index: int) -> int:
    """A distinct 32-bit sampler seed per (user seed, pass) pair."""
    return (int(seed) * 0x9E3779B1 + int(index)) & 0xFFFFFFFF


def plan_pass(remaining: int, pixels: int, seconds_per_spp: float | None, pass_seconds: float) -> int:
    """Samples per pixel of the next pass.

    The first pass takes one sample (it also compiles the kernels), later ones
    as many as fit in ``pass_seconds``, rounded down to a power of two so that
    the few distinct pass sizes reuse compiled kernels.
    """
    if seconds_per_spp is None:
        budget = 1
    else:
        budget = int(pass_seconds / max(seconds_per_spp, 1e-9))
    budget = min(budget, remaining, max(1, MAX_SAMPLES_PER_PASS // max(pixels, 1)))
    return 1 << (max(budget, 1).bit_length() - 1)


def render_passes(scene, spp: int, *, seed: int = 0, pass_seconds: float = 1.0) -> Iterator[Progress]:
    """Render ``scene`` with ``spp`` samples per pixel in passes, yielding the mean after each.

    Stop iterating to cancel: no work is left behind.
    """
    import mitsuba as mi

    if spp < 1:
        raise ValueError("spp must be at least 1")
    width, height = (int(c) for c in scene.sensors()[0].film().crop_size())
    total = None
    done, index, seconds_per_spp = 0, 0, None
    start = time.perf_counter()
    while done < spp:
        count = plan_pass(spp - done, width * height, seconds_per_spp, pass_seconds)
        began = time.perf_counter()
        image = np.asarray(mi.render(scene, spp=count, seed=pass_seed(seed, index)), dtype=np.float32)
        elapsed = time.perf_counter() - began
        # The first pass includes kernel compilation, so the second stays short too;
        # from the third on, passes fill ``pass_seconds``.
        seconds_per_spp = elapsed / count
        total = image * count if total is None else total + image * count
        done += count
        index += 1
        yield Progress(index, done, spp, time.perf_counter() - start, total / done)


def render_image(scene, spp: int, *, seed: int = 0) -> np.ndarray:
    """The finished (H, W, 4) image of :func:`render_passes`."""
    progress = None
    for progress in render_passes(scene, spp, seed=seed):
        pass
    return progress.image
