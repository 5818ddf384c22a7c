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
"""
import pytest

bpy = pytest.importorskip("bpy")
import numpy as np  # noqa: E402
from shader_scenes import SHADERS, render  # noqa: E402

pytestmark = pytest.mark.slow
SAMPLES = 128

AGREE = (0.02, 0.05)
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


def blocks(image, size=8):
    height, width = image.shape
    return image.reshape(height // size, size, width // size, size).mean(axis=(1, 3))


@pytest.mark.parametrize("shader", list(SHADERS))
def test_shader_matches_cycles(cycles, tmp_path, shader):
    ours_sphere, _, ours = render("MITSUBA_SCRATCH", shader, tmp_path / "ours.exr", samples=SAMPLES)
    cycles_sphere, cycles_mean, reference = render("CYCLES", shader, tmp_path / "cycles.exr", samples=SAMPLES)
    mean_tolerance, block_tolerance = MODEL_DIFFERENCES.get(shader, AGREE)
    assert cycles_sphere > 0.05
    assert ours_sphere / cycles_sphere == pytest.approx(1.0, abs=mean_tolerance)
    assert np.abs(blocks(ours) - blocks(reference)).max() < block_tolerance * cycles_mean
