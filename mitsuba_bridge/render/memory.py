"""Memory a render needs, estimated up front, so that a render too big for the machine is refused
with a number instead of running until the system kills it.

The estimate (:func:`estimate_render_bytes`) is a pure function of the film
size and the schedule:

* **Film:** Mitsuba's image block holds 5 float32 channels per pixel in a
  spectral variant (RGB, alpha, weight) and develops into 4 more (RGBA).
* **Accumulation** (:mod:`mitsuba_bridge.render.schedule`): the chunk's float32 image
  and its float64 contribution, the pairwise sums held (at most
  ⌊log2 chunks⌋ + 1 float64 RGBA images), the float64 total and the float32
  running mean.
* **Samples in flight:** ``pixels × chunk spp`` samples of one ``mi.render``
  call, :data:`BYTES_PER_SAMPLE_IN_FLIGHT` each (sample index and sampler
  state, should the backend store them).

Measured with the LLVM variant at 2048² (scratched plate, one call): about
28 bytes per pixel for the film, against 36 counted here; samples in flight
did not add measurable memory (the path tracer runs as one kernel).
"""
from __future__ import annotations

import os
from dataclasses import dataclass

from .schedule import Chunk

__all__ = ["BYTES_PER_SAMPLE_IN_FLIGHT", "MemoryEstimate", "NotEnoughMemory", "estimate_render_bytes",
           "available_memory_bytes", "check_memory"]

#: Film: 5 float32 channels in the image block + 4 in the developed image.
FILM_BYTES_PER_PIXEL = (5 + 4) * 4
#: Sample index and sampler state of one sample in flight, should the backend materialise them.
BYTES_PER_SAMPLE_IN_FLIGHT = 16
_RGBA_F32, _RGBA_F64 = 4 * 4, 4 * 8


class NotEnoughMemory(RuntimeError):
    """The render would need more memory than is free (the message gives both figures)."""


@dataclass(frozen=True)
class MemoryEstimate:
    film_bytes: int
    accumulation_bytes: int
    samples_bytes: int

    @property
    def total_bytes(self) -> int:
        return self.film_bytes + self.accumulation_bytes + self.samples_bytes


def estimate_render_bytes(width: int, height: int, chunks: list[Chunk]) -> MemoryEstimate:
    """Memory of rendering a ``width`` × ``height`` film with the schedule ``chunks`` (see the module docstring)."""
    pixels = int(width) * int(height)
    held = max(len(chunks), 1).bit_length()  # the most pairwise sums held at once
    accumulation = pixels * (_RGBA_F32 + _RGBA_F64 + held * _RGBA_F64 + _RGBA_F64 + _RGBA_F32)
    in_flight = pixels * max((c.spp for c in chunks), default=1)
    return MemoryEstimate(pixels * FILM_BYTES_PER_PIXEL, accumulation, in_flight * BYTES_PER_SAMPLE_IN_FLIGHT)


def available_memory_bytes() -> int | None:
    """Memory the system can give without swapping (``MemAvailable``), or None where unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _gb(count: int) -> str:
    if count < 1e9:
        return f"{count / 1e6:.1f} MB"
    return f"{count / 1e9:.2f} GB" if count < 1e11 else f"{count / 1e9:.0f} GB"


def check_memory(width: int, height: int, chunks: list[Chunk], available: int | None = None) -> MemoryEstimate:
    """The estimate, or :class:`NotEnoughMemory` when it exceeds ``available`` (default: what is free now)."""
    estimate = estimate_render_bytes(width, height, chunks)
    available = available_memory_bytes() if available is None else available
    if available is not None and estimate.total_bytes > available:
        in_flight = int(width) * int(height) * max((c.spp for c in chunks), default=1)
        raise NotEnoughMemory(
            f"a {width} x {height} render needs about {_gb(estimate.total_bytes)} of memory (film "
            f"{_gb(estimate.film_bytes)}, accumulation {_gb(estimate.accumulation_bytes)}, {in_flight:,} samples "
            f"in flight {_gb(estimate.samples_bytes)}) but only {_gb(available)} is free: lower the resolution "
            "or render a crop region")
    return estimate
