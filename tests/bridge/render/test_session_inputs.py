"""The interactive session checks what it is given as the command line checks its arguments: one ValueError
(a ScratchUserError) with a clear message, nothing changed; a film too large for the allowed memory is refused
before anything is allocated; a closed session says so.  The description's own invariants refuse bad values
for every user of the description (mitsuba_bridge/scene/description.py)."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import camera_at, quad, simple_scene
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.errors import ScratchUserError
from scratch_iridescence.mitsuba_bridge.render import session as interactive

ROOT = Path(__file__).resolve().parents[3]
SETTINGS = S.RenderSettings(seed=1, max_depth=3)
EYE = camera_at((0, 0, 3))


def plate():
    metal = S.ScratchedMetal(scratch.random_scratches(40, seed=2), coherence_diameter_m=30e-6)
    return simple_scene(film=S.Film(24, 16), camera=S.Camera(EYE, fov_x_deg=60),
                        shapes=(S.Shape("plate", quad(2.0), np.eye(4), "scratched"),),
                        materials={"scratched": metal}, lights=[S.PointLight((0, 0.5, 2), (5.0, 5.0, 5.0))],
                        world=S.ConstantWorld((0.1, 0.1, 0.1)))


# (what, a call that builds the bad value, words of the message): each refused by the description itself
DESCRIPTION_CASES = [
    ("fov nan", lambda: S.Camera(EYE, fov_x_deg=math.nan), "field of view"),
    ("fov 0", lambda: S.Camera(EYE, fov_x_deg=0.0), "field of view (degrees) must lie in (0.0, 180.0)"),
    ("fov 180", lambda: S.Camera(EYE, fov_x_deg=180.0), "field of view"),
    ("fov negative", lambda: S.Camera(EYE, fov_x_deg=-30.0), "field of view"),
    ("ortho width 0", lambda: S.Camera(EYE, projection="orthographic", ortho_width=0.0), "orthographic width"),
    ("zero camera matrix", lambda: S.Camera(np.zeros((4, 4))), "not an affine transform"),
    ("flat camera matrix", lambda: S.Camera(np.diag([1.0, 0.0, 1.0, 1.0])), "zero scale along an axis"),
    ("nan camera matrix", lambda: S.Camera(np.full((4, 4), np.nan)), "NaN or infinite"),
    ("3x3 camera matrix", lambda: S.Camera(np.eye(3)), "4×4 matrix, got shape (3, 3)"),
    ("inf far clip", lambda: S.Camera(EYE, far=math.inf), "far clipping distance must be a finite number"),
    ("film nan", lambda: S.Film(math.nan, 16), "film width must be a whole number, got nan"),
    ("film 0", lambda: S.Film(24, 0), "film height must be at least 1"),
    ("film float", lambda: S.Film(24.5, 16), "film width must be a whole number"),
    ("crop floats", lambda: S.Film(24, 16, crop=(0.5, 0, 4, 4)), "crop window must be a whole number"),
    ("nan point power", lambda: S.PointLight((0, 0, 1), (math.nan, 1.0, 1.0)), "point light intensity"),
    ("inf sun", lambda: S.SunLight((0, 0, -1), (math.inf,) * 3), "sun irradiance"),
    ("zero sun direction", lambda: S.SunLight((0, 0, 0), (1.0,) * 3), "sun direction must not be zero"),
    ("nan spot matrix", lambda: S.SpotLight(np.full((4, 4), np.nan), (1.0,) * 3, 40, 30), "spot light matrix"),
    ("nan area size", lambda: S.AreaLight(np.eye(4), "disk", math.nan, 1.0, (1.0,) * 3), "area light size x"),
    ("nan world", lambda: S.ConstantWorld((math.nan, 0.1, 0.1)), "world colour must be three finite numbers"),
    ("nan sky", lambda: S.SkyWorld((0, 0, 1), turbidity=math.nan), "sky turbidity"),
    ("nan spp", lambda: S.RenderSettings(spp=math.nan), "spp must be a whole number"),
    ("nan shape matrix", lambda: S.Shape("x", quad(1.0), np.full((4, 4), np.inf), "m"), "shape 'x': matrix"),
]


@pytest.mark.parametrize("what, build, words", DESCRIPTION_CASES, ids=[case[0] for case in DESCRIPTION_CASES])
def test01_the_description_refuses_bad_values_once_for_everyone(what, build, words):
    with pytest.raises(ValueError) as refused:
        build()
    assert isinstance(refused.value, ScratchUserError) and words in str(refused.value), str(refused.value)


def test02_good_values_still_pass_and_frames_keep_their_rotation():
    camera = S.Camera(EYE @ np.diag([2.0, 2.0, 2.0, 1.0]), fov_x_deg=179.0, far=1e6)
    assert np.allclose(camera.to_world, EYE)
    assert S.Film(np.int64(24), 16).width == 24 and type(S.Film(np.int64(24), 16).width) is int
    zero_scale = np.diag([0.0, 0.0, 0.0, 1.0])  # Blender hides objects so: a shape may have it
    assert np.array_equal(S.Shape("hidden", quad(1.0), zero_scale, "m").to_world, zero_scale)


@pytest.fixture(scope="module")
def session(variant):
    session = interactive.Session(plate(), SETTINGS, samples=2)
    session.step(math.inf)
    yield session
    session.close()


SESSION_CASES = [
    ("camera None", lambda s: s.set_camera(None), "the camera must be a Camera, got NoneType"),
    ("film None", lambda s: s.set_film(None), "the film must be a Film"),
    ("3x3 transform", lambda s: s.set_transform("plate", np.eye(3)), "must be a 4×4 matrix, got shape (3, 3)"),
    ("zero transform", lambda s: s.set_transform("plate", np.zeros((4, 4))), "not an affine transform"),
    ("nan transform", lambda s: s.set_transform("plate", np.full((4, 4), np.nan)), "NaN or infinite"),
    ("unknown shape", lambda s: s.set_transform("nothing", np.eye(4)), "no shape named 'nothing'"),
    ("light -1", lambda s: s.set_light(-1, S.PointLight((0, 0, 1), (1.0,) * 3)), "from 0 to 0, got -1"),
    ("light 5", lambda s: s.set_light(5, S.PointLight((0, 0, 1), (1.0,) * 3)), "from 0 to 0, got 5"),
    ("light True", lambda s: s.set_light(True, S.PointLight((0, 0, 1), (1.0,) * 3)), "whole number"),
    ("light not a light", lambda s: s.set_light(0, "bright"), "the light must be a PointLight or"),
    ("world a colour", lambda s: s.set_world((0.5, 0.5, 0.5)), "the world must be a ConstantWorld or"),
    ("material None", lambda s: s.set_material("scratched", None), "the material must be a"),
    ("unknown material", lambda s: s.set_material("nothing", S.Diffuse()), "no material 'nothing'"),
    ("scratches None", lambda s: s.set_scratches("scratched", None), "the scratches must be a ScratchSet"),
    ("step nan", lambda s: s.step(math.nan), "step takes seconds >= 0"),
    ("step -1", lambda s: s.step(-1.0), "step takes seconds >= 0"),
    ("update of a tuple", lambda s: s.apply((interactive.Change.CAMERA, ())), "an update must be a Update"),
    ("update without arguments", lambda s: s.apply(interactive.Update(interactive.Change.LIGHT)),
     "a LIGHT update takes 2 arguments, got ()"),
]


@pytest.mark.parametrize("what, call, words", SESSION_CASES, ids=[case[0] for case in SESSION_CASES])
def test03_bad_updates_are_one_clear_error_and_change_nothing(session, what, call, words):
    before = session.description
    updates = session.stats["updates"]
    with pytest.raises(ValueError) as refused:
        call(session)
    assert isinstance(refused.value, ScratchUserError) and words in str(refused.value), str(refused.value)
    assert session.description is before and session.stats["updates"] == updates


def test04_a_film_too_large_for_the_allowed_memory_is_refused_before_any_allocation(session):
    # Film(100000, 100000) would need about 780 GiB: refused at once, the session keeps its scene and renders on
    rebuilds = session.stats["rebuilds"]
    with pytest.raises(MemoryError, match=r"a 100000 x 100000 interactive render needs about [\d.]+ GiB of memory but "
                                          r"only [\d.]+ GiB is allowed \("):
        session.set_film(S.Film(100_000, 100_000))
    assert session.stats["rebuilds"] == rebuilds and session.description.film == S.Film(24, 16)
    assert session.step(0.0).image.shape == (16, 24, 4)


def test05_a_session_too_large_for_ulimit_v_is_refused_in_a_child_not_a_crash():
    code = f"""
import resource, sys
sys.path.insert(0, {str(ROOT / "tests" / "bridge")!r})
from bridge_scenes import simple_scene
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.render.session import Session
resource.setrlimit(resource.RLIMIT_AS, (6_000_000 * 1024, resource.RLIM_INFINITY))
try:
    Session(simple_scene(film=S.Film(20_000, 20_000)), S.RenderSettings(variant="llvm_ad_spectral"))
except MemoryError as error:
    print("refused:", error)
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("refused: a 20000 x 20000 interactive render needs about ")
    assert "address-space limit, ulimit -v 5.7 GiB" in result.stdout


def test06_a_closed_session_says_so_for_every_call(variant):
    closed = interactive.Session(plate(), SETTINGS, samples=1)
    closed.close()
    calls = [lambda: closed.step(), lambda: closed.set_camera(S.Camera(EYE)), lambda: closed.set_film(S.Film(8, 8)),
             lambda: closed.set_transform("plate", np.eye(4)),
             lambda: closed.set_light(0, S.PointLight((0, 0, 1), (1,) * 3)), lambda: closed.set_world(None),
             lambda: closed.apply(interactive.Update(interactive.Change.WORLD, (None,))),
             lambda: closed.rebuild(plate())]
    for call in calls:
        with pytest.raises(interactive.SessionClosed, match="the session is closed"):
            call()
