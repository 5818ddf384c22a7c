"""The neutral scene description owns its invariants: frames that must not scale are orthonormal."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge import scene as S


def scaled_frame():
    """A rotation about (1, 2, 3) by 40°, scaled by (2, 0.5, 3) and sheared, at (1, -2, 5)."""
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    angle = np.radians(40.0)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    matrix = np.eye(4)
    matrix[:3, :3] = rotation @ np.diag([2.0, 0.5, 3.0])
    matrix[:3, 3] = (1.0, -2.0, 5.0)
    return matrix, rotation


@pytest.mark.parametrize("make", [lambda m: S.Camera(m, fov_x_deg=40),
                                  lambda m: S.SpotLight(m, (1.0, 1.0, 1.0), 30.0, 20.0)])
def test01_camera_and_spot_frames_are_stored_orthonormal(make):
    matrix, rotation = scaled_frame()
    frame = make(matrix).to_world
    np.testing.assert_allclose(frame[:3, :3] @ frame[:3, :3].T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(frame[:3, :3], rotation, atol=1e-12)  # the scale is gone, the rotation kept
    np.testing.assert_array_equal(frame[:3, 3], matrix[:3, 3])
    np.testing.assert_array_equal(frame[3], [0, 0, 0, 1])


def test02_a_mirroring_frame_becomes_the_proper_rotation_and_area_lights_keep_their_size():
    mirrored = np.diag([1.0, 1.0, -2.0, 1.0])
    frame = S.Camera(mirrored).to_world
    assert np.linalg.det(frame[:3, :3]) == pytest.approx(1.0)
    matrix, _ = scaled_frame()
    area = S.AreaLight(matrix, "rectangle", 1.0, 1.0, (1.0, 1.0, 1.0))
    np.testing.assert_array_equal(area.to_world, matrix)  # an area light's scale is its size


def test03_frames_must_be_finite_4x4():
    with pytest.raises(ValueError, match="4×4"):
        S.Camera(np.eye(3))
    with pytest.raises(ValueError, match="finite"):
        S.SpotLight(np.full((4, 4), np.nan), (1.0, 1.0, 1.0), 30.0, 20.0)


def test04_the_bridge_loads_a_scratch_bsdf_for_scripts(variant):
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge import bsdf, scratch
    from scratch_iridescence.mitsuba_bridge.bsdf.plugin import plugin_class

    scratches = scratch.random_scratches(20, seed=3)
    loaded = bsdf.load(scratches, unit_scale=0.01, coherence_diameter=40e-6)
    assert isinstance(loaded, plugin_class()) and isinstance(loaded, mi.BSDF)
    params = mi.traverse(loaded)
    assert float(params["coherence_diameter"][0]) == pytest.approx(40e-6)
    assert float(params["unit_scale"][0]) == pytest.approx(0.01)
