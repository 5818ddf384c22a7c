"""The repository is an extension package with a Blender-free half (issue: foundation)."""
import ast
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


#: Packages that must work without Blender: every module in them imports with bpy blocked.
BLENDER_FREE = ["scratch_iridescence.mitsuba_bridge", "scratch_iridescence.addon.geometry"]
BLENDER_MODULES = ("bpy", "mathutils", "gpu", "bmesh", "bpy_extras", "gpu_extras")


#: Source for a fresh interpreter: a meta-path finder that refuses Blender's modules (imports ``sys`` first).
BLOCK_BLENDER = f"""class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {BLENDER_MODULES!r}:
            raise ImportError('blocked: ' + name)
sys.meta_path.insert(0, Block())
"""


@pytest.mark.parametrize("package", BLENDER_FREE)
def test_blender_free_packages_import_with_bpy_unavailable(package):
    # A meta-path finder that refuses Blender's modules, in a fresh interpreter; every module of the
    # package is found by walking its folder, so a new module is covered without editing a list.
    code = f"""
import sys, importlib, pkgutil
{BLOCK_BLENDER}package = importlib.import_module({package!r})
names = [info.name for info in pkgutil.walk_packages(package.__path__, {package!r} + '.')]
for name in names:
    importlib.import_module(name)
assert not any(m.split('.')[0] == 'bpy' for m in sys.modules)
print(len(names))
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) >= 8


def test_the_blender_free_geometry_tests_run_without_blender():
    # tests/addon/conftest.py leaves out only its own Blender tests where bpy is missing: collected with
    # Blender blocked, the geometry tests are all there and nothing else of tests/addon.
    code = f"""
import importlib.util, sys
import pytest
{BLOCK_BLENDER}find_spec = importlib.util.find_spec
importlib.util.find_spec = lambda name, *rest: None if name.split('.')[0] == 'bpy' else find_spec(name, *rest)
sys.exit(pytest.main(['--collect-only', '-q', '-p', 'no:cacheprovider', 'tests/addon']))
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    collected = [line for line in result.stdout.splitlines() if "::" in line]
    assert len(collected) >= 50 and all(line.startswith("tests/addon/geometry/") for line in collected), collected[:5]


def test_importing_mitsuba_bridge_has_no_side_effects():
    code = "import sys, scratch_iridescence.mitsuba_bridge; print('mitsuba' in sys.modules, 'drjit' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert result.stdout.split() == ["False", "False"], result.stderr


def test_the_bridge_has_one_import_name_and_one_plugin_class():
    # From the repository root, where a bare 'mitsuba_bridge' would be found on the path: refused,
    # so no second copy of ScratchSet, SceneDescription or the BSDF class can exist.
    code = """
import sys
try:
    import mitsuba_bridge
except ImportError as error:
    print('refused:', error)
import mitsuba as mi
from scratch_iridescence.mitsuba_bridge.render.activation import activate
from scratch_iridescence.mitsuba_bridge.bsdf import PLUGIN_NAME, plugin
activate('llvm_ad_spectral')
activate('llvm_ad_spectral')
bsdf = mi.load_dict({'type': PLUGIN_NAME})
print('class:', type(bsdf) is plugin.plugin_class())
print('copies:', sorted(m for m in sys.modules if m.split('.')[0] == 'mitsuba_bridge'))
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].startswith("refused: import the bridge as 'scratch_iridescence.mitsuba_bridge'"), lines
    assert lines[1:] == ["class: True", "copies: []"], lines


def _python_files(folder):
    return [p for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts]


@pytest.mark.parametrize("package", ["mitsuba_bridge", "addon", "scenes"])
def test_packages_use_relative_imports_only(package):
    for path in _python_files(package):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            for name in names:
                top = name.split(".")[0]
                assert top not in ("mitsuba_bridge", "addon", "scratch_iridescence"), \
                    f"{path.relative_to(ROOT)} imports {name} absolutely"
                blender_free = path.is_relative_to(ROOT / "mitsuba_bridge") or \
                    path.is_relative_to(ROOT / "addon" / "geometry")
                if blender_free:  # also imports inside functions, which the import test above never runs
                    assert top not in BLENDER_MODULES, \
                        f"{path.relative_to(ROOT)} imports {name}: this folder must not touch Blender"


def test_gather_and_builder_meet_only_in_the_scene_description():
    # Gathering (Blender -> SceneDescription) and building (SceneDescription -> Mitsuba dict) share no
    # helpers: invariants such as orthonormal frames live in mitsuba_bridge/scene/.
    for folder, forbidden in [("addon/render/gather", ("mitsuba_bridge.builder", "mitsuba_bridge.bsdf")),
                              ("mitsuba_bridge/builder", ("addon",))]:
        for path in _python_files(folder):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.ImportFrom):
                    module = (node.module or "").lstrip(".")
                    assert not module.startswith(forbidden), f"{path.relative_to(ROOT)} imports {node.module}"


# ---- the bridge's rooms (docs/architecture.md): which room may import which
#: Room -> the rooms it may import (besides itself), function-level imports included.  ``root`` is the
#: package's ``__init__`` (the bundled libLLVM's set-up, ``register_plugins``), ``errors`` its user errors.
BRIDGE_ROOMS = {
    "errors": set(),
    "device": {"errors"},
    "files": {"errors"},
    "scratch": {"errors", "files"},
    "bsdf/maths": set(),
    "bsdf/tables": {"errors", "device", "files", "scratch"},
    "bsdf": {"errors", "scratch", "bsdf/maths", "bsdf/tables"},
    "scene": {"errors", "scratch", "bsdf"},
    "builder": {"errors", "files", "scratch", "bsdf", "bsdf/tables", "scene"},
    "folder": {"errors", "files", "scratch", "bsdf", "scene", "builder"},
    "render": {"root", "errors", "device", "files", "scratch", "bsdf", "scene", "builder"},
    "validation": {"errors", "device", "scratch", "bsdf", "bsdf/tables", "render"},
    "cluster": {"root", "errors", "device", "files", "folder", "render"},
    "cli": {"errors", "device", "files", "scratch", "scene", "folder", "render", "validation", "cluster"},
    "root": {"device", "bsdf"},
}
#: Modules that must not touch Dr.Jit or Mitsuba, not even inside a function: the tables are built once per set
#: on the host with numpy (docs/architecture.md); device/ and files/ are the floor everything stands on.
NO_JIT = ("bsdf/tables",)


def _bridge_room(module: str) -> str:
    parts = module.split(".")[2:]  # scratch_iridescence.mitsuba_bridge.<room>...
    if not parts or parts == ["__main__"]:
        return "root" if not parts else "cli"
    if parts[0] == "bsdf" and len(parts) > 1 and parts[1] in ("maths", "tables"):
        return f"bsdf/{parts[1]}"
    return parts[0]


def _bridge_imports():
    """``{module: {imported bridge module or package, ...}}`` and ``{module: {top-level outside names}}``, every
    import of every bridge module (function-level ones too), relative names resolved."""
    package = "scratch_iridescence.mitsuba_bridge"
    modules = {}
    for path in _python_files("mitsuba_bridge"):
        relative = path.relative_to(ROOT / "mitsuba_bridge").with_suffix("")
        parts = [p for p in relative.parts if p != "__init__"]
        modules[".".join([package, *parts])] = (path, path.name == "__init__.py")
    inside, outside = {}, {}
    for name, (path, is_package) in modules.items():
        base = name.split(".") if is_package else name.split(".")[:-1]
        found, foreign = set(), set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                foreign.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                foreign.add((node.module or "").split(".")[0])
            elif isinstance(node, ast.ImportFrom):
                target = ".".join(base[:len(base) - node.level + 1] + ([node.module] if node.module else []))
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    found.add(sub if sub in modules else target)
        inside[name], outside[name] = found & modules.keys(), foreign
    return inside, outside


def test_bridge_rooms_import_only_the_rooms_below_them():
    inside, _ = _bridge_imports()
    assert len({_bridge_room(m) for m in inside}) >= 12, sorted({_bridge_room(m) for m in inside})
    wrong = [f"{m} ({_bridge_room(m)}) imports {t} ({_bridge_room(t)})" for m, targets in sorted(inside.items())
             for t in sorted(targets) if _bridge_room(t) != _bridge_room(m)
             and _bridge_room(t) not in BRIDGE_ROOMS[_bridge_room(m)]]
    assert not wrong, "\n".join(wrong)


def test_the_bridge_has_no_import_circles():
    # Function-level imports count: one that closes a circle means a name lives in the wrong room.
    inside, _ = _bridge_imports()
    index, low, stack, on_stack, circles = {}, {}, [], set(), []

    def visit(module):  # Tarjan's strongly connected components
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for target in inside[module]:
            if target not in index:
                visit(target)
                low[module] = min(low[module], low[target])
            elif target in on_stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == module:
                    break
            if len(component) > 1 or module in inside[module]:
                circles.append(sorted(component))

    for module in sorted(inside):
        if module not in index:
            visit(module)
    assert not circles, circles


def test_tables_never_touch_drjit_or_mitsuba():
    _, outside = _bridge_imports()
    jit = [f"{m} imports {sorted(names & {'drjit', 'mitsuba'})}" for m, names in sorted(outside.items())
           if _bridge_room(m) in NO_JIT and names & {"drjit", "mitsuba"}]
    assert not jit, jit


def test_the_floor_rooms_import_nothing_above_them():
    inside, _ = _bridge_imports()
    for room in ("device", "files", "bsdf/maths"):
        above = [f"{m} imports {t}" for m, targets in inside.items() if _bridge_room(m) == room
                 for t in targets if _bridge_room(t) not in ({room} | BRIDGE_ROOMS[room])]
        assert not above, above


def test_top_level_layout_is_as_documented():
    tracked = subprocess.run(["git", "ls-files"], capture_output=True, text=True, cwd=ROOT).stdout.split()
    if not tracked:
        pytest.skip("not a git checkout")
    top = {path.split("/")[0] for path in tracked}
    assert top <= {"addon", "blender_manifest.toml", "mitsuba_bridge", "scenes", "tests", "docs", "README.md",
                   "pyproject.toml", "Makefile", ".ci", ".gitignore", "__init__.py", "LICENSE", "farm"}, top
    assert len((ROOT / "__init__.py").read_text().strip().splitlines()) == 3


def test_manifest_has_the_required_fields():
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert manifest["id"] == "scratch_iridescence"
    assert manifest["type"] == "add-on"
    assert len(manifest["tagline"]) <= 64
    for key in ("schema_version", "version", "name", "maintainer", "license", "blender_version_min"):
        assert manifest[key]
    assert manifest["version"] == tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def test_manifest_passes_blenders_validator():
    bpy_spec = __import__("importlib.util").util.find_spec("bpy")
    cli = Path(bpy_spec.origin).parent / "5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py"
    result = subprocess.run([sys.executable, str(cli), "validate", str(ROOT)], capture_output=True, text=True)
    assert result.returncode == 0 and "Success" in result.stdout, result.stdout + result.stderr


def test_root_is_importable_as_the_extension_package():
    code = """
import scratch_iridescence, os
assert os.path.samefile(os.path.dirname(scratch_iridescence.__file__), %r)
scratch_iridescence.register()
scratch_iridescence.unregister()
scratch_iridescence.register()
scratch_iridescence.unregister()
from scratch_iridescence.mitsuba_bridge import scratch
print(scratch.FORMAT)
""" % str(ROOT)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd="/")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("scratch-iridescence/1")


def test_command_line_generate_and_info(tmp_path):
    out = tmp_path / "plate.npz"
    run = lambda *args: subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", *args],
                                       capture_output=True, text=True, cwd=ROOT)
    made = run("generate", str(out), "--count", "50", "--depth", "G[250, 80]", "--width", "U[1, 6]")
    assert made.returncode == 0, made.stderr
    info = run("info", str(out))
    assert info.returncode == 0 and "50 scratches" in info.stdout
    out.write_bytes(b"junk")
    bad = run("info", str(out))
    assert bad.returncode == 1 and "not a scratch file" in bad.stderr
