"""The Rendered viewport: view camera, depsgraph classifier on real edits, and the engine's sync and draw paths.

Headless Blender has no 3D view: the ``region``/``region_data`` a window would
pass are replaced by :class:`View`, which carries the real matrices Blender
computes for a camera (``matrix_world`` and ``calc_matrix_camera``).
"""
import math
import time
from types import SimpleNamespace

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from strokes import stroke  # noqa: E402
from render_scenes import (add_camera, add_light, material, set_world, setup_render,  # noqa: E402
                           store_unfittable_scratches)
from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.addon.render import sync  # noqa: E402
from scratch_iridescence.addon.render.gather import Warnings, gather_scene  # noqa: E402
from scratch_iridescence.addon.render.gather.camera import gather_camera  # noqa: E402
from scratch_iridescence.addon.render.view import view_camera  # noqa: E402
from scratch_iridescence.addon.render.viewport import ViewportRender, coalesce  # noqa: E402
from scratch_iridescence.mitsuba_bridge import scene as S  # noqa: E402
from scratch_iridescence.mitsuba_bridge.render.session import Change, Update  # noqa: E402

WIDTH, HEIGHT = 64, 48


def view_of(camera_object, width=WIDTH, height=HEIGHT):
    """What ``view_update``/``view_draw`` read from a 3D view looking through ``camera_object``."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    window = camera_object.calc_matrix_camera(depsgraph, x=width, y=height)
    region_data = SimpleNamespace(view_matrix=camera_object.matrix_world.inverted(), window_matrix=window,
                                  is_perspective=camera_object.data.type == "PERSP")
    return SimpleNamespace(region=SimpleNamespace(width=width, height=height), region_data=region_data)


def wait_for(viewport, condition, timeout=120.0):
    """Wait until ``condition()`` holds (the viewport's worker thread gets there), at most ``timeout`` s."""
    end = time.monotonic() + timeout
    while not condition() and time.monotonic() < end:
        time.sleep(0.05)
    assert condition(), viewport.latest()[3]


class Recorder:
    """The calls ``view_draw`` makes on the engine."""

    def __init__(self):
        self.stats, self.redraws, self.bound = [], 0, 0

    def update_stats(self, stats, info):
        self.stats.append(info)

    def tag_redraw(self):
        self.redraws += 1

    def bind_display_space_shader(self, scene):
        self.bound += 1

    def unbind_display_space_shader(self):
        pass


@pytest.fixture
def studio(scratched_plane):
    """The scratched plane under a point light and a grey world, a camera 3 m above, a diffuse cube aside."""
    scene = setup_render(bpy.context.scene, WIDTH, HEIGHT)
    scene.scratch_iridescence.viewport_samples = 4
    camera = add_camera(scene, location=(0, 0, 3))
    light = add_light(scene, "POINT", location=(0.3, 0.5, 2.0), energy=200.0)
    set_world(scene, colour=(0.1, 0.1, 0.1))
    bpy.ops.mesh.primitive_cube_add(size=0.2, location=(1.5, 0, 0.1))
    cube = bpy.context.active_object
    cube.data.materials.append(material("Paint", Color=(0.8, 0.2, 0.1, 1.0)))
    bpy.context.view_layer.objects.active = scratched_plane
    return SimpleNamespace(scene=scene, camera=camera, light=light, plane=scratched_plane, cube=cube)


@pytest.fixture
def updates_of(studio):
    """``updates_of(edit)`` runs ``edit`` and returns what the classifier makes of the depsgraph update."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    state = sync.snapshot(depsgraph, gather_scene(depsgraph, view=(S.Camera(np.eye(4)), S.Film(WIDTH, HEIGHT))))
    seen = []

    def handler(scene, depsgraph):
        seen.append(sync.classify(depsgraph, state))

    bpy.app.handlers.depsgraph_update_post.append(handler)

    def run(edit):
        seen.clear()
        edit()
        bpy.context.view_layer.update()
        return [update for updates in seen for update in updates]

    yield run
    bpy.app.handlers.depsgraph_update_post.remove(handler)


def test01_view_camera_matches_the_scene_camera_seen_through_the_view(studio):
    camera = studio.camera
    camera.location, camera.rotation_euler = (0.4, -2.0, 1.5), (math.radians(60), 0, math.radians(10))
    camera.data.lens, camera.data.shift_x, camera.data.shift_y = 35.0, 0.1, -0.05
    bpy.context.view_layer.update()
    view = view_of(camera)
    seen = view_camera(view.region_data.view_matrix, view.region_data.window_matrix, True)
    expected = gather_camera(studio.scene, camera, Warnings())
    assert seen.projection == "perspective"
    assert np.allclose(seen.to_world, expected.to_world, atol=1e-5)
    assert seen.fov_x_deg == pytest.approx(expected.fov_x_deg, rel=1e-5)
    assert (seen.shift_x, seen.shift_y) == pytest.approx((expected.shift_x, expected.shift_y), abs=1e-6)
    assert (seen.near, seen.far) == pytest.approx((expected.near, expected.far), rel=1e-3)


def test02_orthographic_view_keeps_width_and_shift_and_starts_in_front(studio):
    camera = studio.camera
    camera.data.type, camera.data.ortho_scale, camera.data.shift_x = "ORTHO", 3.0, 0.2
    bpy.context.view_layer.update()
    view = view_of(camera)
    seen = view_camera(view.region_data.view_matrix, view.region_data.window_matrix, False)
    expected = gather_camera(studio.scene, camera, Warnings())
    assert seen.projection == "orthographic"
    assert seen.ortho_width == pytest.approx(expected.ortho_width, rel=1e-6)
    assert seen.shift_x == pytest.approx(expected.shift_x, abs=1e-6)
    assert np.allclose(seen.to_world, expected.to_world, atol=1e-5)
    # Blender's own orthographic 3D views clip from behind their origin (near = -far/2): the camera
    # moves back along its axis until the near plane is just in front of it, the far plane moves along.
    near, far, half = -5.0, 10.0, 1.5
    window = np.diag([1 / half, 1 / half * 4 / 3, -2 / (far - near), 1.0])
    window[2, 3] = -(far + near) / (far - near)
    behind = view_camera(np.eye(4), window, False)
    assert 0 < behind.near < 1e-3 * far and behind.far == pytest.approx(far - near + behind.near)
    assert np.allclose(behind.to_world[:3, 3], (0, 0, -near + behind.near))


def test03_moving_an_object_is_a_transform_of_its_shape(studio, updates_of):
    updates = updates_of(lambda: setattr(studio.cube, "location", (1.0, 0.5, 0.2)))
    assert [u.change.value for u in updates] == ["transform"]
    name, matrix = updates[0].args
    assert name == "Cube" and np.allclose(matrix[:3, 3], (1.0, 0.5, 0.2))


def test04_a_pen_stroke_is_a_scratch_update_of_the_object(studio, updates_of):
    before = storage.read_scratches(studio.plane).count
    points = [(-0.5, -0.3, 0.0), (0.0, 0.1, 0.0), (0.5, 0.2, 0.0)]
    updates = updates_of(lambda: bpy.ops.scratch.paint_stroke("EXEC_DEFAULT", True, stroke=stroke(points), seed=1))
    assert [u.change.value for u in updates] == ["scratches"]
    key, scratches = updates[0].args
    assert key == "scratches:Plane" and scratches.count == before + 1


def test05_generate_import_and_undo_are_scratch_updates(studio, updates_of, tmp_path):
    bpy.ops.ed.undo_push(message="before")
    assert [u.change.value for u in updates_of(lambda: bpy.ops.scratch.generate("EXEC_DEFAULT", True, count=30, seed=2))] == ["scratches"]
    undone = updates_of(lambda: bpy.ops.ed.undo())
    assert [u.change.value for u in undone] == ["scratches"] and undone[0].args[1].count == 50
    path = tmp_path / "set.npz"
    bpy.ops.scratch.export_file(filepath=str(path))
    imported = updates_of(lambda: bpy.ops.scratch.import_file(filepath=str(path), mode="ADD"))
    assert [u.change.value for u in imported] == ["scratches"] and imported[0].args[1].count == 100


def test06_light_world_and_material_values_update_in_place(studio, updates_of):
    updates = updates_of(lambda: setattr(studio.light.data, "energy", 400.0))
    assert [u.change.value for u in updates] == ["light"]
    index, light = updates[0].args
    assert index == 0 and light.intensity[0] == pytest.approx(400.0 / (4 * math.pi), rel=1e-6)
    background = studio.scene.world.node_tree.nodes["Background"]
    updates = updates_of(lambda: background.inputs["Color"].default_value.__setitem__(0, 0.5))
    assert [u.change.value for u in updates] == ["world"] and updates[0].args[0].radiance[0] == pytest.approx(0.5)
    paint = bpy.data.materials["Paint"].node_tree.nodes["Diffuse BSDF"]
    updates = updates_of(lambda: paint.inputs["Color"].default_value.__setitem__(1, 0.6))
    assert [u.change.value for u in updates] == ["material"]
    assert updates[0].args[0] == "material:Paint" and updates[0].args[1].reflectance[1] == pytest.approx(0.6)


def test07_scratch_material_settings_update_the_bsdf(studio, updates_of):
    updates = updates_of(lambda: setattr(studio.plane.scratch_iridescence, "coherent", not studio.plane.scratch_iridescence.coherent))
    assert [u.change.value for u in updates] == ["material"]
    updates = updates_of(lambda: setattr(studio.plane.scratch_iridescence, "crossings", "height_field"))
    assert [u.change.value for u in updates] == ["material"] and updates[0].args[1].crossings == "height_field"


def test08_edits_without_a_cheaper_form_rebuild(studio, updates_of):
    def move_vertex():
        studio.cube.data.vertices[0].co.x += 0.05
        studio.cube.data.update()

    assert updates_of(move_vertex) == [Update(Change.BUILD)]
    assert updates_of(lambda: bpy.ops.scratch.clear()) == [Update(Change.BUILD)]  # no longer a scratch BSDF
    assert updates_of(lambda: setattr(studio.cube, "hide_render", True)) == [Update(Change.BUILD)]
    assert updates_of(lambda: setattr(studio.scene.scratch_iridescence, "max_depth", 3)) == [Update(Change.BUILD)]


def test09_coalescing_keeps_the_last_build_and_the_last_camera():
    build, camera1, camera2 = Update(Change.BUILD, (1,)), Update(Change.CAMERA, (1,)), Update(Change.CAMERA, (2,))
    light = Update(Change.LIGHT, (0, None))
    assert coalesce([light, build, camera1, light, camera2]) == [build, light, camera2]


def test10_engine_paths_build_update_draw_and_stop(studio):
    """view_update builds, a move reaches the session as a transform, view_draw gets as far as the GPU."""
    pytest.importorskip("mitsuba")
    viewport = ViewportRender()
    engine, context = Recorder(), view_of(studio.camera)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    viewport.view_update(context, depsgraph)

    def wait(condition):
        wait_for(viewport, condition)

    wait(lambda: viewport.latest()[2])
    progress, _, finished, error, stats = viewport.latest()
    assert error is None and progress.image.shape == (HEIGHT, WIDTH, 4) and progress.spp_done == 4
    assert progress.image[..., :3].mean() > 0.0
    kernels = stats["kernels_compiled"]

    handler = lambda scene, depsgraph: viewport.view_update(context, depsgraph)  # noqa: E731 (as Blender calls it)
    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        studio.cube.location.x = 1.2
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)
    wait(lambda: viewport.latest()[4].get("last_update") == "transform" and viewport.latest()[2])
    assert viewport.latest()[4]["rebuilds"] == 0

    studio.camera.location.x = 0.3  # the view moves: view_draw posts the camera, then tries to draw
    bpy.context.view_layer.update()
    viewport.view_draw(engine, view_of(studio.camera), depsgraph)
    assert "background mode" in viewport.draw_error  # gpu is unavailable headless; all before it ran
    assert engine.stats and engine.stats[-1].startswith("Mitsuba | Sample")
    wait(lambda: viewport.latest()[4].get("last_update") == "camera" and viewport.latest()[2])
    assert viewport.latest()[4]["kernels_compiled"] == kernels  # a move and a camera: nothing compiled
    assert max(viewport.main_thread_seconds) < 5.0  # the build's gather; bench_viewport measures the real figure
    viewport.stop()
    assert viewport.join(timeout=30.0)


def test10b_a_user_error_is_shown_in_the_viewport_without_a_traceback(studio, capfd):
    """Scratch tables no machine holds (a thousand scratches 2·10⁴ UV units long, within the format's bounds):
    the viewport shows what they need, the console no traceback (there is no bug to report), Blender goes on."""
    pytest.importorskip("mitsuba")
    store_unfittable_scratches(studio.plane)
    viewport = ViewportRender()
    capfd.readouterr()
    viewport.view_update(view_of(studio.camera), bpy.context.evaluated_depsgraph_get())
    wait_for(viewport, lambda: viewport.latest()[3] is not None)
    error = viewport.latest()[3]
    assert error.startswith("Mitsuba Scratch viewport: building the tables of 1,000 scratches needs about 298.0 GiB"), \
        error
    assert "Traceback" not in capfd.readouterr().err
    viewport.stop()
    assert viewport.join(timeout=30.0)


def test11_camera_view_with_a_render_border_renders_only_the_border(studio):
    """The border's fractions of the camera frame become the film's crop window, as Cycles renders it."""
    view = view_of(studio.camera)  # the frame fills the region: same aspect as the render resolution
    render = studio.scene.render
    render.border_min_x, render.border_max_x, render.border_min_y, render.border_max_y = 0.25, 0.75, 0.5, 1.0
    render.use_border = True
    _, film = ViewportRender._region_view(view, studio.scene)
    assert film.crop is None  # not a camera view: the whole region
    view.region_data.view_perspective = "CAMERA"
    _, film = ViewportRender._region_view(view, studio.scene)
    # x from 16 to 48 of 64; y from 24 to 48 of 48 counted from the bottom, so rows 0-24 from the top
    assert (film.width, film.height, film.crop) == (WIDTH, HEIGHT, (16, 0, 32, 24))
    # zoomed out camera view (the frame fills the middle half of a twice larger region): the same border
    zoom = np.diag([0.5, 0.5, 1.0, 1.0])
    view.region_data.window_matrix = zoom @ np.asarray(view.region_data.window_matrix)
    view.region.width, view.region.height = 2 * WIDTH, 2 * HEIGHT
    _, film = ViewportRender._region_view(view, studio.scene)
    assert film.crop == (WIDTH // 2 + 16, HEIGHT // 2, 32, 24)
    render.use_border = False
    assert ViewportRender._region_view(view, studio.scene)[1].crop is None

    pytest.importorskip("mitsuba")
    render.use_border = True
    view = view_of(studio.camera)
    view.region_data.view_perspective = "CAMERA"
    viewport = ViewportRender()
    viewport.view_update(view, bpy.context.evaluated_depsgraph_get())
    end = time.monotonic() + 120.0
    while not viewport.latest()[2] and time.monotonic() < end:
        time.sleep(0.05)
    progress, _, _, error, _ = viewport.latest()
    assert error is None and progress.image.shape == (24, 32, 4)
    viewport.stop()
    assert viewport.join(timeout=30.0)


def test12_f12_beside_the_rendered_viewport_takes_its_scratch_tables(studio, tmp_path):
    """F12 while the viewport shows the same scratched object builds no scratch tables: it takes the
    viewport's (mitsuba_bridge/bsdf/persistent.py), also without Persistent Data."""
    pytest.importorskip("mitsuba")
    from scratch_iridescence.mitsuba_bridge.bsdf import persistent

    viewport = ViewportRender()
    viewport.view_update(view_of(studio.camera), bpy.context.evaluated_depsgraph_get())
    wait_for(viewport, lambda: viewport.latest()[2])
    before = persistent.statistics()
    studio.scene.render.use_persistent_data = False
    studio.scene.render.filepath = str(tmp_path / "final")
    bpy.ops.render.render(write_still=True)
    after = persistent.statistics()
    viewport.stop()
    assert viewport.join(timeout=30.0)
    assert len(list(tmp_path.glob("final.*"))) == 1  # the render was written
    assert (after["built"] - before["built"], after["reused"] - before["reused"]) == (0, 1)


def test13_final_renders_and_viewport_passes_take_turns():
    """A final render waits for the viewport pass in progress (and says so once), viewports wait while it
    renders, then go on; two viewports step one at a time (turns.py: Dr.Jit traces every BSDF in the
    process, a half-made one too)."""
    import threading

    from scratch_iridescence.addon.render import turns

    events, waits = [], []
    pass_started, end_pass = threading.Event(), threading.Event()

    def viewport_pass(name, started=None, until=None):
        with turns.viewport_turn():
            events.append(name + " starts")
            if started is not None:
                started.set()
            if until is not None:
                until.wait(30)
            events.append(name + " ends")

    first = threading.Thread(target=viewport_pass, args=("pass 1", pass_started, end_pass))
    first.start()
    assert pass_started.wait(30)

    def final_render():
        with turns.viewports_paused(lambda: waits.append(turns.state())):
            events.append("F12 starts")
            second = threading.Thread(target=viewport_pass, args=("pass 2",))
            second.start()
            second.join(0.3)
            assert second.is_alive()  # waits for the final render
            events.append("F12 ends")
        second.join(30)

    f12 = threading.Thread(target=final_render)
    f12.start()
    f12.join(0.3)
    assert f12.is_alive() and "F12 starts" not in events  # waits for pass 1
    end_pass.set()
    f12.join(30)
    first.join(30)
    assert events == ["pass 1 starts", "pass 1 ends", "F12 starts", "F12 ends", "pass 2 starts", "pass 2 ends"]
    assert waits == [{"final_renders": 1, "viewports_working": 1, "viewports_waiting": 0}]

    # two viewports in Rendered shading: one step at a time, and both get their turns
    inside, most, steps = [0], [0], {"A": 0, "B": 0}

    def viewport(name):
        for _ in range(40):
            with turns.viewport_turn():
                inside[0] += 1
                most[0] = max(most[0], inside[0])
                steps[name] += 1
                time.sleep(0.001)
                inside[0] -= 1

    workers = [threading.Thread(target=viewport, args=(name,)) for name in steps]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(60)
    assert most == [1] and steps == {"A": 40, "B": 40}
    assert turns.state() == {"final_renders": 0, "viewports_working": 0, "viewports_waiting": 0}
