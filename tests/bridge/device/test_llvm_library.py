"""An unusable libLLVM is refused before any kernel compiles; never an abort (issue 10 item 5).

The LLVM-15 cases run in a subprocess with ``DRJIT_LIBLLVM_PATH`` pointing at a
real libLLVM 15 (Debian's ``libllvm15``): Dr.Jit reads the variable once, at
``import drjit``, and with that library the first kernel aborts the process, so
the crash itself can only be observed from outside.

"Only LLVM 15 on the system" is simulated without ``DRJIT_LIBLLVM_PATH`` too: a
folder on ``LD_LIBRARY_PATH`` whose ``libLLVM.so`` is LLVM 15 is what Dr.Jit's
``dlopen("libLLVM.so")`` finds first.  There, the extension's bundled libLLVM
wheel (installed the way Blender installs extension wheels) must render.
"""
from __future__ import annotations

import glob
import os
import signal
import importlib.util
import platform
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from scratch_iridescence.mitsuba_bridge.device import llvm_library, variants

dr = pytest.importorskip("drjit")

ROOT = Path(__file__).resolve().parents[3]

#: What used to happen inside Blender: the CPU variant, then the first kernel (min/max: 'fminimum').
UNCHECKED = """
import drjit as dr, mitsuba as mi
print('LLVM', dr.detail.llvm_version(), flush=True)
mi.set_variant('llvm_ad_spectral')
print(dr.minimum(mi.Float([1, 2, 3]), mi.Float(2.0)), flush=True)
print('SURVIVED')
"""

#: The bridge's way in: choose the variant (which checks the LLVM), then render the Cornell box at 1 spp.
CHECKED = """
from scratch_iridescence.mitsuba_bridge.device import variants
try:
    variant = variants.set_variant('auto')
except variants.VariantError as error:
    print('REFUSED', error)
else:
    import mitsuba as mi
    image = mi.render(mi.load_dict(mi.cornell_box()), spp=1)
    print('RENDERED', variant, image.shape)
import drjit as dr, mitsuba as mi
print('LLVM', dr.detail.llvm_version(), 'VARIANT', mi.variant())
"""


def run_python(code: str, tmp_path: Path, library: str | None, **extra_env: str) -> subprocess.CompletedProcess:
    """``code`` in a fresh interpreter with Dr.Jit pointed at ``library`` and an empty kernel cache.

    The empty cache matters: a kernel compiled earlier by a good LLVM would be reused
    instead of compiled, and LLVM 15 would then not get the chance to abort.
    """
    env = {key: value for key, value in os.environ.items() if key != llvm_library.ENV_VAR}
    env["DRJIT_CACHE_DIR"] = str(tmp_path / "drjit-cache")
    if library is not None:
        env[llvm_library.ENV_VAR] = library
    env.update(extra_env)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=300)


def test_llvm15_really_aborts_the_process_on_the_first_kernel(tmp_path, llvm15):
    # The simulation is real: without the check, the process dies with SIGABRT (exit 134 in a shell).
    result = run_python(UNCHECKED, tmp_path, llvm15)
    assert "LLVM (15," in result.stdout
    assert result.returncode == -signal.SIGABRT, result.stdout + result.stderr
    assert "LLVM ERROR" in result.stderr and "SURVIVED" not in result.stdout


def test_llvm15_is_refused_before_any_kernel_with_what_to_install(tmp_path, llvm15):
    result = run_python(CHECKED, tmp_path, llvm15)
    log = result.stdout + result.stderr
    assert result.returncode == 0, log
    assert "REFUSED Mitsuba's CPU backend found LLVM 15.0" in result.stdout, log
    assert f"DRJIT_LIBLLVM_PATH='{llvm15}'" in result.stdout  # says where the bad library came from
    assert "apt install libllvm19" in result.stdout  # and what to install instead
    assert "VARIANT None" in result.stdout and "LLVM ERROR" not in log  # no variant set, nothing compiled


@pytest.mark.parametrize("kind", ["missing", "not a library"])
def test_a_library_path_that_is_not_llvm_is_a_clear_error(tmp_path, kind):
    path = tmp_path / "libLLVM-fake.so"
    if kind == "not a library":
        path.write_bytes(b"\x7fELF" + bytes(range(256)) * 4)  # an ELF magic and garbage after it
    result = run_python(CHECKED, tmp_path, str(path))
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"REFUSED Mitsuba's CPU backend needs the LLVM library (libLLVM 16 or newer): " \
           f"DRJIT_LIBLLVM_PATH='{path}' could not be loaded" in result.stdout, result.stdout + result.stderr
    assert "VARIANT None" in result.stdout


def test_the_systems_llvm_renders_here(tmp_path):
    # The positive case, in the same harness: the machine's own libLLVM (>= 16, installed by `make setup`).
    result = run_python(CHECKED, tmp_path, None)
    assert "RENDERED llvm_ad_spectral (256, 256, 3)" in result.stdout, result.stdout + result.stderr
    major = int(result.stdout.split("LLVM (")[1].split(",")[0])
    assert major >= llvm_library.MIN_LLVM_MAJOR


def test_an_old_llvm_is_refused_in_process_without_compiling(monkeypatch):
    monkeypatch.setattr(dr, "has_backend", lambda backend: backend == dr.JitBackend.LLVM)
    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (15, 0, 6))
    with pytest.raises(variants.VariantError, match=r"found LLVM 15\.0\.6.*which would crash"):
        variants.choose_variant("auto")
    with pytest.raises(variants.VariantError, match=r"found LLVM 15\.0\.6"):
        variants.choose_variant("llvm_ad_spectral")
    # Dr.Jit reports -1 when a library loaded without LLVMGetVersion, which LLVM 16 added: too old too.
    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (-1, -1, -1))
    with pytest.raises(variants.VariantError, match="an unknown old version"):
        variants.choose_variant("auto")


def test_cuda_is_tried_first_and_an_old_llvm_does_not_matter_then(monkeypatch):
    monkeypatch.setattr(dr, "has_backend", lambda backend: True)
    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (15, 0, 6))
    assert variants.choose_variant("auto") == "cuda_ad_spectral"


@pytest.mark.parametrize("platform, expected", [
    ("linux", "apt install libllvm19"),
    ("darwin", "'brew install llvm'"),
    ("win32", "'winget install --id LLVM.LLVM --exact'"),
])
def test_the_install_hint_names_the_fix_for_each_platform(platform, expected):
    hint = llvm_library.install_hint(platform)
    assert expected in hint
    assert "DRJIT_LIBLLVM_PATH" in hint and "restart Blender" in hint and "CUDA" in hint and "Metal" in hint


def manifest_llvm_wheel() -> Path:
    """wheels/<the karellen-llvm-core wheel that blender_manifest.toml bundles> (downloaded by `make setup`)."""
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    name = next(Path(entry).name for entry in manifest["wheels"]
                if Path(entry).name.startswith("karellen_llvm_core-"))
    return ROOT / "wheels" / name


LLVM_WHEEL = manifest_llvm_wheel()
needs_llvm_wheel = pytest.mark.skipif(
    not LLVM_WHEEL.is_file() or (sys.platform, platform.machine()) != ("linux", "x86_64"),
    reason=f"the bundled libLLVM wheel wheels/{LLVM_WHEEL.name} is Linux x64 only and fetched by 'make setup'")


@pytest.fixture(scope="module")
def system_with_only_llvm15(tmp_path_factory, llvm15):
    """LD_LIBRARY_PATH for a folder whose libLLVM.so is LLVM 15: what Dr.Jit loads when nothing else is said."""
    folder = tmp_path_factory.mktemp("system-llvm15")
    (folder / "libLLVM.so").symlink_to(llvm15)
    return {"LD_LIBRARY_PATH": str(folder)}


@pytest.fixture(scope="module")
def blender_site_packages(tmp_path_factory):
    """The bundled wheel installed by Blender's own extension wheel installer (from the bpy wheel)."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        pytest.skip("the bpy module provides Blender's wheel installer")
    source = next(Path(spec.origin).parent.glob("[0-9]*.[0-9]*/scripts/modules/_bpy_internal/extensions/"
                                                 "wheel_manager.py"))
    module_spec = importlib.util.spec_from_file_location("blender_wheel_manager", source)
    wheel_manager = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(wheel_manager)
    local = tmp_path_factory.mktemp("extensions") / ".local"
    site = local / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    errors = []
    wheel_manager.apply_action(local_dir=str(local), local_dir_site_packages=str(site),
                               wheel_list=[("scratch_iridescence", [str(LLVM_WHEEL)])],
                               error_fn=errors.append, remove_error_fn=lambda path, error: errors.append(error),
                               debug=False)
    assert not errors, errors
    return site


def test_a_system_with_only_llvm15_aborts_unchecked_and_is_refused_checked(tmp_path, system_with_only_llvm15):
    unchecked = run_python(UNCHECKED, tmp_path, None, **system_with_only_llvm15)
    assert "LLVM (15," in unchecked.stdout and unchecked.returncode == -signal.SIGABRT
    checked = run_python(CHECKED, tmp_path, None, **system_with_only_llvm15)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert "REFUSED Mitsuba's CPU backend found LLVM 15.0" in checked.stdout, checked.stdout + checked.stderr


@needs_llvm_wheel
def test_the_bundled_llvm_renders_where_the_system_has_only_llvm15(tmp_path, system_with_only_llvm15,
                                                                   blender_site_packages):
    # Blender leaves the wheel's data files where the wheel put them, and runs no post-install hook.
    assert list(blender_site_packages.glob("karellen_llvm_core-*.data/data/lib/libLLVM.so.*"))
    result = run_python(CHECKED, tmp_path, None, PYTHONPATH=str(blender_site_packages), **system_with_only_llvm15)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "RENDERED llvm_ad_spectral (256, 256, 3)" in result.stdout, result.stdout + result.stderr
    assert f"LLVM ({LLVM_WHEEL.name.split('-')[1].split('.')[0]}," in result.stdout


@needs_llvm_wheel
def test_the_users_choice_of_library_wins_over_the_bundled_one(tmp_path, llvm15, blender_site_packages):
    result = run_python(CHECKED, tmp_path, llvm15, PYTHONPATH=str(blender_site_packages))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "REFUSED Mitsuba's CPU backend found LLVM 15.0" in result.stdout
    assert "unset DRJIT_LIBLLVM_PATH to use the LLVM bundled with the extension" in result.stdout


@needs_llvm_wheel
def test_a_bundled_llvm_that_cannot_load_is_named_in_the_error(tmp_path, blender_site_packages):
    # The wheel's libc++ gone (a damaged install): libLLVM cannot be opened, and the error says it was ours.
    site = tmp_path / "site-packages"
    shutil.copytree(blender_site_packages, site, symlinks=True)
    for runtime in site.glob("karellen_llvm_core-*.data/data/lib/*-linux-gnu/libc++.so*"):
        runtime.unlink()
    result = run_python(CHECKED, tmp_path, None, PYTHONPATH=str(site))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "REFUSED Mitsuba's CPU backend needs the LLVM library (libLLVM 16 or newer): the LLVM bundled with " \
           f"the extension ({site.resolve()}/karellen_llvm_core-" in result.stdout, result.stdout + result.stderr


PROBE_BYPASSING_THE_VERSION_CHECK = """
from scratch_iridescence.mitsuba_bridge.device import llvm_library, variants
llvm_library.llvm_problem = lambda: None  # as if LLVM 15 had passed the version check
try:
    variants.set_variant('auto')
except variants.VariantError as error:
    print('REFUSED', error)
import mitsuba as mi
print('VARIANT', mi.variant())
"""


def test_the_probe_catches_a_crashing_llvm_that_passed_the_version_check(tmp_path, llvm15):
    result = run_python(PROBE_BYPASSING_THE_VERSION_CHECK, tmp_path, llvm15)
    assert result.returncode == 0, result.stdout + result.stderr  # the child crashed, not this process
    assert f"REFUSED Mitsuba's CPU backend crashed while compiling a test kernel with LLVM 15.0.6 " \
           f"(exit status {-signal.SIGABRT}: " in result.stdout, result.stdout + result.stderr
    assert "LLVM ERROR" in result.stdout and "VARIANT None" in result.stdout


@pytest.mark.parametrize("child, refused", [
    ("import os; os.abort()", True),                        # a crash: refuse
    ("raise ImportError('no mitsuba in the child')", False),  # a Python error: says nothing about LLVM
    ("print('LLVM-PROBE-RENDERED')", False),                # rendered
])
def test_only_a_crashing_probe_refuses(tmp_path, monkeypatch, child, refused):
    script = tmp_path / "probe.py"
    script.write_text(child)
    monkeypatch.setattr(llvm_library, "_PROBE_SCRIPT", script)
    monkeypatch.setattr(llvm_library, "_probe_answers", {})
    problem = llvm_library.probe_problem()
    assert (problem is not None) == refused, problem
    if refused:
        assert problem.startswith("Mitsuba's CPU backend crashed while compiling a test kernel")
        assert "DRJIT_LIBLLVM_PATH" in problem  # with the install hint
    monkeypatch.setattr(sys, "executable", str(tmp_path / "no-such-python"))
    assert llvm_library.probe_problem() == problem  # answered once per process and library
    monkeypatch.setattr(llvm_library, "_probe_answers", {})
    assert llvm_library.probe_problem() is None  # a child that cannot start: inconclusive
    blender = tmp_path / "blender"  # a Blender build that reports itself as sys.executable
    blender.write_text(f"#!/bin/sh\ntouch {tmp_path / 'blender-started'}\n")
    blender.chmod(0o755)
    monkeypatch.setattr(sys, "executable", str(blender))
    monkeypatch.setattr(llvm_library, "_probe_answers", {})
    assert llvm_library.probe_problem() is None
    assert not (tmp_path / "blender-started").exists()  # not started: it would have opened a window


@needs_llvm_wheel
def test_the_pip_installed_wheel_is_found_too(tmp_path, system_with_only_llvm15):
    # `pip install scratch-iridescence[llvm]` puts the data files under the prefix's lib/, not in site-packages.
    prefix = tmp_path / "prefix"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-deps",
                    "--no-index", "--prefix", str(prefix), str(LLVM_WHEEL)], check=True, timeout=300)
    site = next(prefix.glob("lib/python*/site-packages"))
    assert list((prefix / "lib").glob("libLLVM.so.*"))  # beside site-packages, not in it
    result = run_python(CHECKED, tmp_path, None, PYTHONPATH=str(site), **system_with_only_llvm15)
    assert "RENDERED llvm_ad_spectral (256, 256, 3)" in result.stdout, result.stdout + result.stderr
    assert "LLVM (23," in result.stdout


def test_the_llvm_extra_pins_the_wheel_the_extension_bundles():
    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["llvm"]
    version = LLVM_WHEEL.name.split("-")[1]
    assert extra == [f"karellen-llvm-core=={version}; sys_platform == 'linux' and platform_machine == 'x86_64'"]


#: Register the add-on and press F12 with the bundled LLVM, then compare the environment with what it was.
REGISTER_AND_RENDER = """
import os, subprocess, sys
import bpy
before = dict(os.environ)
import scratch_iridescence
scratch_iridescence.register()
scene = bpy.context.scene
scene.render.engine = "MITSUBA_SCRATCH"
scene.render.resolution_x, scene.render.resolution_y = 16, 12
scene.scratch_iridescence.samples = 1
scene.render.filepath = os.path.join(os.getcwd(), "frame.png")
bpy.ops.render.render(write_still=True)
import drjit as dr
print("LLVM", dr.detail.llvm_version())
print("CHANGED", sorted(key for key in set(before) | set(os.environ) if before.get(key) != os.environ.get(key)))
child = subprocess.run([sys.executable, "-c", "import os; print(os.environ.get('DRJIT_LIBLLVM_PATH'))"],
                       capture_output=True, text=True)
print("CHILD SEES", child.stdout.strip())
"""


@needs_llvm_wheel
def test_the_bundled_llvm_leaves_the_process_environment_as_it_was(tmp_path, system_with_only_llvm15,
                                                                   blender_site_packages):
    # Dr.Jit reads DRJIT_LIBLLVM_PATH during `import drjit` only: the variable exists for that import and no longer,
    # so neither another add-on nor a child process of Blender's inherits it.
    pytest.importorskip("bpy")
    result = run_python(REGISTER_AND_RENDER, tmp_path, None, PYTHONPATH=str(blender_site_packages),
                        **system_with_only_llvm15)
    log = result.stdout + result.stderr
    assert result.returncode == 0, log
    assert f"LLVM ({LLVM_WHEEL.name.split('-')[1].split('.')[0]}," in result.stdout, log  # the bundled one rendered
    assert "CHANGED []" in result.stdout, log
    assert "CHILD SEES None" in result.stdout, log


def test_the_environment_variable_is_set_for_the_import_only(monkeypatch):
    monkeypatch.delenv(llvm_library.ENV_VAR, raising=False)
    seen = []
    with llvm_library._environment_variable(llvm_library.ENV_VAR, "/lib/libLLVM.so.19"):
        seen.append(os.environ.get(llvm_library.ENV_VAR))
    assert seen == ["/lib/libLLVM.so.19"] and llvm_library.ENV_VAR not in os.environ
    monkeypatch.setenv(llvm_library.ENV_VAR, "/user/choice.so")
    with pytest.raises(RuntimeError):
        with llvm_library._environment_variable(llvm_library.ENV_VAR, "/lib/libLLVM.so.19"):
            raise RuntimeError("an import that failed")
    assert os.environ[llvm_library.ENV_VAR] == "/user/choice.so"


#: Windows without a bundled library: LLVM's own installation is handed over (simulated: sys.platform and the
#: installer's path replaced, the machine's libLLVM 19 standing in for LLVM-C.dll; the system offers only 15).
WINDOWS_INSTALL = """
import os, sys
from pathlib import Path
from scratch_iridescence.mitsuba_bridge.device import llvm_library
assert 'drjit' not in sys.modules
llvm_library.WINDOWS_INSTALL = Path(sys.argv[-1])
real_platform, sys.platform = sys.platform, 'win32'
print('HANDED', llvm_library.configure())
sys.platform = real_platform
import drjit as dr
print('LLVM', dr.detail.llvm_version(), 'ENV', os.environ.get('DRJIT_LIBLLVM_PATH'))
"""


def test_windows_hands_llvms_own_installation_to_drjit(tmp_path, system_with_only_llvm15):
    library = next(iter(sorted(glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM.so.1[6-9]*")
                               + glob.glob("/usr/lib/x86_64-linux-gnu/libLLVM.so.[2-9][0-9]*"))), None)
    if library is None:
        pytest.skip("no libLLVM >= 16 of Debian's to stand in for LLVM-C.dll")
    result = subprocess.run([sys.executable, "-c", WINDOWS_INSTALL, library], capture_output=True, text=True,
                            cwd=tmp_path, timeout=300,
                            env={**{k: v for k, v in os.environ.items() if k != llvm_library.ENV_VAR},
                                 **system_with_only_llvm15, "DRJIT_CACHE_DIR": str(tmp_path / "cache")})
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"HANDED {library}" in result.stdout
    major = library.split(".so.")[1].split(".")[0]
    assert f"LLVM ({major}," in result.stdout and "ENV None" in result.stdout, result.stdout
