"""Progressive rendering: the fixed sample schedule, its summation tree, and the running mean."""
import time

import numpy as np
import pytest

from bridge_scenes import interrupting_scene, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge.render import freezing, interrupts, passes as render, schedule
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.device.variants import on_gpu


def spy_on_chunks(monkeypatch, around):
    """Route every chunk's render call (frozen or traced: ``FrozenRender.__call__``) through
    ``around(render_call, spp, seed)``."""
    original = freezing.FrozenRender.__call__

    def spied(self, scene, sensor, spp, seed):
        return around(lambda: original(self, scene, sensor, spp, seed), spp, seed)

    monkeypatch.setattr(freezing.FrozenRender, "__call__", spied)


def test01_schedule_adds_up_to_spp_in_chunks_the_samplers_take_within_the_memory_bound():
    for spp in (1, 7, 64, 100, 1000, 4097):
        for pixels in (1, 768, 512 * 512, 1920 * 1080, 10_000 ** 2):
            chunks = schedule.sample_schedule(spp, pixels, seed=3)
            sizes = [c.spp for c in chunks]
            assert sum(sizes) == spp and [c.index for c in chunks] == list(range(len(chunks)))
            assert all(size & (size - 1) == 0 for size in sizes)  # powers of two
            assert set(sizes) <= schedule.SAMPLER_SIZES  # none that multijitter rounds (test_sampler.py)
            assert sizes == sorted(sizes, reverse=True)
            assert all(size * pixels <= max(schedule.MAX_SAMPLES_PER_PASS, pixels) for size in sizes)
            assert set(sizes) <= {sizes[0], 4, 2, 1}  # at most four compiled kernels
            # One pixel, one thread: small chunks, or whole Dr.Jit blocks of a call large for 64 threads.
            assert all(size <= 4 or (16384 % size == 0 and pixels * size > 16384 * 2 * 64) for size in sizes)
    assert [c.spp for c in schedule.sample_schedule(100, 512 * 512)] == [16] * 6 + [4]  # 32 would round to 35
    assert [c.spp for c in schedule.sample_schedule(100, 1024 * 1024)] == [8] * 12 + [4]
    assert [c.spp for c in schedule.sample_schedule(256, 720 * 450)] == [16] * 16  # a SIMD packet per pixel
    assert [c.spp for c in schedule.sample_schedule(64, 320 * 200)] == [64]
    assert [c.spp for c in schedule.sample_schedule(8192 + 67, 32 * 24)] == [4096] * 2 + [4] * 16 + [2, 1]
    assert [c.spp for c in schedule.sample_schedule(64, 2 * 2)] == [4] * 16  # a tiny film: small chunks only
    assert schedule.sample_schedule(5, 4096 * 4096) == schedule.sample_schedule(5, 4096 * 4096)


def test01b_the_gpu_schedule_keeps_a_pixel_in_one_warp():
    """On a GPU full chunks take at most 32 spp (one warp; docs/rendering.md), 16 being the most of those the
    stratified sampler takes; large films keep their chunks."""
    for spp in (1, 7, 64, 100, 1000, 4097):
        for pixels in (1, 768, 512 * 512, 1920 * 1080, 10_000 ** 2):
            sizes = [c.spp for c in schedule.sample_schedule(spp, pixels, seed=3, gpu=True)]
            assert sum(sizes) == spp and sizes == sorted(sizes, reverse=True)
            assert all(size & (size - 1) == 0 and size <= schedule.GPU_CHUNK_SPP for size in sizes)
            assert all(size * pixels <= max(schedule.MAX_SAMPLES_PER_PASS, pixels) for size in sizes)
            assert set(sizes) <= {sizes[0], 4, 2, 1}
            if pixels >= 512 * 512:  # chunks of 16 spp or fewer: the CPU's schedule
                assert sizes == [c.spp for c in schedule.sample_schedule(spp, pixels, seed=3)]
    assert [c.spp for c in schedule.sample_schedule(4096 + 67, 32 * 24, gpu=True)] == [16] * 260 + [2, 1]
    assert [c.spp for c in schedule.sample_schedule(64, 2 * 2, gpu=True)] == [16] * 4


def test02_schedule_refuses_what_cannot_be_rendered():
    with pytest.raises(ValueError, match="spp must be at least 1"):
        schedule.sample_schedule(0, 100)
    with pytest.raises(ValueError, match="at least one pixel"):
        schedule.sample_schedule(4, 0)
    with pytest.raises(schedule.ScheduleError, match="2,000,000,000 spp over 4 pixels would take 500,000,000"):
        schedule.sample_schedule(2_000_000_000, 2 * 2)  # Blender's Samples field allows it; refused at once
    assert len(schedule.sample_schedule(4_000_000, 32 * 24)) == 976 + 576  # 976 x 4096 + 576 x 4 spp


def test03_chunk_seeds_differ_across_chunks_and_user_seeds():
    seeds = {render.pass_seed(seed, index) for seed in range(20) for index in range(200)}
    assert len(seeds) == 20 * 200
    assert all(0 <= s < 2 ** 32 for s in seeds)
    assert [c.seed for c in schedule.sample_schedule(64, 2 * 10 ** 6, seed=7)] == [
        render.pass_seed(7, i) for i in range(16)]


def test04_parts_cover_the_schedule_and_their_tree_nodes_sum_to_the_single_machine_total_bit_for_bit():
    rng = np.random.default_rng(0)
    for count in range(1, 41):
        # Values spanning many magnitudes (glints beside dark pixels) make float64 rounding order-dependent.
        leaves = rng.random((count, 5)) * 10.0 ** rng.integers(-8, 8, (count, 5))
        sums = schedule.PairwiseSum()
        for leaf in leaves:
            sums.add(leaf)
        whole = sums.total()
        assert whole.tobytes() == schedule.tree_sum(schedule.root(count), count,
                                                    lambda n: leaves[n.index] if n.level == 0 else None).tobytes()
        for parts in range(1, count + 1):
            stored = {}
            for part in range(1, parts + 1):
                run = schedule.part_range(part, parts, count)
                part_sums = schedule.PairwiseSum(start=run.start)
                for index in run:
                    part_sums.add(leaves[index])
                nodes = part_sums.node_sums(count)
                covered = sorted(i for n in nodes for i in range(n.start, min(n.stop, count)))
                assert covered == list(run)
                for node, value in nodes.items():  # a part computes its nodes as the tree does
                    tree = schedule.tree_sum(node, count, lambda n: leaves[n.index] if n.level == 0 else None)
                    assert value.tobytes() == tree.tobytes()
                stored.update(nodes)
            merged = schedule.tree_sum(schedule.root(count), count, stored.get)
            assert merged.tobytes() == whole.tobytes(), (count, parts)


def test04b_sums_kept_as_dr_jit_arrays_are_the_numpy_sums_bit_for_bit(variant):
    """A render keeps its chunks' contributions on the device (``render._contribution``, Dr.Jit float64):
    the same tree of IEEE additions, so the same bits as NumPy's, totals and a part's nodes alike."""
    import mitsuba as mi

    rng = np.random.default_rng(1)
    count, spps = 13, [16] * 12 + [4]
    # float32 images spanning many magnitudes, as chunk images are (glints beside dark pixels)
    images = (rng.random((count, 3, 5, 4)) * 10.0 ** rng.integers(-6, 6, (count, 3, 5, 4))).astype(np.float32)
    on_host, on_device = schedule.PairwiseSum(), schedule.PairwiseSum()
    for image, spp in zip(images, spps):
        on_host.add(np.multiply(image, float(spp), dtype=np.float64))
        on_device.add(render._contribution(mi.TensorXf(image), spp))
    assert type(on_device.partials()[0]).__name__.startswith("TensorXf64")  # kept on the device
    assert on_device.total().tobytes() == on_host.total().tobytes()
    host_nodes, device_nodes = on_host.node_sums(count), on_device.node_sums(count)
    assert list(device_nodes) == list(host_nodes)
    assert all(device_nodes[n].tobytes() == host_nodes[n].tobytes() for n in host_nodes)


def test05_parts_split_at_most_into_as_many_as_there_are_chunks():
    assert list(schedule.part_range(2, 3, 10)) == [3, 4, 5]
    with pytest.raises(ValueError, match="at most 2 parts, not 3"):
        schedule.part_range(1, 3, 2)
    with pytest.raises(ValueError, match="1 <= part <= 3"):
        schedule.part_range(4, 3, 10)


@pytest.fixture(scope="module")
def lit_scene(variant):
    description = simple_scene(lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    return builder.load_scene(description, S.RenderSettings())


def test06_chunks_add_up_to_the_requested_samples_and_report_progress(lit_scene):
    steps = list(render.render_passes(lit_scene, 37))
    sizes = [c.spp for c in schedule.sample_schedule(37, 32 * 24, gpu=on_gpu())]
    assert sizes == ([16, 16, 4, 1] if on_gpu() else [4] * 9 + [1])  # the GPU's schedule; the CPU's small film
    first = sizes[0]
    assert [p.spp_done for p in steps] == list(np.cumsum(sizes)) and steps[-1].finished
    assert steps[0].fraction == pytest.approx(first / 37)
    assert steps[-1].image.shape == (24, 32, 4) and steps[-1].image.dtype == np.float32


def test07_running_mean_is_the_spp_weighted_mean_of_the_chunks(lit_scene, monkeypatch):
    calls = []

    def record(render_call, spp, seed):
        image = render_call()
        calls.append((spp, seed, np.asarray(image)))
        return image

    spy_on_chunks(monkeypatch, record)
    steps = list(render.render_passes(lit_scene, 13, seed=4))
    final = steps[-1].image
    assert np.array_equal(steps[0].image, calls[0][2])  # an early mean, asked for late, is still that chunk's
    expected = sum(spp * image for spp, _, image in calls) / sum(spp for spp, _, _ in calls)
    assert np.allclose(final, expected, atol=1e-6)
    assert [(spp, seed) for spp, seed, _ in calls] == [(c.spp, c.seed)
                                                       for c in schedule.sample_schedule(13, 32 * 24, 4)]


def test08_more_samples_reduce_the_noise(lit_scene):
    reference = render.render_image(lit_scene, 512, seed=99)[..., :3]
    error = [np.abs(render.render_image(lit_scene, spp, seed=1)[..., :3] - reference).mean() for spp in (1, 64)]
    assert error[1] < 0.5 * error[0]


def test09_stopping_the_iteration_cancels_without_rendering_further(lit_scene, monkeypatch):
    count = []
    spy_on_chunks(monkeypatch, lambda render_call, spp, seed: (count.append(1), render_call())[1])
    for progress in render.render_passes(lit_scene, 100_000):
        if progress.index == 2:
            break
    assert len(count) == (3 if on_gpu() else 2)  # on a GPU chunk 3 is already launched (overlap, test11b)


def test10_a_tiny_film_renders_the_same_bits_every_time(variant):
    """One pixel at 256 spp: one call would split the pixel's samples between threads, whose atomic adds
    land in any order under load (measured: 4 different images in 4 single calls at 4 x 4 pixels x 65 536
    spp); the schedule's 4-spp chunks keep each pixel in one thread."""
    description = simple_scene(film=S.Film(1, 1), lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    scene = builder.load_scene(description, S.RenderSettings())
    images = {render.render_image(scene, 256, seed=5).tobytes() for _ in range(3)}
    assert len(images) == 1


def test11_the_image_is_the_same_bit_for_bit_whatever_the_timing(lit_scene, monkeypatch):
    """Slow and uneven chunks (a busy machine) and a display refreshed at other moments change nothing."""
    spp = 4096 + 7  # several chunks of several sizes
    quiet = render.render_image(lit_scene, spp, seed=11)
    delays = np.random.default_rng(1)

    def busy(render_call, spp, seed):
        time.sleep(delays.uniform(0, 0.05))
        return render_call()

    spy_on_chunks(monkeypatch, busy)
    refresh, shown = render.Refresh(0.02), []
    for progress in render.render_passes(lit_scene, spp, seed=11):
        if refresh.due(progress):
            shown.append(progress.spp_done)
    assert shown[-1] == spp
    assert progress.image.tobytes() == quiet.tobytes()


def test11b_overlapped_chunks_give_the_same_image_and_leave_one_pass_in_flight_when_stopped(lit_scene, monkeypatch):
    """``overlap`` (the GPU's default) launches chunk k + 1 once chunk k's image is on the host: the same
    images bit for bit; stopping after chunk 2 has launched chunk 3 and nothing more, and a render after
    that is unharmed."""
    chunks = schedule.sample_schedule(4096 + 7, 32 * 24, 3, gpu=on_gpu())
    plain = [p.image for p in render.render_chunks(lit_scene, chunks, 4096 + 7, overlap=False)]
    overlapped = [p.image for p in render.render_chunks(lit_scene, chunks, 4096 + 7, overlap=True)]
    assert len(overlapped) == len(plain) > 3
    assert all(a.tobytes() == b.tobytes() for a, b in zip(plain, overlapped))

    count = []
    spy_on_chunks(monkeypatch, lambda render_call, spp, seed: (count.append(1), render_call())[1])
    for progress in render.render_chunks(lit_scene, chunks, 4096 + 7, overlap=True):
        if progress.index == 2:
            break
    assert len(count) == 3
    after = list(render.render_chunks(lit_scene, chunks, 4096 + 7, overlap=True))[-1].image
    assert after.tobytes() == plain[-1].tobytes()


def test12_chunks_must_be_consecutive():
    chunks = schedule.sample_schedule(37, 32 * 24)
    with pytest.raises(ValueError, match="consecutive chunks"):
        next(render.render_chunks(None, [chunks[0], chunks[2]], 8))


def test13_a_render_mitsuba_stopped_early_never_reaches_the_image(variant):
    """Mitsuba's SIGINT handler cancels the integrator, and a process that ignores SIGINT never hears of it:
    ``should_stop()`` is what tells. The integrator's ``timeout`` sets the same flag, deterministically."""
    import mitsuba as mi

    scene = builder.load_scene(simple_scene(world=S.ConstantWorld((0.5, 0.5, 0.5))), S.RenderSettings())
    assert np.asarray(interrupts.render_whole(scene, spp=1, seed=0)).shape == (24, 32, 4)
    stopped = mi.load_dict({"type": "scene", "integrator": {"type": "path", "timeout": 1e-9},
                            "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}},
                            "world": {"type": "constant"}})
    with pytest.raises(interrupts.RenderInterrupted, match="stopped the render early"):
        interrupts.render_whole(stopped, spp=1, seed=0)
    with pytest.raises(KeyboardInterrupt):  # the CLI's Ctrl-C path: "interrupted: nothing was written", 130
        list(render.render_passes(stopped, 8))


def test14_ctrl_c_inside_a_python_plugin_is_an_interruption_not_a_failure(variant):
    """A SIGINT that arrives while Mitsuba traces a Python plugin raises ``KeyboardInterrupt`` inside
    ``dr.custom``, which hands it on as a ``RuntimeError``: the CLI must still say "interrupted" (exit 130),
    not "rendering failed". The plugin sends itself a real SIGINT, so the moment is deterministic."""
    with interrupting_scene() as scene:
        with pytest.raises(interrupts.RenderInterrupted) as caught:
            interrupts.render_whole(scene, spp=1, seed=0)
        assert interrupts.interruption_in(caught.value.__cause__)
        with pytest.raises(KeyboardInterrupt):  # render_passes hands it on to the CLI's Ctrl-C path
            list(render.render_passes(scene, 4))
        del scene, caught
    assert not interrupts.interruption_in(RuntimeError("a plugin failed: KeyboardInterrupt"))
    plain = builder.load_scene(simple_scene(world=S.ConstantWorld((0.5, 0.5, 0.5))), S.RenderSettings())
    assert np.asarray(interrupts.render_whole(plain, spp=1, seed=0)).shape == (24, 32, 4)  # nothing lingers
