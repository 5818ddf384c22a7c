"""The built Linux extension zip: what it holds, and that it installs into a sandboxed Blender user
folder, enables and renders.

Where a libLLVM 15 exists, the sandbox's system LLVM is that one (LD_LIBRARY_PATH): the render
must then use the libLLVM the zip bundles.

Slow: builds the zips from the current tree first (as ``make extension`` does; the first
build downloads about 300 MB of wheels into ``wheels/``).
"""
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]

INSTALL_AND_RENDER = r"""
import importlib.machinery, os, sys
import bpy

zip_path, output = sys.argv[-2], sys.argv[-1]
result = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
print("INSTALL", result)
site = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local", "lib",
                    "python{}.{}".format(*sys.version_info[:2]), "site-packages")
print("WHEELS", sorted(n for n in os.listdir(site) if n.endswith(".dist-info")))

class OnlyBundled:
    # mitsuba, drjit and OpenEXR must come from the extension's wheels, not from this venv.
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("mitsuba", "drjit", "OpenEXR") and "." not in name:
            spec = importlib.machinery.PathFinder.find_spec(name, [site])
            if spec is None:
                raise ImportError(name + " is not bundled")
            return spec
        return None
sys.meta_path.insert(0, OnlyBundled())

engine = bpy.types.RenderEngine.bl_rna_get_subclass_py("MITSUBA_SCRATCH")
print("ENGINE", engine.__module__)
scene = bpy.context.scene
scene.render.engine = "MITSUBA_SCRATCH"
scene.render.resolution_x, scene.render.resolution_y = 32, 24
scene.scratch_iridescence.samples = 4
scene.render.image_settings.file_format = "PNG"
scene.render.filepath = output
bpy.ops.render.render(write_still=True)
import mitsuba, drjit
print("MITSUBA", mitsuba.__file__)
print("LLVM", drjit.detail.llvm_version(), os.environ.get("DRJIT_LIBLLVM_PATH"))
"""


#: Tracked files that users do not run: the scenes (demo, paper harness) and the numerical validation
#: with its brute-force reference and probe; the farm job definitions and the Dask cluster room, whose
#: Dask is not bundled (blender_manifest.toml, [build] paths_exclude_pattern).
NOT_SHIPPED = ("scenes/", "mitsuba_bridge/validation/", "mitsuba_bridge/cluster/", "farm/", "tests/", "docs/", ".ci/",
               "Makefile", "pyproject.toml", ".gitignore")


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory) -> Path:
    """Build the zips from the current tree (wheels are downloaded once into wheels/, then reused)."""
    output = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, str(ROOT / ".ci" / "build_extension.py"), "--output-dir", str(output)],
                   check=True, cwd=ROOT)
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    return output / f"{manifest['id']}-{manifest['version']}-linux_x64.zip"


@pytest.mark.slow
def test_zip_holds_the_addon_and_the_bridge_but_not_the_paper_harness(linux_zip):
    names = set(zipfile.ZipFile(linux_zip).namelist())
    tracked = subprocess.run(["git", "ls-files"], capture_output=True, text=True, cwd=ROOT, check=True).stdout.split()
    shipped = {path for path in tracked if not path.startswith(NOT_SHIPPED)}
    assert "addon/geometry/surface.py" in shipped and "mitsuba_bridge/bsdf/model.py" in shipped
    assert shipped <= names, sorted(shipped - names)
    leaked = sorted(name for name in names if name.startswith(NOT_SHIPPED))
    assert not leaked, leaked
    code = {name for name in names if not name.startswith("wheels/")}
    assert code == shipped, sorted(code ^ shipped)  # nothing untracked (caches, egg-info, outputs) either
    assert {name.split("-")[0] for name in names if name.startswith("wheels/")} == \
        {"wheels/mitsuba", "wheels/drjit", "wheels/openexr", "wheels/karellen_llvm_core"}
    # Nothing of Dask (the cluster extra) nor the cluster room that needs it enters the zip.
    assert not [name for name in names if "dask" in name or "distributed" in name or "/cluster/" in name]


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="installs the Linux x64 zip")
def test_linux_zip_installs_enables_and_renders_with_its_own_wheels(linux_zip, tmp_path, llvm15_or_none):
    zip_path = linux_zip
    sandbox = tmp_path / "blender-user"
    output = tmp_path / "frame.png"
    env = {"BLENDER_USER_RESOURCES": str(sandbox), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
           "TMPDIR": str(tmp_path)}
    if llvm15_or_none is not None:  # a system whose only libLLVM is 15: the bundled one must be used
        (tmp_path / "system-lib").mkdir()
        (tmp_path / "system-lib" / "libLLVM.so").symlink_to(llvm15_or_none)
        env["LD_LIBRARY_PATH"] = str(tmp_path / "system-lib")
    result = subprocess.run([sys.executable, "-c", INSTALL_AND_RENDER, str(zip_path), str(output)],
                            capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    log = result.stdout + result.stderr
    assert result.returncode == 0, log
    assert "INSTALL {'FINISHED'}" in log
    assert "ENGINE bl_ext.user_default.scratch_iridescence" in log
    assert all(f"'{name}-" in log for name in ("mitsuba", "drjit", "openexr")), log
    assert f"MITSUBA {sandbox}" in log  # rendered with the bundled Mitsuba
    # ... and the bundled libLLVM (karellen-llvm-core 23), whatever the system offers
    assert "LLVM (23, " in log and f"{sandbox}" in log.split("LLVM (23, ")[1], log
    assert "LLVM probe" not in log  # the crash probe ran in a child with the bundled wheels and rendered
    assert output.is_file() and output.stat().st_size > 100
