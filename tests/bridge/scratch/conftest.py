"""Small scratch sets built in code for the scratch-set tests."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.scratch import Gaussian, Profile, ScratchSet, random_scratches


@pytest.fixture
def two_scratches() -> ScratchSet:
    """A straight two-vertex scratch and a bent three-vertex V-groove."""
    return ScratchSet.from_polylines(
        [np.array([[0.1, 0.1], [0.4, 0.1]]), np.array([[0.5, 0.5], [0.6, 0.6], [0.7, 0.5]])],
        width=[1e-6, 2e-6], depth=[250e-9, 500e-9],
        profile=[Profile.RECTANGULAR, Profile.TRIANGULAR],
        depth_variation=[(0.0, 0.0), (1.1, 0.04)], seed=[7, 8])


@pytest.fixture
def plate_scratches() -> ScratchSet:
    """500 scratches drawn as in the paper's Fig. 7(b)."""
    return random_scratches(500, seed=3, width=Gaussian(4e-6, 1.3e-6), depth=Gaussian(250e-9, 80e-9),
                            vertices=5, curvature=2.0, depth_variation=(1.1, 0.04))
