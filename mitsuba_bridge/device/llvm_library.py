"""The libLLVM that Dr.Jit's CPU backend loads: a bundled one when present, and a check before any kernel.

Dr.Jit 1.5 compiles CPU kernels through the LLVM C API of a shared library it
opens when ``drjit`` is imported: ``DRJIT_LIBLLVM_PATH`` when set (and then
nothing else), else ``libLLVM.so`` on the loader path, else the newest
``/usr/lib/<triple>/libLLVM*.so.*`` (Homebrew's on macOS, ``LLVM-C.dll`` on
Windows).  With LLVM 15 or older the first kernel **aborts the process**
(``LLVM ERROR: Cannot select ... fminimum``, SIGABRT), which inside Blender loses
the user's unsaved work; an exception cannot catch it.  Hence three steps:

* :func:`configure` runs when :mod:`mitsuba_bridge` is imported, before ``drjit``
  is: where the extension bundles a libLLVM wheel (Linux x64:
  ``karellen-llvm-core``, see docs/rendering.md) and the user has not chosen a
  library, it points ``DRJIT_LIBLLVM_PATH`` at it;
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

import ctypes
import os
import subprocess
import sys
import tempfile
from pathlib import Path

__all__ = ["MIN_LLVM_MAJOR", "ENV_VAR", "BUNDLED_DISTRIBUTION", "bundled_library", "configure",
           "llvm_version", "llvm_problem", "probe_problem", "install_hint"]

#: Oldest LLVM major version Dr.Jit 1.5 renders with (15 aborts on the first kernel that uses min/max).
MIN_LLVM_MAJOR = 16
#: Dr.Jit reads this once, when ``drjit`` is imported.
ENV_VAR = "DRJIT_LIBLLVM_PATH"
#: The wheel that ships a libLLVM exporting the C API (Apache-2.0 WITH LLVM-exception), Linux x64 only.
BUNDLED_DISTRIBUTION = "karellen-llvm-core"

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


def bundled_library() -> Path | None:
    """The libLLVM shared library of the installed ``karellen-llvm-core`` wheel, or None.

    Works for both layouts: pip puts the wheel's data files under the
    environment's ``lib/``, Blender's extension installer leaves them in
    ``karellen_llvm_core-<version>.data/data/lib/`` inside its site-packages;
    the wheel's RECORD names the file either way.
    """
    from importlib import metadata

    try:
        distribution = metadata.distribution(BUNDLED_DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return None
    for file in distribution.files or ():
        if file.name.startswith("libLLVM.so."):
            path = Path(distribution.locate_file(file)).resolve()
            if path.is_file():
                return path
    return None


def _load_runtime(library: Path) -> None:
    """Load the bundled libc++ beside ``library`` so that dlopen of libLLVM finds it by SONAME."""
    for folder in (library.parent, *library.parent.glob("*-linux-gnu")):
        runtime = [folder / name for name in _BUNDLED_RUNTIME]
        if all(path.is_file() for path in runtime):
            for path in runtime:
                ctypes.CDLL(str(path))
            return


def configure() -> Path | None:
    """Point Dr.Jit at the bundled libLLVM unless the user chose one; returns the library selected.

    Must run before ``drjit`` is first imported (Dr.Jit reads ``DRJIT_LIBLLVM_PATH``
    then, once); :mod:`mitsuba_bridge` calls it on import.  Does nothing when
    ``DRJIT_LIBLLVM_PATH`` is already set (the user's choice wins), when
    ``drjit`` is already loaded, or when no bundled library is installed.
    """
    global _selected_bundled
    if os.environ.get(ENV_VAR) or "drjit" in sys.modules:
        return None
    library = bundled_library()
    if library is None:
        return None
    try:
        _load_runtime(library)
    except OSError as error:  # e.g. a system without libatomic.so.1: fall back to the system's LLVM
        print(f"Scratch Iridescence: the bundled LLVM is unusable here ({error}); using the system's",
              file=sys.stderr)
        return None
    os.environ[ENV_VAR] = str(library)
    _selected_bundled = library
    return library


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
    chosen = os.environ.get(ENV_VAR)
    if version is None:
        if chosen and _selected_bundled is not None and chosen == str(_selected_bundled):
            where = f"the LLVM bundled with the extension ({chosen}) could not be loaded"
        elif chosen:
            where = f"{ENV_VAR}={chosen!r} could not be loaded"
        else:
            where = "no libLLVM was found"
        return f"Mitsuba's CPU backend needs the LLVM library (libLLVM {MIN_LLVM_MAJOR} or newer): {where}. " \
               + install_hint()
    if version[0] < MIN_LLVM_MAJOR:
        found = ".".join(str(part) for part in version) if version[0] > 0 else "an unknown old version"
        source = f" (from {ENV_VAR}={chosen!r})" if chosen else ""
        return (f"Mitsuba's CPU backend found LLVM {found}{source}, which would crash the renderer "
                f"(Dr.Jit needs LLVM {MIN_LLVM_MAJOR} or newer). " + install_hint())
    return None


def probe_problem() -> str | None:
    """None unless a tiny render with Dr.Jit's libLLVM crashes a child process; then what to do.

    Runs once per process and library (about 1.5 s; an empty kernel cache makes the
    child really compile).  Only a crash refuses: a child that cannot start, cannot
    import Mitsuba or times out says nothing about LLVM, so rendering goes ahead.
    """
    key = (os.environ.get(ENV_VAR, ""), llvm_version())
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
        if bundled is not None and os.environ.get(ENV_VAR) != str(bundled):
            text += f", or unset {ENV_VAR} to use the LLVM bundled with the extension ({bundled})"
        elif bundled is None:
            text += ", or install the extension zip for linux-x64, which bundles LLVM"
    elif platform == "darwin":
        text = "Install LLVM with Homebrew ('brew install llvm'); Dr.Jit finds Homebrew's libLLVM.dylib by itself"
    elif platform.startswith("win"):
        text = ("Install LLVM 16 or newer for Windows x64 (the LLVM-*-win64.exe installer from the LLVM "
                "releases page, with 'Add LLVM to the system PATH') so that LLVM-C.dll is found")
    else:
        text = "Install LLVM 16 or newer"
    return (text + f", or set {ENV_VAR} to the full path of a libLLVM {MIN_LLVM_MAJOR}+ library; "
            "then restart Blender. An NVIDIA GPU with a CUDA driver renders without LLVM.")


if __name__ == "__main__" and sys.argv[1:] == ["--probe"]:
    sys.exit(_probe_main())
