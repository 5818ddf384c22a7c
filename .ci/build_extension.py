"""Build the installable extension zips: one per platform, with the Mitsuba, Dr.Jit and OpenEXR wheels.

``blender_manifest.toml`` is the single source of truth: its ``wheels`` list
names every wheel file exactly (CPython 3.11 for Blender 4.2-5.0, 3.13 for
Blender 5.1; Linux x64, Windows x64, macOS arm64), plus the py3 wheel of a
libLLVM for Linux x64 (``karellen-llvm-core``, docs/rendering.md).  This script

1. downloads the listed wheels that are missing from ``wheels/`` with pip
   (``--no-deps --only-binary``, each for its own platform and Python);
2. builds with Blender's extension tool, shipped in the bpy wheel
   (``blender_ext.py build --split-platforms``), into ``dist/``;
3. validates every zip with the same tool.

Run with ``make extension`` (or ``.venv/bin/python .ci/build_extension.py``).
"""
from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tomllib
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


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


def download_missing(wheels: list[str], folder: Path) -> None:
    """pip-download every listed wheel not yet in ``folder``, grouped by (Python, platform)."""
    missing = [name for name in wheels if not (folder / name).is_file()]
    groups: dict[tuple[str, str], list[str]] = defaultdict(list)
    for name in missing:
        distribution, version, python, platform = parse_wheel(name)
        groups[(python or "3", platform)].append(f"{distribution}=={version}")
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


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", default=str(ROOT / "dist"))
    parser.add_argument("--no-download", action="store_true", help="fail instead of downloading missing wheels")
    parser.add_argument("--download-only", metavar="PREFIX",
                        help="only download the listed wheels whose file name starts with PREFIX, then stop "
                             "(make setup fetches the bundled libLLVM this way for the tests)")
    args = parser.parse_args(argv)

    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    wheels = [Path(entry).name for entry in manifest.get("wheels", [])]
    if args.download_only:
        download_missing([name for name in wheels if name.startswith(args.download_only)], ROOT / "wheels")
        return 0
    if not args.no_download:
        download_missing(wheels, ROOT / "wheels")
    cli = extension_cli()
    output = Path(args.output_dir)
    output.mkdir(parents=True, exist_ok=True)
    for old in output.glob(f"{manifest['id']}-*.zip"):
        old.unlink()
    subprocess.run([sys.executable, str(cli), "build", "--source-dir", str(ROOT), "--output-dir", str(output),
                    "--split-platforms"], check=True)
    zips = sorted(output.glob(f"{manifest['id']}-{manifest['version']}-*.zip"))
    if len(zips) != len(manifest.get("platforms", [])):
        raise SystemExit(f"error: expected one zip per platform {manifest.get('platforms')}, got {zips}")
    for path in zips:
        result = subprocess.run([sys.executable, str(cli), "validate", str(path)], capture_output=True, text=True)
        if result.returncode != 0:
            raise SystemExit(f"error: {path.name} failed validation:\n{result.stdout}{result.stderr}")
        print(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}: "
              f"{path.stat().st_size / 2 ** 20:.0f} MB, validated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
