"""A small render through mi.load_dict + mi.render: a plate scratched on its left half under a sun."""
from __future__ import annotations

import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
from scratch_iridescence.mitsuba_bridge import scratch

SIZE = 64


def scene_dict(scratches):
    """A 10 cm aluminium plate (the rectangle spans 2 units: unit_scale 5 cm) seen off the sun's mirror direction."""
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {
            "type": "perspective", "fov": 40,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, -2.6, 1.5], target=[0, 0, 0], up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent"},
        },
        "sun": {"type": "directional", "direction": [0.0, -0.55, -0.5], "irradiance": 20.0},
        "sky": {"type": "constant", "radiance": 0.02},
        "plate": {"type": "rectangle", "bsdf": scratch_bsdf.plugin_dict(scratches, unit_scale=0.05)},
    }


def small_scene(settings: dict, size: int):
    """The plate with 300 scratches on its left half, the BSDF's ``settings``, on a ``size``² film."""
    s = scratch.random_scratches(300, seed=7, width=scratch.Uniform(1e-6, 5e-6), depth=scratch.Constant(2.5e-7),
                                 region=((0.0, 0.0), (0.5, 1.0)), length=(0.2, 0.5))
    description = scene_dict(s)
    description["plate"]["bsdf"].update(settings)
    description["sensor"]["film"].update(width=size, height=size)
    return mi.load_dict(description)


def test01_scratched_half_of_a_plate_shows_coloured_glints():
    scratches = scratch.random_scratches(
        800, seed=4, width=scratch.Gaussian(4e-6, 1.3e-6), depth=scratch.Gaussian(250e-9, 80e-9),
        depth_variation=(1.1, 0.04), region=((0.0, 0.0), (0.5, 1.0)), length=(0.1, 0.3))
    scene = mi.load_dict(scene_dict(scratches))
    image = np.mean([np.asarray(mi.render(scene, spp=16, seed=s)) for s in range(2)], axis=0)
    assert image.shape == (SIZE, SIZE, 3) and np.all(np.isfinite(image))
    # linear sRGB: saturated spectral colours may leave the gamut (negative components), luminance may not
    luminance = image @ np.array([0.2126, 0.7152, 0.0722])
    assert luminance.min() > -1e-6

    mask_scene = {key: value for key, value in scene_dict(scratches).items() if key != "sun"}
    mask_scene["plate"] = {"type": "rectangle", "bsdf": {"type": "diffuse"}}
    plate = np.asarray(mi.render(mi.load_dict(mask_scene), spp=1)).sum(axis=2) > 0
    columns = np.arange(SIZE)[None, :].repeat(SIZE, axis=0)
    # u = 0 is the left edge of the rectangle, which the camera sees on the left of the image
    left, right = plate & (columns < SIZE // 2 - 4), plate & (columns >= SIZE // 2 + 4)
    assert left.sum() > 300 and right.sum() > 300
    assert luminance[left].mean() > 5 * luminance[right].mean()

    bright = left & (luminance > np.percentile(luminance[left], 90))
    chroma = (image.max(axis=2) - image.min(axis=2)) / np.maximum(np.abs(image).max(axis=2), 1e-6)
    assert np.median(chroma[bright]) > 0.15  # diffraction colours, not grey glints
    assert np.median(chroma[right]) < np.median(chroma[bright])


def test02_a_scene_with_another_scratch_count_renders_without_compiling():
    import drjit as dr

    def launches(count, seed):
        s = scratch.random_scratches(count, seed=seed, width=scratch.Uniform(1e-6, 5e-6),
                                     depth=scratch.Constant(2e-7), region=((0.0, 0.0), (0.5, 1.0)))
        description = dict(scene_dict(s), sensor=dict(scene_dict(s)["sensor"], film={
            "type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}}))
        # No environment emitter: the path integrator writes its Dr.Jit registry ID into the kernel as a
        # literal, and which ID a new scene's sky gets depends on when the last scene's emitters were freed
        # (garbage collection): the kernels would differ for a reason that has nothing to do with scratches.
        del description["sky"]
        scene = mi.load_dict(description)
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            dr.eval(mi.render(scene, spp=2))
            return [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]

    launches(50, 1)
    second = launches(1234, 2)
    assert second and all(k["cache_hit"] for k in second)


@pytest.mark.parametrize("settings", [{}, {"coherent": False}, {"crossings": "height_field"}],
                         ids=["coherent", "incoherent", "height_field"])
def test03_frozen_chunks_give_the_traced_image_bit_for_bit(settings, monkeypatch):
    """Renders record each chunk size once with ``dr.freeze`` and replay it (render.render_chunks): the
    scratch BSDF's tables are all reachable, so nothing falls back to tracing, and the image is the
    traced one to the last bit."""
    from scratch_iridescence.mitsuba_bridge.render import freezing, passes as render

    scene = small_scene(settings, 16)
    spp = 13  # chunks of 4, 4, 4 and 1 spp on a 16 x 16 film: two sizes, two replays
    schedule = render.sample_schedule(spp, 16 * 16, 3)
    assert [c.spp for c in schedule] == [4, 4, 4, 1]
    traced = list(render.render_chunks(scene, schedule, spp, freeze=False))[-1].image

    used = []
    original = freezing.FrozenRender.__call__
    monkeypatch.setattr(freezing.FrozenRender, "__call__",
                        lambda self, *arguments: (used.append(self), original(self, *arguments))[1])
    frozen = list(render.render_chunks(scene, schedule, spp))[-1].image
    passes = used[0]
    assert passes.enabled and passes.failure is None, passes.failure
    assert passes.recordings <= 3
    assert frozen.tobytes() == traced.tobytes() and np.abs(traced[..., :3]).max() > 0


if __name__ == "__main__":  # write the test image for a look: python tests/bridge/bsdf/test_render.py out.png
    import sys

    mi.set_variant("llvm_ad_spectral")
    from scratch_iridescence import mitsuba_bridge

    mitsuba_bridge.register_plugins()
    s = scratch.random_scratches(800, seed=4, width=scratch.Gaussian(4e-6, 1.3e-6),
                                 depth=scratch.Gaussian(250e-9, 80e-9), depth_variation=(1.1, 0.04),
                                 region=((0.0, 0.0), (0.5, 1.0)), length=(0.1, 0.3))
    mi.util.write_bitmap(sys.argv[1], mi.render(mi.load_dict(scene_dict(s)), spp=64))
