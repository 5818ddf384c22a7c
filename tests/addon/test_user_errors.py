"""User errors become one report and keep the scratches; programming errors surface with their traceback."""
import pytest

bpy = pytest.importorskip("bpy")
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.geometry.surface import SurfaceError  # noqa: E402
from scratch_iridescence.addon.mesh import MeshError  # noqa: E402
from scratch_iridescence.addon.operators.editing import USER_ERRORS  # noqa: E402
from scratch_iridescence.addon.render.gather import GatherError  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402
from scratch_iridescence.mitsuba_bridge.errors import ParameterError, ScratchUserError  # noqa: E402
from scratch_iridescence.mitsuba_bridge.device.memory import NotEnoughMemory  # noqa: E402
from scratch_iridescence.mitsuba_bridge.device.variants import VariantError  # noqa: E402
from scratch_iridescence.mitsuba_bridge.files.regular import NotARegularFile  # noqa: E402


def test01_every_user_error_is_a_scratch_user_error_and_keeps_its_builtin_base():
    for error, builtin in [(scratch.ScratchFormatError, ValueError), (MeshError, ValueError),
                           (SurfaceError, ValueError), (ParameterError, ValueError),
                           (NotEnoughMemory, MemoryError), (VariantError, RuntimeError), (NotARegularFile, OSError),
                           (GatherError, RuntimeError)]:
        assert issubclass(error, ScratchUserError) and issubclass(error, builtin), error
    assert ValueError not in USER_ERRORS and TypeError not in USER_ERRORS and Exception not in USER_ERRORS
    assert not issubclass(ValueError, USER_ERRORS) and not issubclass(KeyError, USER_ERRORS)


def test02_a_bad_parameter_is_reported_and_the_scratches_stay(scratched_plane):
    before = storage.raw_scratch_bytes(scratched_plane)
    with pytest.raises(RuntimeError, match="Length Max is below Length Min"):  # an ERROR report
        bpy.ops.scratch.generate("EXEC_DEFAULT", True, count=5, length_min=0.2, length_max=0.1)
    assert storage.raw_scratch_bytes(scratched_plane) == before


@pytest.mark.parametrize("bug", [ValueError("index out of range in a helper"), TypeError("wrong call")])
def test03_a_bug_inside_an_operator_surfaces_as_a_traceback(scratched_plane, monkeypatch, bug):
    import scratch_iridescence.addon.operators.generate as generate_module

    def broken(*_args, **_kwargs):
        raise bug

    before = storage.raw_scratch_bytes(scratched_plane)
    monkeypatch.setattr(generate_module, "scatter", broken)
    with pytest.raises(RuntimeError) as raised:
        bpy.ops.scratch.generate("EXEC_DEFAULT", True, count=5)
    message = str(raised.value)
    assert "Traceback" in message and type(bug).__name__ in message and str(bug) in message
    assert storage.raw_scratch_bytes(scratched_plane) == before


def test04_the_overlay_draws_nothing_on_user_errors_and_lets_bugs_raise(scratched_plane, monkeypatch):
    from types import SimpleNamespace

    from scratch_iridescence.addon.ui import overlay

    context = SimpleNamespace(active_object=scratched_plane, view_layer=bpy.context.view_layer,
                              space_data=SimpleNamespace(overlay=SimpleNamespace(show_overlays=True)))
    data = overlay.drawable_data(context)
    assert data is not None and len(data.positions) >= 2 * 50  # the 50 scratches, as line pieces

    def raising(error):
        def overlay_data(*_args):
            raise error
        return overlay_data

    monkeypatch.setattr(overlay, "overlay_data", raising(MeshError("the mesh has no faces")))
    assert overlay.drawable_data(context) is None
    monkeypatch.setattr(overlay, "overlay_data", raising(ValueError("a bug in the line builder")))
    with pytest.raises(ValueError, match="a bug in the line builder"):
        overlay.drawable_data(context)
