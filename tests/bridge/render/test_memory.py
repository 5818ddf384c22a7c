"""The memory estimate of a render (a pure function) and the refusal when it exceeds what is free."""
import pytest

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
    with pytest.raises(footprint.NotEnoughMemory) as refused:
        footprint.check_memory(10_000, 10_000, chunks, available=8_000_000_000)
    message = str(refused.value)
    assert message.startswith("a 10000 x 10000 render needs about 37.20 GB of memory (film 3.60 GB, "
                              "accumulation 32.00 GB,")
    assert "only 8.00 GB is free" in message and "100,000,000 samples in flight" in message
    assert footprint.check_memory(1920, 1080, schedule.sample_schedule(64, 1920 * 1080),
                                  available=8_000_000_000).total_bytes < 2e9


def test_free_memory_is_known_on_this_machine():
    free = footprint.available_memory_bytes()
    assert free is None or 1e6 < free < 1e15
