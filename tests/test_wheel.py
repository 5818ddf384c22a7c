"""The package as farm workers install it: a wheel built from the tracked files with ``python -m build``, installed
with pip, whose ``scratch-iridescence`` console script renders the same image, bit for bit, as this checkout."""
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("build")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel built from a copy of the tracked files (the checkout gets no build/ or egg-info)."""
    tracked = subprocess.run(["git", "ls-files"], capture_output=True, text=True, cwd=ROOT).stdout.split()
    if not tracked:
        pytest.skip("not a git checkout")
    source = tmp_path_factory.mktemp("source")
    for name in tracked:
        (source / name).parent.mkdir(parents=True, exist_ok=True)
        (source / name).write_bytes((ROOT / name).read_bytes())
    dist = tmp_path_factory.mktemp("dist")
    # --no-isolation: setuptools of this environment (the build needs no download).
    result = subprocess.run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(dist),
                             str(source)], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return next(dist.glob("scratch_iridescence-*.whl"))


def test01_the_wheel_holds_every_module_of_the_package_and_its_console_script(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    sources = [p.relative_to(ROOT).as_posix() for folder in ("mitsuba_bridge", "addon")
               for p in (ROOT / folder).rglob("*.py") if "__pycache__" not in p.parts]
    missing = sorted(f"scratch_iridescence/{name}" for name in sources if f"scratch_iridescence/{name}" not in names)
    assert not missing, missing
    assert not [name for name in names if name.startswith(("scratch_iridescence/tests", "scratch_iridescence/farm"))]
    entry_points = next(name for name in names if name.endswith("entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert "scratch-iridescence = scratch_iridescence.mitsuba_bridge.cli:main" in text
    metadata = zipfile.ZipFile(wheel).read(next(n for n in names if n.endswith("METADATA"))).decode()
    assert "Provides-Extra: cluster" in metadata and "distributed==2026.8.0" in metadata


@pytest.mark.slow  # installs the wheel and renders twice in fresh processes
def test02_its_console_script_renders_what_this_checkout_renders(wheel, tmp_path):
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-deps",
                    "--no-index", "--target", str(site), str(wheel)], check=True)
    environment = {"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"}
    where = subprocess.run([sys.executable, "-c", "import scratch_iridescence; print(scratch_iridescence.__file__)"],
                           capture_output=True, text=True, env=environment, cwd=tmp_path)
    assert where.stdout.strip().startswith(str(site)), where.stdout + where.stderr
    made = subprocess.run([str(site / "bin" / "scratch-iridescence"), "generate", str(tmp_path / "set.npz"), "--count",
                           "20"], capture_output=True, text=True, env=environment, cwd=tmp_path)
    assert made.returncode == 0, made.stderr
    # A scene folder exported by this checkout, rendered by the installed wheel and by this checkout.
    sys.path.insert(0, str(ROOT / "tests" / "bridge"))
    from bridge_scenes import simple_scene
    from scratch_iridescence.mitsuba_bridge import scene as S
    from scratch_iridescence.mitsuba_bridge.folder import export
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    activate("llvm_ad_spectral")
    export.export_folder(simple_scene(lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))]), S.RenderSettings(spp=4),
                         tmp_path / "scene")
    arguments = ["render", str(tmp_path / "scene"), "--spp", "9", "--variant", "llvm_ad_spectral", "-q", "-o"]
    installed = subprocess.run([str(site / "bin" / "scratch-iridescence"), *arguments, str(tmp_path / "wheel.exr")],
                               capture_output=True, text=True, env=environment, cwd=tmp_path)
    assert installed.returncode == 0, installed.stderr
    checkout = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", *arguments,
                               str(tmp_path / "checkout.exr")], capture_output=True, text=True, cwd=tmp_path)
    assert checkout.returncode == 0, checkout.stderr
    assert (tmp_path / "wheel.exr").read_bytes() == (tmp_path / "checkout.exr").read_bytes()
