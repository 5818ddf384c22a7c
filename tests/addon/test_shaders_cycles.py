"""Every supported shader measured against Cycles (shipped in the bpy wheel), as lights and skies are.

Each shader's scene (tests/addon/shader_scenes.py: a sphere on a grey floor under a
white world, 64 × 64) is rendered by this engine and by Cycles at 128 samples with
seed 0. Two figures must agree: the mean luminance of the sphere's disc (ratio to
Cycles within the shader's tolerance) and the picture itself (8 × 8-pixel block
means within a fraction of the image mean).

Tolerances: measured with seeds 0 and 1, the sphere means move by at most 0.4 %
between seeds in either engine and the blocks by at most 2 % of the image mean
(this engine) and 1.1 % (Cycles); RGB → spectrum → RGB moves colours by up to
1 %. Hence 2 % on the sphere mean and 5 % on the blocks where the models agree.
Where Mitsuba's model differs, the tolerance is the stated difference plus that
margin (docs/rendering.md lists the measured ratios).

The volumes and the textures laid out in Generated coordinates are held to the noise itself
(:func:`test_shader_within_the_noise_floor`): each engine renders the scene with two seeds, and the
blurred relative L1 distance between the engines (4 × 4-pixel block means) must stay within the sum
of the two engines' own distances between their seeds, the noise floor measured in the same run.
"""
import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402
from shader_scenes import SHADERS, render  # noqa: E402

pytestmark = pytest.mark.slow
SAMPLES = 128

AGREE = (0.02, 0.05)
#: shader → (the sphere's mean ratio to Cycles, its tolerance, the blocks' tolerance) where the ratio is
#: not 1: what this engine renders differently, on purpose (docs/rendering.md says why).
STATED = {
    # White diffuse + white glossy: Cycles' sum reflects up to twice the light that arrives; both halves are
    # rendered at 0.5 here (gather warns). Measured 0.49 on this sphere; the picture differs by as much as the
    # sphere is bright, so only its mean is held (no block tolerance).
    "add_capped": (0.49, 0.03, None),
    # Cycles' Principled v2 sheen is a microfiber layer (Zeltner et al. 2022), Mitsuba's the Disney 2015
    # grazing-angle lobe: on a dark base the sheen adds far less here (measured 0.72 on this sphere; the
    # blocks differ by up to 0.19 of the image mean).
    "principled_sheen": (0.72, 0.04, 0.25),
}
#: shader → (tolerance of the sphere's mean ratio, of the blocks), and why it differs from AGREE.
MODEL_DIFFERENCES = {
    # Cycles' Refraction BSDF refracts everything (no Fresnel loss); Mitsuba's dielectric loses the
    # reflected part at every interface: measured 0.90 on the sphere.
    "refraction": (0.13, 0.30),
    # Mitsuba's principled is the Disney 2015 model, Cycles' Principled v2 another: 4.3 % brighter on
    # this sphere (7-10 % on the default cube), and so everything built on a Principled BSDF.
    "principled": (0.07, 0.08),
    "principled_alpha": (0.05, 0.06),
    "math_and_mix_rgb": (0.07, 0.10),
}


#: Scenes compared with the noise floor (each engine renders them twice).
NOISE_FLOOR = ["volume_principled", "volume_scatter", "volume_absorption", "volume_in_glass", "world_fog",
               "checker_generated", "image_generated"]


def blocks(image, size=8):
    height, width = image.shape
    return image.reshape(height // size, size, width // size, size).mean(axis=(1, 3))


def blurred_l1(image, reference):
    """Mean absolute difference of the 4 × 4-pixel block means, relative to the reference's mean."""
    return float(np.abs(blocks(image, 4) - blocks(reference, 4)).mean() / blocks(reference, 4).mean())


@pytest.mark.parametrize("shader", list(SHADERS))
def test_shader_matches_cycles(cycles, tmp_path, shader):
    ours_sphere, _, ours = render("MITSUBA_SCRATCH", shader, tmp_path / "ours.exr", samples=SAMPLES)
    cycles_sphere, cycles_mean, reference = render("CYCLES", shader, tmp_path / "cycles.exr", samples=SAMPLES)
    ratio, mean_tolerance, block_tolerance = STATED.get(shader, (1.0, *MODEL_DIFFERENCES.get(shader, AGREE)))
    assert cycles_sphere > 0.05
    assert ours_sphere / cycles_sphere == pytest.approx(ratio, abs=mean_tolerance)
    if block_tolerance is not None:
        assert np.abs(blocks(ours) - blocks(reference)).max() < block_tolerance * cycles_mean


@pytest.mark.parametrize("shader", NOISE_FLOOR)
def test_shader_within_the_noise_floor(cycles, tmp_path, shader):
    ours = [render("MITSUBA_SCRATCH", shader, tmp_path / f"ours{seed}.exr", samples=SAMPLES, seed=seed)[2]
            for seed in (0, 1)]
    theirs = [render("CYCLES", shader, tmp_path / f"cycles{seed}.exr", samples=SAMPLES, seed=seed)[2]
              for seed in (0, 1)]
    floor = blurred_l1(ours[1], ours[0]) + blurred_l1(theirs[1], theirs[0])
    assert blurred_l1(ours[0], theirs[0]) < floor
