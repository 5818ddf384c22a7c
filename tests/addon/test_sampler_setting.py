"""The Sampler render setting (docs/rendering.md, The sampler): independent by default, multi-jittered by choice,
gathered into the render settings and written by File > Export > Mitsuba Scene into scene.xml."""
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera, add_plane, setup_render  # noqa: E402
from scratch_iridescence.addon.render.gather import gather_settings  # noqa: E402


def test_the_sampler_is_independent_by_default_gathered_and_exported(empty_scene, tmp_path):
    settings = empty_scene.scratch_iridescence
    assert settings.sampler == "independent" and gather_settings(empty_scene).sampler == "independent"
    settings.sampler = "multijitter"
    assert gather_settings(empty_scene).sampler == "multijitter"
    setup_render(empty_scene, 8, 6, samples=4)
    add_camera(empty_scene, location=(0, 0, 3), lens=40)
    add_plane(empty_scene, size=2)
    for name in ("independent", "multijitter"):
        settings.sampler = name
        assert bpy.ops.scratch.export_mitsuba(directory=str(tmp_path / name)) == {"FINISHED"}
        assert f'<sampler type="{name}"' in (tmp_path / name / "scene.xml").read_text()
