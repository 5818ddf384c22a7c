"""The built Linux extension zip installs into a sandboxed Blender user folder, enables and renders.

Slow: builds the zips from the current tree first (as ``make extension`` does; the first
build downloads about 300 MB of wheels into ``wheels/``).
"""
import subprocess
import sys
import tomllib
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
import mitsuba
print("MITSUBA", mitsuba.__file__)
"""


def linux_zip(output: Path) -> Path:
    """Build the zips from the current tree (wheels are downloaded once into wheels/, then reused)."""
    subprocess.run([sys.executable, str(ROOT / ".ci" / "build_extension.py"), "--output-dir", str(output)],
                   check=True, cwd=ROOT)
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    return output / f"{manifest['id']}-{manifest['version']}-linux_x64.zip"


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="installs the Linux x64 zip")
def test_linux_zip_installs_enables_and_renders_with_its_own_wheels(tmp_path):
    zip_path = linux_zip(tmp_path / "dist")
    sandbox = tmp_path / "blender-user"
    output = tmp_path / "frame.png"
    env = {"BLENDER_USER_RESOURCES": str(sandbox), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
           "TMPDIR": str(tmp_path)}
    result = subprocess.run([sys.executable, "-c", INSTALL_AND_RENDER, str(zip_path), str(output)],
                            capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    log = result.stdout + result.stderr
    assert result.returncode == 0, log
    assert "INSTALL {'FINISHED'}" in log
    assert "ENGINE bl_ext.user_default.scratch_iridescence" in log
    assert all(f"'{name}-" in log for name in ("mitsuba", "drjit", "openexr")), log
    assert f"MITSUBA {sandbox}" in log  # rendered with the bundled Mitsuba
    assert output.is_file() and output.stat().st_size > 100
