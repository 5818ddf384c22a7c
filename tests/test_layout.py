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


@pytest.mark.parametrize("package", BLENDER_FREE)
def test_blender_free_packages_import_with_bpy_unavailable(package):
    # A meta-path finder that refuses Blender's modules, in a fresh interpreter; every module of the
    # package is found by walking its folder, so a new module is covered without editing a list.
    code = f"""
import sys, importlib, pkgutil
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {BLENDER_MODULES!r}:
            raise ImportError('blocked: ' + name)
sys.meta_path.insert(0, Block())
package = importlib.import_module({package!r})
names = [info.name for info in pkgutil.walk_packages(package.__path__, {package!r} + '.')]
for name in names:
    importlib.import_module(name)
assert not any(m.split('.')[0] == 'bpy' for m in sys.modules)
print(len(names))
"""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) >= 8


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
    # helpers: invariants such as orthonormal frames live in mitsuba_bridge/scene.py.
    for folder, forbidden in [("addon/render/gather", ("mitsuba_bridge.builder", "mitsuba_bridge.bsdf")),
                              ("mitsuba_bridge/builder", ("addon",))]:
        for path in _python_files(folder):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.ImportFrom):
                    module = (node.module or "").lstrip(".")
                    assert not module.startswith(forbidden), f"{path.relative_to(ROOT)} imports {node.module}"


def test_top_level_layout_is_as_documented():
    tracked = subprocess.run(["git", "ls-files"], capture_output=True, text=True, cwd=ROOT).stdout.split()
    if not tracked:
        pytest.skip("not a git checkout")
    top = {path.split("/")[0] for path in tracked}
    assert top <= {"addon", "blender_manifest.toml", "mitsuba_bridge", "scenes", "tests", "docs", "README.md",
                   "pyproject.toml", "Makefile", ".ci", ".gitignore", "__init__.py"}, top
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
