"""The benchmark table's filtered column (``scenes/noise.py``): the noise estimate and the spp search.

The worker itself (renders of a saved picture with the Footprint Filter) runs in ``make paper`` in
miniature: tests/addon/test_paper_scenes.py test10 (slow)."""
import math

import numpy as np
import pytest

from scratch_iridescence.scenes import noise


def test01_relative_noise_of_two_seeds_is_the_images_own_noise():
    # Two renders of an image whose pixels have mean mu and standard deviation sigma: the estimate is
    # sigma / mu.  With 2e5 pixel-channels its relative standard error is about 1/sqrt(2 n) = 0.16 %;
    # 1 % is six of them.
    rng = np.random.default_rng(7)
    mean = rng.uniform(0.5, 1.5, size=(200, 250, 3))
    mu, sigma = float(mean.mean()), 0.3
    first = mean + sigma * rng.standard_normal(mean.shape)
    second = mean + sigma * rng.standard_normal(mean.shape)
    assert noise.relative_noise(first, second) == pytest.approx(sigma / mu, rel=0.01)
    # the image's own content (its mean's variation over the pixels) is not noise
    assert noise.relative_noise(mean, mean) == 0.0


def test02_relative_noise_refuses_what_it_cannot_measure():
    with pytest.raises(ValueError, match="different shapes"):
        noise.relative_noise(np.ones((4, 4, 3)), np.ones((4, 5, 3)))
    with pytest.raises(ValueError, match="black"):
        noise.relative_noise(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)))


def test03_the_next_probe_follows_one_over_sqrt_spp_with_a_margin_within_bounds():
    # noise 4x the target at 2 spp: 1/sqrt(spp) says 32 spp; the margin asks 10 % more
    assert noise.next_probe(2, 4.0, 1.0, 512) == math.ceil(32 * noise.PREDICTION_MARGIN)
    # never beyond the picture's own spp, always at least one more than the last probe
    assert noise.next_probe(64, 10.0, 1.0, 512) == 512
    assert noise.next_probe(8, 1.01, 1.0, 512) == 9


def test04_noise_is_measured_on_what_the_picture_shows():
    # Blender's Standard view: exposure, clipped to [0, 1], then the sRGB encoding (0.5 -> 0.7354)
    linear = np.array([0.0, 0.002, 0.25, 1.0, 4000.0])
    np.testing.assert_allclose(noise.display_referred(linear, 1.0), [0.0, 0.050709, 0.735357, 1.0, 1.0], atol=1e-5)
    # a lamp seen directly (thousands of times white, its edge pixels half covered from seed to seed) is as
    # noisy as a white edge, not a thousand times more
    rng = np.random.default_rng(3)
    cover = rng.random((2, 64, 64, 3)) < 0.5
    lamp = noise.relative_noise(*noise.display_referred(4000.0 * cover, 0.0))
    white = noise.relative_noise(*noise.display_referred(1.0 * cover, 0.0))
    assert lamp == pytest.approx(white)
