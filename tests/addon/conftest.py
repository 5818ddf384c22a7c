"""Headless Blender fixtures: the add-on registered once, a fresh empty file per test.

Add-on tests import the bridge as ``scratch_iridescence.mitsuba_bridge``, the
add-on's own copy: the top-level ``mitsuba_bridge`` is the same code loaded as a
different module, so its ``ScratchSet`` is a different class.
"""
import pytest

bpy = pytest.importorskip("bpy")


@pytest.fixture(scope="session")
def addon():
    """The extension package, registered for the whole session."""
    import scratch_iridescence

    scratch_iridescence.register()
    yield scratch_iridescence
    scratch_iridescence.unregister()


@pytest.fixture
def empty_scene(addon):
    """Factory settings with no objects (registered classes survive the reset)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


@pytest.fixture
def plane(empty_scene):
    """A 2 m plane with the default UV map, active and selected."""
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    return bpy.context.active_object
