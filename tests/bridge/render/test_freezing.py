"""Frozen passes: Mitsuba's global tables are found, hidden plugin arrays fall back to traced passes."""
import numpy as np
import pytest

from bridge_scenes import interrupting_scene, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge.render import freezing
from scratch_iridescence.mitsuba_bridge import scene as S

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")

#: Read by HiddenAlbedo.eval without being one of its attributes: no traversal can find it.
_HIDDEN = {}


def test01_recording_errors_name_the_unreachable_variable():
    error = RuntimeError("record(): Variable r17[95] -> 0x5, label=(null), was created before recording was "
                         "started, but it was not specified as an input variable!")
    wrapped = RuntimeError("record(): error encountered while recording")
    wrapped.__cause__ = error
    assert freezing.unreachable_variable(wrapped) == 17
    assert freezing.unreachable_variable(RuntimeError("something else")) is None


def test02_spectral_renders_read_a_few_global_tables(variant):
    handles = freezing.mitsuba_globals()
    assert 1 <= len(handles) <= freezing.MAX_GLOBALS
    assert freezing.mitsuba_globals() is handles  # found once per variant


@pytest.fixture(scope="module")
def lit_scene(variant):
    description = simple_scene(lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    return builder.load_scene(description, S.RenderSettings())


def test03_frozen_passes_equal_traced_ones_and_replay_new_seeds(lit_scene):
    frozen = freezing.FrozenRender()
    recordings = []
    for seed in (3, 4, 5, 6):
        image = np.asarray(frozen(lit_scene, 0, 1, seed))
        assert np.array_equal(image, np.asarray(mi.render(lit_scene, spp=1, seed=seed)))
        recordings.append(frozen.recordings)
    # The first render leaves a few scene values in their final, opaque form: one more recording at
    # most, then only replays.
    assert frozen.enabled and frozen.failure is None and recordings[1] <= 2 and recordings[-1] == recordings[1]


def _hidden_albedo_scene():
    class HiddenAlbedo(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]

        def eval(self, ctx, si, wo, active=True):
            return mi.Spectrum(_HIDDEN["albedo"] * dr.maximum(mi.Frame3f.cos_theta(wo), 0.0) / dr.pi)

        def pdf(self, ctx, si, wo, active=True):
            return dr.maximum(mi.Frame3f.cos_theta(wo), 0.0) / dr.pi

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = mi.warp.square_to_cosine_hemisphere(sample2)
            bs.pdf = self.pdf(ctx, si, bs.wo)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
            return bs, mi.Spectrum(_HIDDEN["albedo"])

        def traverse(self, callback):
            pass

    mi.register_bsdf("hidden_albedo_test", lambda props: HiddenAlbedo(props))
    _HIDDEN["albedo"] = dr.opaque(mi.Float, 0.5)
    description = simple_scene(lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))])
    scene_dict = builder.scene_dict(description, S.RenderSettings())
    shape = next(key for key in scene_dict if key.startswith("shape-"))
    scene_dict[shape] = {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale(2.0),
                         "bsdf": {"type": "hidden_albedo_test"}}
    return mi.load_dict(scene_dict)


def test04_a_plugin_that_cannot_be_recorded_falls_back_to_traced_passes_never_to_stale_ones(variant):
    scene = _hidden_albedo_scene()
    frozen = freezing.FrozenRender()
    first = np.asarray(frozen(scene, 0, 1, 7))
    assert not frozen.enabled and "record()" in frozen.failure  # Dr.Jit refuses to record it
    _HIDDEN["albedo"] = dr.opaque(mi.Float, 0.25)  # a replay would still use 0.5
    second = np.asarray(frozen(scene, 0, 1, 7))
    assert np.allclose(second[..., :3], 0.5 * first[..., :3], rtol=1e-5, atol=1e-7)


def test04b_a_render_that_fell_back_says_why_on_every_later_progress(variant, lit_scene):
    """The fallback costs only speed, so the image says nothing of it: the progress carries the reason for
    the CLI, the engine's console and ``make paper``'s table."""
    from scratch_iridescence.mitsuba_bridge.render import passes as render
    from scratch_iridescence.mitsuba_bridge.render.schedule import sample_schedule

    chunks = sample_schedule(3, 16, 0)
    traced = list(render.render_chunks(_hidden_albedo_scene(), chunks, 3))
    assert all("record()" in progress.traced_because for progress in traced)
    note = traced[-1].traced_note
    assert note.startswith(render.TRACED_NOTE_PREFIX) and "\n" not in note
    assert len(note) <= len(render.TRACED_NOTE_PREFIX) + 30 + render.TRACED_REASON_CHARS
    frozen = list(render.render_chunks(lit_scene, chunks, 3))
    assert all(progress.traced_because is None and progress.traced_note is None for progress in frozen)


def test_a_ctrl_c_while_recording_is_handed_on_and_keeps_freezing_enabled(variant):
    """Dr.Jit wraps the KeyboardInterrupt in a RuntimeError, like a failed recording: it must not be taken for
    one (which would switch freezing off for the session), but end the pass as an interruption."""
    from scratch_iridescence.mitsuba_bridge.render import passes as render

    frozen, traced = freezing.FrozenRender(), freezing.FrozenRender(enabled=False)
    with interrupting_scene() as scene:
        for passes in (frozen, traced):  # (the plain mi.render of a session without freezing too)
            with pytest.raises(render.RenderInterrupted):
                passes(scene, 0, 1, 0)
        del scene
    assert frozen.enabled and frozen.failure is None


def test05_activating_a_variant_finds_the_global_tables_before_any_scene_exists(variant):
    """activate() calibrates at once: found later, with a scratch BSDF alive, the calibration's
    virtual BSDF call would compile the whole scratch model into its kernel (freezing.calibrate)."""
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge.device import variants
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    assert activate(mi.variant()) == mi.variant()
    assert mi.variant() in freezing._globals and freezing.mitsuba_globals() is freezing._globals[mi.variant()]
