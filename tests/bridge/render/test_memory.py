"""The memory estimate of a render (a pure function) and the refusal when it exceeds what is allowed (the limits
themselves: tests/bridge/device/test_memory.py)."""
import pytest

from scratch_iridescence.mitsuba_bridge.device.memory import MemoryLimit
from scratch_iridescence.mitsuba_bridge.errors import ScratchUserError
from scratch_iridescence.mitsuba_bridge.render import memory as footprint, schedule


def test_the_estimate_counts_film_accumulation_and_samples_in_flight():
    chunks = schedule.sample_schedule(64, 10_000 * 10_000)  # one sample per chunk: 64 chunks
    estimate = footprint.estimate_render_bytes(10_000, 10_000, chunks)
    pixels = 10 ** 8
    assert estimate.film_bytes == pixels * 36                      # 5 + 4 float32 channels
    assert estimate.accumulation_bytes == pixels * (16 + 32 + 7 * 32 + 32 + 16)  # 7 = pairwise sums held for 64
    assert estimate.samples_bytes == pixels * 1 * 16
    assert estimate.total_bytes == 3.6e9 + 32e9 + 1.6e9


def test_more_samples_per_chunk_mean_more_samples_in_flight():
    small = footprint.estimate_render_bytes(256, 256, schedule.sample_schedule(64, 256 * 256))
    assert small.samples_bytes == 256 * 256 * 64 * 16  # 64 spp fit in one chunk at 256²
    assert small.total_bytes < 200e6


def test_a_render_that_does_not_fit_is_refused_with_both_figures():
    chunks = schedule.sample_schedule(64, 10_000 * 10_000)
    cgroup = MemoryLimit(8 * 2 ** 30, "cgroup v2 memory.max 8.0 GiB of /farm, 0.0 MiB in use")
    with pytest.raises(footprint.NotEnoughMemory) as refused:
        footprint.check_memory(10_000, 10_000, chunks, limit=cgroup)
    message = str(refused.value)
    assert message.startswith("a 10000 x 10000 render needs about 34.6 GiB of memory (film 3.4 GiB, "
                              "accumulation 29.8 GiB,")
    assert "but only 8.0 GiB is allowed (cgroup v2 memory.max 8.0 GiB of /farm" in message
    assert "100,000,000 samples in flight" in message and message.endswith("render a crop region")
    assert isinstance(refused.value, MemoryError) and isinstance(refused.value, ScratchUserError)
    assert footprint.check_memory(1920, 1080, schedule.sample_schedule(64, 1920 * 1080),
                                  limit=cgroup).total_bytes < 2e9


def test_an_interactive_session_s_films_are_estimated_too():
    assert footprint.estimate_session_bytes(100, 50) == 5000 * (36 + 48)
    assert footprint.estimate_session_bytes(100, 50, preview_divisor=4, strip_pixels=1000) == \
        (5000 + 25 * 13 + 1000) * 36 + 5000 * 48
    with pytest.raises(footprint.NotEnoughMemory, match=r"a 100000 x 100000 interactive render needs about "
                                                        r"782.3 GiB of memory but only 16.0 GiB is allowed \(free"):
        footprint.check_session_memory(100_000, 100_000, limit=MemoryLimit(2 ** 34, "free memory, MemAvailable"))
