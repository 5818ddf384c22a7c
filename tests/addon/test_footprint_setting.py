"""The Footprint Filter render setting (docs/rendering.md, Render settings; docs/model.md §11): off by default (far views are not
bounded yet) and gathered into the render settings (the builder and the export take it from there: tests/bridge/builder/test_scratched.py)."""
import pytest

bpy = pytest.importorskip("bpy")
from scratch_iridescence.addon.render.gather import gather_settings  # noqa: E402


def test_footprint_filter_is_off_by_default_and_gathered(empty_scene):
    settings = empty_scene.scratch_iridescence
    assert not settings.footprint_filter
    assert gather_settings(empty_scene).footprint_filter is False
    settings.footprint_filter = True
    assert gather_settings(empty_scene).footprint_filter is True
