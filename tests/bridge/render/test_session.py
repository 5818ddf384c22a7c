"""The interactive session: in-place updates give the rebuilt scene's image, without compiling kernels."""
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import camera_at, quad, simple_scene
from scratch_iridescence.mitsuba_bridge import builder, scratch
from scratch_iridescence.mitsuba_bridge.render import session as interactive, passes as render
from scratch_iridescence.mitsuba_bridge import scene as S

SETTINGS = S.RenderSettings(seed=3, max_depth=4)
SAMPLES = 8


def scratches(count, seed):
    return scratch.random_scratches(count, seed=seed, region=((0.1, 0.1), (0.9, 0.9)), length=(0.05, 0.2))


def plate_scene(camera=None):
    """A scratched 2 m plate under a point light and a dim world, 64 × 48 pixels."""
    metal = S.ScratchedMetal(scratches(200, 1), coherence_diameter_m=30e-6)
    return simple_scene(film=S.Film(64, 48), camera=camera or S.Camera(camera_at((0, 0, 3)), fov_x_deg=60),
                        shapes=(S.Shape("plate", quad(2.0), np.eye(4), "scratched"),),
                        materials={"scratched": metal}, lights=[S.PointLight((0, 0.5, 2), (5.0, 5.0, 5.0))],
                        world=S.ConstantWorld((0.1, 0.1, 0.1)))


def finish(session):
    progress = session.step(0.0)
    while not session.finished:
        progress = session.step(0.0)
    return progress


def rebuilt_image(description):
    session = interactive.Session(description, SETTINGS, samples=SAMPLES)
    try:
        return finish(session).image
    finally:
        session.close()


@pytest.fixture
def session(variant):
    session = interactive.Session(plate_scene(), SETTINGS, samples=SAMPLES)
    finish(session)  # the first frame compiles what the session needs
    yield session
    session.close()


def test00_a_session_in_a_fresh_process_sets_up_its_variant_itself():
    """No other call first: the session activates the settings' variant (plugins, CPU target, calibration)."""
    code = """
import sys
sys.path.insert(0, {tests!r})
from bridge_scenes import simple_scene
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.render.session import Session
session = Session(simple_scene(world=S.ConstantWorld((1.0, 1.0, 1.0))), S.RenderSettings(variant="llvm_ad_spectral"),
                  samples=2, start_divisor=1)
progress = session.step(60.0)
print(progress.spp_done, progress.image.shape, float(progress.image[..., :3].mean()) > 0)
""".format(tests=str(Path(__file__).resolve().parents[1]))
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["2", "(24,", "32,", "4)", "True"], result.stdout


def test01_schedule_starts_small_then_refines_with_fixed_pass_sizes():
    plan = [interactive.plan_pass(i, spp, 64, 4) for i, spp in enumerate([0, 0, 1, 2, 3, 4, 8, 12])]
    assert plan[0] == (True, 1)                             # a 1/4-resolution preview first
    assert plan[1:5] == [(False, 1)] * 4                    # then single samples at full resolution
    assert plan[5:] == [(False, interactive.BATCH_SPP)] * 3
    assert interactive.plan_pass(9, 62, 64, 4) == (False, 1)  # never more than what remains
    assert interactive.plan_pass(0, 0, 64, 1) == (False, 1)   # no preview at divisor 1


def test02_first_step_shows_the_enlarged_preview_then_full_resolution_passes_count(variant):
    session = interactive.Session(plate_scene(), SETTINGS, samples=SAMPLES)
    first = session.step(0.0)
    assert first.spp_done == 0 and first.image.shape == (48, 64, 4)
    assert np.array_equal(first.image[::4, ::4], first.image[3::4, 3::4])  # 4 × 4 blocks of one value
    second = session.step(0.0)
    assert second.spp_done == 1 and not np.array_equal(second.image[::4, ::4], second.image[1::4, 1::4])
    session.close()


def test03_session_stops_at_its_samples_and_a_closed_one_refuses_to_render(session):
    passes = session.stats["passes"]
    assert session.finished and session.stats["spp_done"] == SAMPLES
    assert session.step(1.0).spp_done == SAMPLES
    assert session.stats["passes"] == passes  # nothing rendered once finished
    session.close()
    with pytest.raises(RuntimeError, match="closed"):
        session.step()


def test04_camera_move_gives_the_rebuilt_image_and_compiles_nothing(session):
    kernels = session.stats["kernels_compiled"]
    cameras = [S.Camera(camera_at((0.2 * i, -0.1 * i, 3.0)), fov_x_deg=50 + 3 * i, shift_x=0.02 * i)
               for i in range(1, 4)]
    for camera in cameras:
        session.set_camera(camera)
        image = finish(session).image
    assert session.stats["kernels_compiled"] == kernels
    assert session.stats["last_update"] == "camera" and session.stats["rebuilds"] == 0
    assert np.array_equal(image, rebuilt_image(plate_scene(cameras[-1])))


def test05_new_scratch_sets_of_other_sizes_give_the_rebuilt_image_and_compile_nothing(session):
    kernels = session.stats["kernels_compiled"]
    for count in (50, 700, 3000):
        new_set = scratches(count, seed=count)
        session.set_scratches("scratched", new_set)
        image = finish(session).image
    assert session.stats["kernels_compiled"] == kernels
    description = plate_scene()
    metal = dataclasses.replace(description.materials["scratched"], scratches=new_set)
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(description, materials={"scratched": metal})))


def test06_moved_object_gives_the_rebuilt_image(session):
    matrix = np.eye(4)
    matrix[:3, :3] = [[0.8, -0.6, 0], [0.6, 0.8, 0], [0, 0, 1]]
    matrix[:3, 3] = (0.3, -0.2, 0.1)
    session.set_transform("plate", matrix)
    image = finish(session).image
    description = plate_scene()
    shape = dataclasses.replace(description.shapes[0], to_world=matrix)
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(description, shapes=(shape,))))
    with pytest.raises(ValueError, match="no shape named 'no such shape'"):
        session.set_transform("no such shape", matrix)


def test07_light_and_world_changes_give_the_rebuilt_image_in_place(session):
    light = S.PointLight((0.4, -0.3, 1.5), (1.0, 3.0, 6.0))
    world = S.ConstantWorld((0.3, 0.2, 0.1))
    session.set_light(0, light)
    session.set_world(world)
    image = finish(session).image
    assert session.stats["rebuilds"] == 0
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(plate_scene(), lights=(light,), world=world)))


def test08_changes_no_parameter_expresses_rebuild(session):
    light = S.SunLight((0.0, 0.3, -1.0), (2.0, 2.0, 2.0))  # another light type
    camera = S.Camera(camera_at((0, 0, 3)), projection="orthographic", ortho_width=2.5)
    session.set_light(0, light)
    session.set_camera(camera)
    image = finish(session).image
    assert session.stats["rebuilds"] == 2
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(plate_scene(camera), lights=(light,))))


def test09_metal_settings_update_in_place(session):
    metal = dataclasses.replace(session.description.materials["scratched"], material="Cu",
                                coherence_diameter_m=50e-6, scratches=scratches(100, 9))
    session.set_material("scratched", metal)
    image = finish(session).image
    assert session.stats["rebuilds"] == 0
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(plate_scene(), materials={"scratched": metal})))


def test09a_metal_settings_keep_the_scratches(session):
    """A settings change alone (the panel's metal or coherence diameter) leaves the scratch set as it is."""
    metal = dataclasses.replace(session.description.materials["scratched"], material="Cu", coherence_diameter_m=50e-6)
    session.set_material("scratched", metal)
    image = finish(session).image
    assert session.stats["rebuilds"] == 0 and "scratches=200" in str(session._scene.shapes()[0].bsdf())
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(plate_scene(), materials={"scratched": metal})))


@pytest.mark.parametrize("option", [
    {"depth_phase": "incidence"},
    # The height field's kernels compile for ~100 s on a cold cache (2-core machine; docs/bsdf.md, Performance).
    pytest.param({"crossings": "height_field", "depth_phase": "incidence"}, marks=pytest.mark.slow),
], ids=["depth_phase", "crossings"])
def test09b_crossing_and_depth_phase_options_rebuild_the_bsdf(session, option):
    """Plugin options no traversed parameter expresses: a rebuild, whose image is the rebuilt scene's."""
    metal = dataclasses.replace(session.description.materials["scratched"], **option)
    session.set_material("scratched", metal)
    image = finish(session).image
    assert session.stats["rebuilds"] == 1
    for name, value in option.items():
        assert f"{name}={value}" in str(session._scene.shapes()[0].bsdf())
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(plate_scene(), materials={"scratched": metal})))
    with pytest.raises(ValueError, match="crossings must be one of"):
        dataclasses.replace(metal, crossings="deepest")


def test10_progressive_image_converges_to_the_final_render_at_equal_spp(variant):
    """Session and F12 path (other seeds) estimate the same image: their pixel differences average to 0."""
    spp = 32
    description = dataclasses.replace(plate_scene(), materials={"scratched": S.Diffuse((0.5, 0.5, 0.5))})
    session = interactive.Session(description, SETTINGS, samples=spp)
    viewport = finish(session).image[..., :3]
    session.close()
    final = render.render_image(builder.load_scene(description, SETTINGS), spp, seed=1234)[..., :3]
    difference = (viewport - final).ravel()
    standard_error = difference.std() / np.sqrt(difference.size)
    assert abs(difference.mean()) < 5.0 * standard_error  # a 5-sigma margin: fails by chance < 1e-6
    assert abs(viewport.mean() / final.mean() - 1.0) < 0.02


def test11_frozen_passes_replay_camera_moves_exactly_as_traced_passes_render_them(variant):
    """Orbiting replays the recording (no re-tracing); its image is bit for bit the unfrozen session's."""
    images = {}
    for freeze in (True, False):
        session = interactive.Session(plate_scene(), SETTINGS, samples=SAMPLES, freeze=freeze)
        finish(session)
        for step in range(1, 3):
            session.set_camera(S.Camera(camera_at((0.15 * step, 0.1, 3.0)), fov_x_deg=55 - step))
            images[freeze] = finish(session).image
        assert session.stats["frozen"] is freeze and session.stats["freeze_failure"] is None
        session.close()
    assert np.array_equal(images[True], images[False])



def test12_appended_strokes_extend_the_tables_give_the_rebuilt_image_and_compile_nothing(session):
    from scratch_iridescence.mitsuba_bridge.bsdf.tables.grid import build_tables

    kernels = session.stats["kernels_compiled"]
    description = plate_scene()
    current = description.materials["scratched"].scratches
    kept_cell_size = build_tables(current).cell_size
    for index in range(3):  # three pen strokes of two scratches each
        stroke = scratch.random_scratches(2, seed=50 + index, region=((0.3, 0.3), (0.7, 0.7)), length=(0.1, 0.3))
        current = scratch.ScratchSet.concatenate([current, stroke])
        session.set_scratches("scratched", current)
        bsdf = session._scene.shapes()[0].bsdf()
        assert bsdf.table_cache.incremental and bsdf.tables.cell_size == kept_cell_size
        image = finish(session).image
    assert session.stats["kernels_compiled"] == kernels
    # the automatic search finds the kept cell size for the final set too: the same tables, the same image
    assert build_tables(current).cell_size == kept_cell_size
    metal = dataclasses.replace(description.materials["scratched"], scratches=current)
    assert np.array_equal(image, rebuilt_image(dataclasses.replace(description, materials={"scratched": metal})))


def test13_the_kernel_counter_sees_a_new_film_size_compile(session):
    kernels = session.stats["kernels_compiled"]
    session.set_film(S.Film(37, 29))  # a size no other test renders: new kernels (compiled or from the disk cache)
    finish(session)
    assert session.stats["kernels_compiled"] > kernels
    settled = session.stats["kernels_compiled"]
    session.set_camera(S.Camera(camera_at((0.1, 0, 3)), fov_x_deg=60))
    finish(session)
    assert session.stats["kernels_compiled"] == settled


# ---- strips: a full-resolution pass rendered as strips of one small film (CPU)

@pytest.mark.parametrize("camera", [
    S.Camera(camera_at((0.3, -0.2, 3.0)), fov_x_deg=55, shift_x=0.1, shift_y=-0.05),
    S.Camera(camera_at((0.3, -0.2, 3.0)), projection="orthographic", ortho_width=2.5, shift_x=-0.2, shift_y=0.1),
], ids=["perspective", "orthographic"])
@pytest.mark.parametrize("crop", [None, (9, 5, 40, 30)], ids=["frame", "crop"])
def test14_window_camera_sees_the_frame_pixels_of_its_window(variant, camera, crop):
    """Each pixel of a window's film casts the ray of the frame's pixel it stands for."""
    import mitsuba as mi

    film = S.Film(64, 48, crop=crop)
    settings = S.RenderSettings(spp=1)
    full = mi.load_dict(builder.sensor_dict(camera, S.Film(64, 48), settings))
    for window in [(9, 5, 40, 12), (0, 40, 64, 12), (20, 30, 7, 3)]:  # the second reaches past the bottom edge
        view, window_film = builder.window_camera(camera, film, window)
        assert window_film.size == window[2:] and window_film.crop is None
        sensor = mi.load_dict(builder.sensor_dict(view, window_film, settings))
        x, y, w, h = window
        i, j = np.meshgrid(np.arange(w) + 0.25, np.arange(h) + 0.75)
        rays = {}
        for name, which, (u, v) in (("window", sensor, (i / w, j / h)), ("frame", full, ((x + i) / 64, (y + j) / 48))):
            ray, _ = which.sample_ray(0.0, 0.5, mi.Point2f(u.ravel(), v.ravel()), mi.Point2f(0.5))
            rays[name] = np.array(ray.o), np.array(ray.d)
        np.testing.assert_allclose(rays["window"][0], rays["frame"][0], atol=2e-5)
        np.testing.assert_allclose(rays["window"][1], rays["frame"][1], atol=2e-5)


def test15_strip_windows_cover_the_window_with_equal_strips():
    assert interactive.strip_windows(S.Film(960, 540), 1 << 17) == [(0, 135 * k, 960, 135) for k in range(4)]
    strips = interactive.strip_windows(S.Film(64, 48, crop=(3, 7, 50, 33)), 50 * 8)
    assert [s[1] for s in strips] == [7, 14, 21, 28, 35] and {s[3] for s in strips} == {7}  # 35 rows for 33
    assert interactive.strip_windows(S.Film(64, 48), 0) == [(0, 0, 64, 48)]
    assert interactive.strip_windows(S.Film(4, 3), 1) == [(0, k, 4, 1) for k in range(3)]


def test16_strips_complete_a_pass_before_the_image_changes_and_reproduce_exactly(variant):
    """Five strips a pass: the preview stays until all five are done; reruns give the same images."""
    def run(renders):
        session = interactive.Session(plate_scene(), SETTINGS, samples=SAMPLES, strip_pixels=64 * 10)
        results = [session.step(0.0)]
        assert session.showing_preview and session.stats["strips"] == 5
        for _ in range(renders):
            results.append(session.step(0.0))
        stats = session.stats
        session.close()
        return results, stats
    results, stats = run(10)
    assert stats["passes"] == 11 and stats["spp_done"] == 2  # preview, then two passes of five strips
    assert all(result is results[0] for result in results[1:5])  # strips of the first pass: still the preview
    assert results[5].spp_done == 1 and not np.array_equal(results[5].image, results[0].image)
    assert all(result is results[5] for result in results[6:10]) and results[10].spp_done == 2
    again, _ = run(10)
    assert all(np.array_equal(a.image, b.image) for a, b in zip(results, again))


def test17_strips_estimate_the_whole_pass_image(variant):
    """Strip and whole-pass sessions (other samples) agree band by band within their noise (5 sigma)."""
    spp = 32
    description = dataclasses.replace(plate_scene(), materials={"scratched": S.Diffuse((0.5, 0.5, 0.5))})
    images = {}
    for strip_pixels in (0, 64 * 10):
        session = interactive.Session(description, SETTINGS, samples=spp, strip_pixels=strip_pixels)
        images[strip_pixels] = finish(session).image[..., :3]
        session.close()
    difference = images[64 * 10] - images[0]
    for band in range(0, 48, 8):  # a strip out of place shows as a band whose difference is no noise
        values = difference[band:band + 8].ravel()
        assert abs(values.mean()) < 5.0 * values.std() / np.sqrt(values.size) + 1e-6, band
    assert abs(images[64 * 10].mean() / images[0].mean() - 1.0) < 0.02


def test18_strip_sessions_take_updates_in_place_and_compile_nothing(variant):
    """Camera moves and new scratch sets in a strip session: the rebuilt strip session's image, no kernels."""
    strips = dict(samples=SAMPLES, strip_pixels=64 * 10)
    session = interactive.Session(plate_scene(), SETTINGS, **strips)
    finish(session)
    kernels = session.stats["kernels_compiled"]
    camera = S.Camera(camera_at((0.2, -0.1, 3.0)), fov_x_deg=52, shift_x=0.03)
    new_set = scratches(300, seed=5)
    session.set_camera(camera)
    session.set_scratches("scratched", new_set)
    image = finish(session).image
    assert session.stats["kernels_compiled"] == kernels and session.stats["rebuilds"] == 0
    session.close()
    description = plate_scene(camera)
    metal = dataclasses.replace(description.materials["scratched"], scratches=new_set)
    rebuilt = interactive.Session(dataclasses.replace(description, materials={"scratched": metal}), SETTINGS,
                                  **strips)
    assert np.array_equal(image, finish(rebuilt).image)
    rebuilt.close()
