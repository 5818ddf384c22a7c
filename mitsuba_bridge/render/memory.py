"""Memory a render needs, estimated up front, so that a render too big for what this process is allowed
(free memory, ``ulimit -v``, a container's cgroup: :mod:`mitsuba_bridge.device.memory`) is refused with
both numbers instead of running until the system kills it.

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

The live viewport's session (:func:`estimate_session_bytes`) holds one film per
sensor (the full frame, the preview, a strip), its float32 running sum and the
image it shows.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..device.memory import MemoryLimit, NotEnoughMemory, check_memory as check_allowed, format_bytes
from .schedule import Chunk

__all__ = ["BYTES_PER_SAMPLE_IN_FLIGHT", "MemoryEstimate", "NotEnoughMemory", "estimate_render_bytes",
           "estimate_session_bytes", "check_memory", "check_session_memory"]

#: Film: 5 float32 channels in the image block + 4 in the developed image.
FILM_BYTES_PER_PIXEL = (5 + 4) * 4
#: Sample index and sampler state of one sample in flight, should the backend materialise them.
BYTES_PER_SAMPLE_IN_FLIGHT = 16
_RGBA_F32, _RGBA_F64 = 4 * 4, 4 * 8


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


def estimate_session_bytes(width: int, height: int, preview_divisor: int = 1, strip_pixels: int = 0) -> int:
    """Memory of an interactive session's films (:mod:`.session`): the frame's, the preview's and a strip's
    film, the running sum, the image shown and the pass read back (float32 RGBA each)."""
    pixels = int(width) * int(height)
    preview = -(-int(width) // max(preview_divisor, 1)) * -(-int(height) // max(preview_divisor, 1)) \
        if preview_divisor > 1 else 0
    strip = min(int(strip_pixels), pixels) if strip_pixels > 0 else 0
    return (pixels + preview + strip) * FILM_BYTES_PER_PIXEL + pixels * 3 * _RGBA_F32


def check_memory(width: int, height: int, chunks: list[Chunk], limit: MemoryLimit | None = None) -> MemoryEstimate:
    """The estimate, or :class:`NotEnoughMemory` when it exceeds what this process is allowed (``limit``;
    default: the smallest limit now, :func:`mitsuba_bridge.device.memory.smallest_limit`)."""
    estimate = estimate_render_bytes(width, height, chunks)
    in_flight = int(width) * int(height) * max((c.spp for c in chunks), default=1)
    check_allowed(estimate.total_bytes, f"a {width} x {height} render",
                  detail=f"film {format_bytes(estimate.film_bytes)}, accumulation "
                         f"{format_bytes(estimate.accumulation_bytes)}, {in_flight:,} samples in flight "
                         f"{format_bytes(estimate.samples_bytes)}",
                  advice="lower the resolution or render a crop region", limit=limit)
    return estimate


def check_session_memory(width: int, height: int, preview_divisor: int = 1, strip_pixels: int = 0,
                         limit: MemoryLimit | None = None) -> int:
    """:func:`estimate_session_bytes`, or :class:`NotEnoughMemory` before any film is allocated."""
    needed = estimate_session_bytes(width, height, preview_divisor, strip_pixels)
    check_allowed(needed, f"a {width} x {height} interactive render", limit=limit,
                  advice="make the viewport smaller or render a border region")
    return needed
