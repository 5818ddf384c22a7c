"""The render's sampler: ``independent`` by default, the stratified ``multijitter`` by choice; every chunk of the
schedule renders exactly its samples, the setting travels through scene.xml, and the stratified one is less
noisy seed to seed (docs/rendering.md, The sampler)."""
import numpy as np
import pytest

from bridge_scenes import diffuse_scene, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.cli.main import main
from scratch_iridescence.mitsuba_bridge.folder import export
from scratch_iridescence.mitsuba_bridge.render import passes, schedule


def test01_every_schedule_size_is_one_each_sampler_takes_as_it_is(variant):
    """Mitsuba's own rounding (``set_sample_count``) leaves every size a schedule can hold alone, for both samplers,
    and rounds the sizes the schedule avoids (``multijitter`` makes 32 spp 35 or 36)."""
    import mitsuba as mi

    for name in S.SAMPLERS:
        sampler = mi.load_dict({"type": name})
        for size in schedule.SAMPLER_SIZES:
            sampler.set_sample_count(size)
            assert sampler.sample_count() == size, (name, size)
    multijitter = mi.load_dict({"type": "multijitter"})
    multijitter.set_sample_count(32)
    assert multijitter.sample_count() != 32  # why the schedule avoids 32
    for spp in (1, 3, 31, 64, 100, 1000, 8192 + 67):
        for pixels in (1, 768, 320 * 200, 512 * 512, 720 * 450, 1920 * 1080):
            for gpu in (False, True):
                assert {c.spp for c in schedule.sample_schedule(spp, pixels, gpu=gpu)} <= schedule.SAMPLER_SIZES


def test02_the_sampler_is_written_into_scene_xml_and_read_back(variant, tmp_path):
    description = simple_scene(world=S.ConstantWorld((0.5, 0.5, 0.5)))
    assert S.RenderSettings().sampler == "independent"
    for name, mitsuba_class in (("multijitter", "MultijitterSampler"), ("independent", "IndependentSampler")):
        scene_file = export.export_folder(description, S.RenderSettings(spp=16, seed=5, sampler=name),
                                          tmp_path / name)
        assert f'<sampler type="{name}"' in scene_file.read_text()
        sampler = export.load_folder(tmp_path / name).sensors()[0].sampler()
        assert (sampler.class_name(), sampler.sample_count()) == (mitsuba_class, 16)
        assert builder.load_scene(description, S.RenderSettings(sampler=name)).sensors()[0].sampler().class_name() \
            == mitsuba_class  # F12 and the viewport build it alike
    with pytest.raises(ValueError, match="sampler must be one of multijitter, independent, got 'ldsampler'"):
        S.RenderSettings(sampler="ldsampler")


def test03_a_sampler_that_would_round_a_chunk_is_refused_with_one_line(variant, tmp_path, capsys):
    """A hand-edited scene.xml with Mitsuba's ``ldsampler`` (1 and 2 spp become 4): the render would weigh a chunk
    by samples it did not render, so the command line refuses it before rendering."""
    scene_file = export.export_folder(simple_scene(world=S.ConstantWorld((0.5, 0.5, 0.5))), S.RenderSettings(spp=4),
                                      tmp_path / "scene")
    scene_file.write_text(scene_file.read_text().replace('type="independent"', 'type="ldsampler"'))
    status = main(["render", str(tmp_path / "scene"), "-o", str(tmp_path / "out.exr"), "--spp", "5", "-q",
                   "--variant", "llvm_ad_spectral"])
    err = capsys.readouterr().err.strip()
    assert status == 2 and "\n" not in err and not (tmp_path / "out.exr").exists()
    assert "sampler (LowDiscrepancySampler) renders 4 spp where a chunk of this render takes 1" in err


def seed_noise(scene, spp: int, seeds=(1, 2), *, one_chunk=False):
    """Per-pixel squared seed-to-seed differences (RGB summed) and the two images: rendered through the schedule,
    or (``one_chunk``) as one chunk of ``spp``, the schedule's chunk of a larger film (64 spp at 320 × 200)."""
    def image(seed):
        if one_chunk:
            return list(passes.render_chunks(scene, [schedule.Chunk(0, spp, seed)], spp))[-1].image
        return passes.render_image(scene, spp, seed=seed)

    first, second = (np.asarray(image(seed), dtype=np.float64)[..., :3] for seed in seeds)
    return ((second - first) ** 2).sum(axis=-1).ravel(), first, second


def test04_the_stratified_sampler_is_less_noisy_seed_to_seed_and_unbiased(variant):
    """The diffuse scene of ``bench_sampler.py`` at 64 × 40 pixels and 16 spp (the schedule's 4-spp chunks): the
    mean squared difference between two seeds, over pixels, is lower with ``multijitter`` than with ``independent``
    by more than 5 standard errors of that difference (pixels as independent draws), and the two samplers' image
    means agree within 5 standard errors (no bias)."""
    description = diffuse_scene(S.Film(64, 40))
    noise, means = {}, {}
    for name in S.SAMPLERS:
        squared, first, second = seed_noise(builder.load_scene(description, S.RenderSettings(sampler=name)), 16)
        noise[name] = squared.mean(), squared.std() / np.sqrt(squared.size)
        means[name] = (first.mean() + second.mean()) / 2, np.sqrt(squared.mean() / 4 / squared.size)  # a pixel: var/2
    (new, new_error), (old, old_error) = noise["multijitter"], noise["independent"]
    assert old - new > 5 * np.hypot(new_error, old_error), noise
    assert new < 0.6 * old, noise  # measured 0.3 here (RMSE ratio 0.55, bench_sampler.py)
    (new_mean, new_mean_error), (old_mean, old_mean_error) = means["multijitter"], means["independent"]
    assert abs(new_mean - old_mean) < 5 * np.hypot(new_mean_error, old_mean_error), means


def test05_one_chunk_of_64_spp_halves_the_seed_to_seed_rmse_or_better(variant):
    """The issue's target where a chunk holds all 64 samples (films up to 320 × 200 at 64 spp): the stratified
    sampler's RMS seed-to-seed difference is half the independent one's or less, i.e. its mean squared difference a
    quarter or less, with 5 standard errors of each estimate against it (measured: 0.12 of it)."""
    description = diffuse_scene(S.Film(64, 40))
    noise = {}
    for name in S.SAMPLERS:
        squared, _, _ = seed_noise(builder.load_scene(description, S.RenderSettings(sampler=name)), 64, one_chunk=True)
        noise[name] = squared.mean(), squared.std() / np.sqrt(squared.size)
    (new, new_error), (old, old_error) = noise["multijitter"], noise["independent"]
    assert new + 5 * new_error < 0.25 * (old - 5 * old_error), noise
