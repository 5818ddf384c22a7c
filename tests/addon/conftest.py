"""Headless Blender fixtures: the add-on registered once, a fresh empty file per test.

Blender is imported by the fixtures, not here, so that ``tests/addon/geometry/``
(Blender-free helpers) runs where ``bpy`` is missing; the Blender tests of this folder
are then not collected (they import ``bpy`` at module level).
"""
import importlib.util

import pytest

if importlib.util.find_spec("bpy") is None:
    collect_ignore_glob = ["test_*.py"]  # this folder's own tests; geometry/ needs no Blender


@pytest.fixture(scope="session")
def addon():
    """The extension package, registered for the whole session."""
    pytest.importorskip("bpy")
    import scratch_iridescence

    scratch_iridescence.register()
    yield scratch_iridescence
    scratch_iridescence.unregister()


@pytest.fixture
def empty_scene(addon):
    """Factory settings with no objects (registered classes survive the reset)."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


@pytest.fixture
def plane(empty_scene):
    """A 2 m plane with the default UV map, active and selected."""
    import bpy

    bpy.ops.mesh.primitive_plane_add(size=2.0)
    return bpy.context.active_object


@pytest.fixture
def cube(empty_scene):
    """Blender's default cube (2 m, UV unwrapped as a cross with seams), active and selected."""
    import bpy

    bpy.ops.mesh.primitive_cube_add(size=2.0)
    return bpy.context.active_object


@pytest.fixture
def scratched_plane(plane):
    """The plane with 50 scratches already stored (to check that failed edits keep them)."""
    from scratch_iridescence.addon import storage
    from scratch_iridescence.mitsuba_bridge import scratch

    storage.write_scratches(plane, scratch.random_scratches(50, seed=5, region=((0.1, 0.1), (0.9, 0.9)),
                                                            length=(0.05, 0.1)))
    return plane


@pytest.fixture(scope="module")
def cycles(addon):
    """Blender's Cycles add-on enabled for a module's comparisons (skips where the build has none)."""
    import addon_utils
    import bpy

    addon_utils.enable("cycles", default_set=True)
    if not hasattr(bpy.types.Scene, "cycles"):
        pytest.skip("Cycles is not available in this Blender build")
    yield
    addon_utils.disable("cycles", default_set=True)
