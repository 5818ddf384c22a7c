"""`make test-blender`: the extension zips installed into every Blender of the version matrix, and the smoke set.

For each Blender of :data:`MATRIX` (the oldest and newest 4.2 LTS, the newest 4.5 LTS and the newest 5.x that
PyPI offers as the ``bpy`` module), in its own virtual environment under a Python it supports (pyenv's), this

1. builds the zips once (.ci/build_extension.py) unless ``--zips`` names a folder of built ones;
2. creates ``out/blender-matrix/bpy-<version>`` with ``pip install bpy==<version>`` (kept for the next run;
   ``make clean`` removes it; no pip cache: the wheels are 330-500 MB each);
3. runs tests/blender/smoke.py in a fresh process with a sandboxed Blender user folder
   (``BLENDER_USER_RESOURCES``, ``HOME``), a libLLVM 15 first on the loader path where one exists (so that
   only the LLVM the zip bundles can render) and a kernel cache shared by the versions;
4. prints each step, one line per Blender, a summary table and ``N passed, N failed``; exits 1 on a failure.

Run with ``make test-blender`` (or ``.venv/bin/python tests/blender/matrix.py [--versions 4.2.0 5.3.0]``).
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "out" / "blender-matrix"
sys.path.insert(0, str(ROOT / ".ci"))
from build_extension import BLENDER_PYTHONS, main as build_zips  # noqa: E402


@dataclass(frozen=True)
class Blender:
    version: str   #: the bpy release
    python: str    #: the CPython it is built for ('3.11')
    why: str       #: its place in the matrix


#: Checked 2026-12-07 with `pip index versions bpy` (under Python 3.11 and 3.13) and each release's
#: Requires-Python.  Update when PyPI offers newer releases (docs/testing.md, "Blender versions").
MATRIX = (
    Blender("4.2.0", "3.11", "oldest 4.2 LTS: its installer takes wheels of every Python"),
    Blender("4.2.23", "3.11", "newest 4.2 LTS"),
    Blender("4.5.15", "3.11", "newest 4.5 LTS"),
    Blender("5.3.0", "3.13", "newest 5.x"),
)

#: Where a libLLVM 15 may be: first on the loader path, it makes the system's LLVM unusable (docs/rendering.md).
LLVM15 = "/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1"


def python_for(version: str) -> str:
    """An interpreter of CPython ``version``: pyenv's newest of that minor, else ``pythonX.Y`` on the PATH."""
    root = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
    candidates = sorted(root.glob(f"{version}.*/bin/python{version}"),
                        key=lambda p: tuple(int(x) for x in p.parts[-3].split(".") if x.isdigit()))
    if candidates:
        return str(candidates[-1])
    found = shutil.which(f"python{version}")
    if found is None:
        raise SystemExit(f"error: no CPython {version} found (pyenv install {version}, or put python{version} "
                         "on the PATH)")
    return found


def environment_for(blender: Blender) -> Path:
    """The virtual environment with ``bpy==blender.version`` (created and installed when missing)."""
    folder = OUT / f"bpy-{blender.version}"
    python = folder / "bin" / "python"
    stamp = folder / ".installed"
    if stamp.is_file() and python.is_file():
        return python
    shutil.rmtree(folder, ignore_errors=True)
    began = time.perf_counter()
    print(f"== bpy {blender.version}: creating {folder.relative_to(ROOT)} (Python {blender.python})", flush=True)
    subprocess.run([python_for(blender.python), "-m", "venv", str(folder)], check=True)
    subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-cache-dir",
                    f"bpy=={blender.version}"], check=True)
    stamp.write_text(f"{time.perf_counter() - began:.0f} s\n")
    print(f"   installed in {time.perf_counter() - began:.0f} s", flush=True)
    return python


def zip_for(zips: Path, python: str, right: bool) -> Path:
    """The Linux x64 zip built for Blender's ``python`` (or, ``right=False``, for another Python)."""
    labels = [target.label for target in BLENDER_PYTHONS if (target.python == python) == right]
    found = sorted(path for label in labels for path in zips.glob(f"scratch_iridescence-*-{label}-linux_x64.zip"))
    if not found:
        raise SystemExit(f"error: no linux_x64 zip for Python {python} in {zips}")
    return found[0]


def run_smoke(blender: Blender, python: Path, zips: Path) -> tuple[list[tuple[str, str, str, str]], int, float, str]:
    """(steps, exit status, seconds, log) of the smoke set in a fresh, sandboxed process of this Blender."""
    work = OUT / "runs" / blender.version
    shutil.rmtree(work, ignore_errors=True)
    (work / "user").mkdir(parents=True)
    env = {"PATH": "/usr/bin:/bin", "HOME": str(work), "TMPDIR": str(work), "LANG": "C.UTF-8",
           "BLENDER_USER_RESOURCES": str(work / "user"), "DRJIT_CACHE_DIR": str(OUT / "drjit-cache")}
    if Path(LLVM15).exists():  # the system's LLVM is then 15, which would crash: only the bundled one renders
        (work / "llvm15").mkdir()
        (work / "llvm15" / "libLLVM.so").symlink_to(LLVM15)
        env["LD_LIBRARY_PATH"] = str(work / "llvm15")
    began = time.perf_counter()
    child = subprocess.run([str(python), str(ROOT / "tests" / "blender" / "smoke.py"),
                            str(zip_for(zips, blender.python, True)), str(zip_for(zips, blender.python, False)),
                            str(work)], capture_output=True, text=True, env=env, cwd=work, timeout=3600)
    seconds = time.perf_counter() - began
    log = child.stdout + child.stderr
    (work / "smoke.log").write_text(log)
    steps = []
    for line in child.stdout.splitlines():
        if line.startswith("SMOKE "):
            _, name, outcome, step_seconds, *detail = line.split(" ", 4) + [""]
            steps.append((name, outcome, step_seconds, detail[0]))
    return steps, child.returncode, seconds, log


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--versions", nargs="*", help="bpy versions to run (default: the whole matrix)")
    parser.add_argument("--zips", help="a folder of built zips (default: build them into out/blender-matrix/dist)")
    args = parser.parse_args(argv)
    known = {blender.version: blender for blender in MATRIX}
    # A release outside the matrix runs too (its Python from its version: 5.1 and newer embed 3.13)
    matrix = [known.get(version) or Blender(version, "3.13" if tuple(map(int, version.split(".")[:2])) >= (5, 1)
                                            else "3.11", "asked for") for version in args.versions] \
        if args.versions else list(MATRIX)
    began = time.perf_counter()
    zips = Path(args.zips).resolve() if args.zips else OUT / "dist"
    if not args.zips:
        build_zips(["--output-dir", str(zips)])
    passed = failed = 0
    rows = []
    for blender in matrix:
        python = environment_for(blender)
        steps, status, seconds, log = run_smoke(blender, python, zips)
        print(f"== Blender {blender.version} (Python {blender.python}, {blender.why}): {seconds:.0f} s", flush=True)
        for name, outcome, step_seconds, detail in steps:
            print(f"   {outcome:4} {name:32} {step_seconds:>6} s  {detail}", flush=True)
        clean_exit = status == 0 and "terminate called" not in log and "Segmentation fault" not in log
        print(f"   {'ok' if clean_exit else 'FAIL'}   exit status {status}"
              + ("" if clean_exit else f"; log: {(OUT / 'runs' / blender.version / 'smoke.log').relative_to(ROOT)}"),
              flush=True)
        if not steps:
            print(log[-3000:], flush=True)
        if clean_exit and steps and all(outcome == "ok" for _, outcome, _, _ in steps):
            shutil.rmtree(OUT / "runs" / blender.version / "user", ignore_errors=True)  # the installed copy: 0.5 GB
        good = sum(outcome == "ok" for _, outcome, _, _ in steps) + clean_exit
        bad = len(steps) + 1 - good
        passed, failed = passed + good, failed + bad
        rows.append((blender, good, bad, seconds))
    print("\nBlender   Python  passed  failed  seconds", flush=True)
    for blender, good, bad, seconds in rows:
        print(f"{blender.version:9} {blender.python:7} {good:6}  {bad:6}  {seconds:7.0f}", flush=True)
    print(f"total {time.perf_counter() - began:.0f} s", flush=True)
    print(f"{passed} passed, {failed} failed", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
