"""Progressive passes: planning, seeds, and the running mean."""
import numpy as np
import pytest

from bridge_scenes import simple_scene
from scratch_iridescence.mitsuba_bridge import builder, render
from scratch_iridescence.mitsuba_bridge import scene as S


def test01_first_pass_takes_one_sample_then_passes_fill_the_target_time():
    assert render.plan_pass(100, 1000, None, 1.0) == 1
    assert render.plan_pass(100, 1000, 0.1, 1.0) == 8      # 10 fit: largest power of two below
    assert render.plan_pass(5, 1000, 0.001, 1.0) == 4      # never more than what remains
    assert render.plan_pass(100, 1000, 10.0, 1.0) == 1     # slow passes still take a sample


def test02_passes_are_bounded_by_memory_on_big_images():
    pixels = 1024 * 1024
    assert render.plan_pass(1024, pixels, 1e-9, 1.0) * pixels == render.MAX_SAMPLES_PER_PASS
    assert render.plan_pass(1024, 4096 * 4096, 1e-9, 1.0) == 1  # one sample per pass at least


def test03_pass_seeds_differ_across_passes_and_user_seeds():
    seeds = {render.pass_seed(seed, index) for seed in range(20) for index in range(200)}
    assert len(seeds) == 20 * 200
    assert all(0 <= s < 2 ** 32 for s in seeds)


@pytest.fixture(scope="module")
def lit_scene(variant):
    description = simple_scene(lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    return builder.load_scene(description, S.RenderSettings())


def test04_passes_add_up_to_the_requested_samples_and_report_progress(lit_scene):
    steps = list(render.render_passes(lit_scene, 37, pass_seconds=0.01))
    assert steps[-1].spp_done == 37 and steps[-1].finished
    assert [p.spp_done for p in steps] == sorted({p.spp_done for p in steps})
    assert steps[0].fraction == pytest.approx(1 / 37)
    assert steps[-1].image.shape == (24, 32, 4) and steps[-1].image.dtype == np.float32


def test05_running_mean_is_the_spp_weighted_mean_of_the_passes(lit_scene, monkeypatch):
    import mitsuba as mi

    calls = []
    original = mi.render

    def spy(scene, spp, seed):
        image = original(scene, spp=spp, seed=seed)
        calls.append((spp, np.asarray(image)))
        return image

    monkeypatch.setattr(mi, "render", spy)
    final = list(render.render_passes(lit_scene, 13, pass_seconds=0.01))[-1].image
    expected = sum(spp * image for spp, image in calls) / sum(spp for spp, _ in calls)
    assert np.allclose(final, expected, atol=1e-6)
    assert len({seed for seed in range(len(calls))}) == len(calls)


def test06_more_samples_reduce_the_noise(lit_scene):
    reference = render.render_image(lit_scene, 512, seed=99)[..., :3]
    error = [np.abs(render.render_image(lit_scene, spp, seed=1)[..., :3] - reference).mean() for spp in (1, 64)]
    assert error[1] < 0.5 * error[0]


def test07_stopping_the_iteration_cancels_without_rendering_further(lit_scene, monkeypatch):
    import mitsuba as mi

    count = []
    original = mi.render
    monkeypatch.setattr(mi, "render", lambda *a, **k: (count.append(1), original(*a, **k))[1])
    for progress in render.render_passes(lit_scene, 10_000, pass_seconds=0.01):
        if progress.index == 2:
            break
    assert len(count) == 2
