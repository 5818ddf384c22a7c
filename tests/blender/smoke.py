"""The smoke set of `make test-blender`, run inside one Blender (a pip ``bpy`` module) by tests/blender/matrix.py.

``python smoke.py RIGHT_ZIP WRONG_ZIP WORK_FOLDER`` installs the extension zip built for this Blender's Python
the way a user does (``extensions.package_install_files``, wheels included) into the user folder that
``BLENDER_USER_RESOURCES`` names, after checking that the zip for the other Python is refused, then runs:
Generate, a painted stroke, F12 with each world type (none, colour, environment, every sky type of this
Blender, the single-scattering sky against Cycles), Export + the command line's render of the folder, a
Rendered-viewport session, and finally ends the process while a viewport pass is in flight.  One line per
step: ``SMOKE <step> ok|FAIL <seconds> <detail>``; the process's exit status is the last check (a crash or
an abort at exit is a failure the orchestrator sees).  Written for the bpy APIs of Blender 4.2 to 5.x.
"""
from __future__ import annotations

import importlib
import math
import os
import subprocess
import sys
import time
import traceback
from pathlib import Path
from types import SimpleNamespace

import bpy

RIGHT_ZIP, WRONG_ZIP, WORK = Path(sys.argv[-3]), Path(sys.argv[-2]), Path(sys.argv[-1])
ENVIRONMENT_BEFORE = dict(os.environ)
FAILURES: list[str] = []
SIZE = (32, 24)


def step(name):
    """Run the decorated function now as one smoke step and print its line."""
    def run(function):
        began = time.perf_counter()
        try:
            detail = function() or ""
            print(f"SMOKE {name} ok {time.perf_counter() - began:.1f} {detail}", flush=True)
        except Exception as error:  # noqa: BLE001 - every step reports, the next one still runs
            traceback.print_exc()
            FAILURES.append(name)
            print(f"SMOKE {name} FAIL {time.perf_counter() - began:.1f} {type(error).__name__}: {error}", flush=True)
        return function
    return run


def check(condition, message):
    if not condition:
        raise AssertionError(message)


def site_packages() -> Path:
    return Path(bpy.utils.user_resource("EXTENSIONS")) / ".local" / "lib" / \
        ("python%d.%d" % sys.version_info[:2]) / "site-packages"


def extension(module: str):
    """A module of the installed extension (``bl_ext.user_default.scratch_iridescence.<module>``)."""
    return importlib.import_module(f"bl_ext.user_default.scratch_iridescence.{module}")


def mean_of(path: Path) -> float:
    """Mean of an image file's RGB, read by Blender."""
    image = bpy.data.images.load(str(path))
    pixels = list(image.pixels)
    bpy.data.images.remove(image)
    rgb = [value for i, value in enumerate(pixels) if i % 4 != 3]
    return sum(rgb) / len(rgb)


def nodes_of(id_data):
    if hasattr(id_data, "use_nodes") and not id_data.use_nodes:
        id_data.use_nodes = True  # 4.x; 5.x worlds and materials always have their node tree
    return id_data.node_tree


def fresh_scene(engine="MITSUBA_SCRATCH"):
    # Not read_factory_settings: its factory preferences would disable the installed extension
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = engine
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    if engine == "MITSUBA_SCRATCH":
        scene.scratch_iridescence.samples = 16
    return scene


def add(scene, data, name, location=(0, 0, 0), rotation=(0, 0, 0)):
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler = location, rotation
    return obj


def studio(scene, world=None):
    """A 2 m grey plane, a camera 3 m above looking down, a point light; ``world`` builds the world."""
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    material = bpy.data.materials.new("Grey")
    tree = nodes_of(material)
    tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1)
    plane.data.materials.append(material)
    scene.camera = add(scene, bpy.data.cameras.new("Camera"), "Camera", (0, 0, 3))
    light = bpy.data.lights.new("Lamp", "POINT")
    light.energy = 200.0
    add(scene, light, "Lamp", (0.3, 0.5, 2.0))
    if world is not None:
        scene.world = bpy.data.worlds.new("World")
        world(nodes_of(scene.world))
    return plane


def scratched_studio():
    """:func:`studio` under a coloured world, its plane holding 200 generated scratches; returns the scene."""
    scene = fresh_scene()
    bpy.context.view_layer.objects.active = studio(scene, colour_world)
    bpy.ops.scratch.generate("EXEC_DEFAULT", count=200, seed=3)
    return scene


def render(scene, name) -> Path:
    path = WORK / f"{name}.exr"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    check(path.is_file(), f"{path.name} was not written")
    return path


# ---------------------------------------------------------------------------------------------- install
print(f"BLENDER {bpy.app.version_string} Python {sys.version.split()[0]}", flush=True)


@step("wrong-zip-refused")
def _():
    # The other Python's zip (its blender_version_min/max exclude this Blender) must not install.  Blender
    # prints why ("doesn't meet the minimum supported version") and its operator still returns FINISHED.
    check(WRONG_ZIP.is_file() and RIGHT_ZIP.is_file(), f"{WRONG_ZIP} or {RIGHT_ZIP} missing")
    try:
        bpy.ops.extensions.package_install_files(filepath=str(WRONG_ZIP), repo="user_default",
                                                 enable_on_install=True)
    except RuntimeError:
        pass
    check(not (Path(bpy.utils.user_resource("EXTENSIONS")) / "user_default" / "scratch_iridescence").exists(),
          "files of the refused zip were installed")
    check(bpy.types.RenderEngine.bl_rna_get_subclass_py("MITSUBA_SCRATCH") is None, "its engine is registered")


@step("install")
def _():
    result = bpy.ops.extensions.package_install_files(filepath=str(RIGHT_ZIP), repo="user_default",
                                                      enable_on_install=True)
    check(result == {"FINISHED"}, result)
    engine = bpy.types.RenderEngine.bl_rna_get_subclass_py("MITSUBA_SCRATCH")
    check(engine is not None and engine.__module__.startswith("bl_ext.user_default.scratch_iridescence"),
          "the engine is not registered from the installed extension")
    names = sorted(path.name for path in site_packages().iterdir())
    running = "cpython-%d%d" % sys.version_info[:2]
    foreign = [name for name in names if "cpython-3" in name and running not in name]
    for package in ("drjit", "mitsuba"):
        foreign += [p.name for p in (site_packages() / package).iterdir() if "cpython-3" in p.name
                    and running not in p.name]
    check(not foreign, f"binaries of another Python installed: {foreign}")
    wheels = sorted(name.split("-")[0] for name in names if name.endswith(".dist-info"))
    return " ".join(wheels)


# ---------------------------------------------------------------------------------------------- editing
@step("generate")
def _():
    fresh_scene()
    check(bpy.types.RenderEngine.bl_rna_get_subclass_py("MITSUBA_SCRATCH") is not None, "the engine is gone")
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    result = bpy.ops.scratch.generate("EXEC_DEFAULT", count=200, seed=3)
    check(result == {"FINISHED"}, result)
    count = extension("addon.storage").read_scratches(bpy.context.active_object).count
    check(count >= 200, f"{count} scratches stored")
    return f"{count} scratches"


@step("paint-stroke")
def _():
    obj = bpy.context.active_object
    before = extension("addon.storage").read_scratches(obj).count
    points = [(-0.8 + 0.1 * i, 0.3 * math.sin(0.2 * i), 0.0) for i in range(15)]
    stroke = [{"name": "", "location": p, "mouse": (0.0, 0.0), "mouse_event": (0.0, 0.0), "pressure": 1.0,
               "size": 0.0, "x_tilt": 0.0, "y_tilt": 0.0, "time": float(i), "is_start": i == 0}
              for i, p in enumerate(points)]
    if "pen_flip" in bpy.types.OperatorStrokeElement.bl_rna.properties:  # Blender 4.x (gone in 5.0)
        stroke = [{**element, "pen_flip": False} for element in stroke]
    result = bpy.ops.scratch.paint_stroke("EXEC_DEFAULT", True, stroke=stroke, seed=1)
    check(result == {"FINISHED"}, result)
    after = extension("addon.storage").read_scratches(obj).count
    check(after == before + 1, f"{before} -> {after} scratches")
    return f"{before} -> {after} scratches"


# ---------------------------------------------------------------------------------------------- F12
def colour_world(tree):
    tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)


def environment_world(tree):
    image = bpy.data.images.new("Sky", 16, 8, alpha=False, float_buffer=True)
    image.pixels.foreach_set([0.6 if i % 4 != 2 else 0.9 for i in range(16 * 8 * 4)])
    image.pack()
    node = tree.nodes.new("ShaderNodeTexEnvironment")
    node.image = image
    tree.links.new(node.outputs["Color"], tree.nodes["Background"].inputs["Color"])


def sky_world(kind, elevation_deg=45.0):
    def build(tree):
        node = tree.nodes.new("ShaderNodeTexSky")
        node.sky_type = kind
        node.sun_elevation = math.radians(elevation_deg)
        node.sun_direction = (0.0, math.cos(math.radians(elevation_deg)), math.sin(math.radians(elevation_deg)))
        tree.links.new(node.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    return build


SKY_TYPES = [item.identifier for item in bpy.types.ShaderNodeTexSky.bl_rna.properties["sky_type"].enum_items]
WORLDS = {"no-world": None, "colour": colour_world, "environment": environment_world,
          **{f"sky-{kind.lower()}": sky_world(kind) for kind in SKY_TYPES}}
F12_MEANS = {}

for world_name, world in WORLDS.items():
    @step(f"f12-{world_name}")
    def _(world_name=world_name, world=world):
        scene = fresh_scene()
        studio(scene, world)
        mean = mean_of(render(scene, f"f12-{world_name}"))
        check(0.0 < mean < 1e4 and mean == mean, f"mean {mean}")
        F12_MEANS[world_name] = mean
        return f"mean {mean:.4f}"


SINGLE_SCATTERING = "NISHITA" if "NISHITA" in SKY_TYPES else "SINGLE_SCATTERING"


@step(f"sky-{SINGLE_SCATTERING.lower()}-vs-cycles")
def _():
    # The floor lit by this Blender's single-scattering sky (4.x: NISHITA), direct light only, against Cycles:
    # tests/addon/test_render_lights.py's check with 5.0 (10 %), here with every Blender of the matrix.
    import addon_utils

    addon_utils.enable("cycles", default_set=True)
    radiance = {}
    for engine in ("MITSUBA_SCRATCH", "CYCLES"):
        scene = fresh_scene(engine)
        scene.render.resolution_x = scene.render.resolution_y = 9
        if engine == "CYCLES":
            scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.max_bounces = 512, False, 0
        else:
            scene.scratch_iridescence.samples, scene.scratch_iridescence.max_depth = 1024, 2
        scene.camera = add(scene, bpy.data.cameras.new("Camera"), "Camera", (0, 0, 1.5))
        scene.camera.data.type, scene.camera.data.ortho_scale = "ORTHO", 0.1
        bpy.ops.mesh.primitive_plane_add(size=20.0)
        material = bpy.data.materials.new("Grey")
        tree = nodes_of(material)
        tree.nodes.remove(tree.nodes["Principled BSDF"])
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
        tree.links.new(diffuse.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
        bpy.context.active_object.data.materials.append(material)
        scene.world = bpy.data.worlds.new("World")
        sky_world(SINGLE_SCATTERING)(nodes_of(scene.world))
        radiance[engine] = mean_of(render(scene, f"sky-{engine.lower()}"))
    ratio = radiance["MITSUBA_SCRATCH"] / radiance["CYCLES"]
    check(abs(ratio - 1.0) < 0.10, f"Mitsuba / Cycles = {ratio:.3f}")
    return f"Mitsuba / Cycles = {ratio:.3f}"


# ---------------------------------------------------------------------------------------------- export + CLI
@step("export-and-cli-render")
def _():
    scene = scratched_studio()
    scene.scratch_iridescence.samples = 256
    f12 = mean_of(render(scene, "export-f12"))
    folder = WORK / "export"
    result = bpy.ops.scratch.export_mitsuba(directory=str(folder))
    check(result == {"FINISHED"} and (folder / "scene.xml").is_file(), result)
    # The command line of the installed extension, in this Blender's Python with the extension's wheels
    repository = Path(bpy.utils.user_resource("EXTENSIONS")) / "user_default"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(repository), str(site_packages())])}
    child = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(folder),
                            "-o", str(WORK / "cli.exr"), "-q"], capture_output=True, text=True, env=env,
                           timeout=900)
    check(child.returncode == 0, child.stdout + child.stderr)
    cli = mean_of(WORK / "cli.exr")
    check(abs(cli / f12 - 1.0) < 0.03, f"CLI mean {cli:.4f} against F12 {f12:.4f}")
    return f"CLI / F12 = {cli / f12:.4f}"


# ---------------------------------------------------------------------------------------------- viewport
VIEWPORT = []


@step("viewport-session")
def _():
    scene = scratched_studio()
    scene.scratch_iridescence.viewport_samples = 100000  # passes go on until the process ends
    depsgraph = bpy.context.evaluated_depsgraph_get()
    camera = scene.camera
    region_data = SimpleNamespace(view_matrix=camera.matrix_world.inverted(), is_perspective=True,
                                  window_matrix=camera.calc_matrix_camera(depsgraph, x=SIZE[0], y=SIZE[1]))
    context = SimpleNamespace(region=SimpleNamespace(width=SIZE[0], height=SIZE[1]), region_data=region_data)
    viewport = extension("addon.render.viewport").ViewportRender()
    VIEWPORT.append(viewport)
    viewport.view_update(context, depsgraph)
    end = time.monotonic() + 600
    while time.monotonic() < end:
        progress, _, _, error, _ = viewport.latest()
        check(error is None, error)
        if progress is not None and progress.spp_done >= 4:
            break
        time.sleep(0.05)
    check(progress is not None and progress.spp_done >= 4, "no image after 600 s")
    mean = float(progress.image[..., :3].mean())
    check(mean > 0.0, "a black viewport image")
    return f"{progress.spp_done} spp, mean {mean:.4f}"


@step("environment-unchanged")
def _():
    changed = sorted(key for key in set(ENVIRONMENT_BEFORE) | set(os.environ)
                     if ENVIRONMENT_BEFORE.get(key) != os.environ.get(key))
    check(not changed, f"changed: {changed}")


@step("bundled-llvm")
def _():
    import drjit

    version = drjit.detail.llvm_version()
    check(str(site_packages()) in str(Path(sys.modules["mitsuba"].__file__).resolve()), "Mitsuba not the bundled one")
    return f"LLVM {'.'.join(map(str, version))}"


print(f"SMOKE-FAILURES {len(FAILURES)} {' '.join(FAILURES)}", flush=True)
print("EXITING with a viewport pass in flight" if VIEWPORT else "EXITING", flush=True)
sys.exit(1 if FAILURES else 0)
