"""Bad input to ``python -m scratch_iridescence.mitsuba_bridge render``/``merge``: one line ``error: ...``, a non-zero status, no traceback,
nothing written and nothing rendered."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import quad, simple_scene
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.folder import export
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.cli.main import main
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr, write_exr

ROOT = Path(__file__).resolve().parents[3]
LLVM = ["--variant", "llvm_ad_spectral"]


@pytest.fixture(scope="module")
def good(variant, tmp_path_factory):
    """A scratched plate exported to ``good/``, plus a plain-diffuse folder ``plain/``."""
    base = tmp_path_factory.mktemp("cli")
    scratches = scratch.random_scratches(50, seed=1)
    plate = S.ScratchedMetal(scratches=scratches, coherence_diameter_m=30e-6)
    description = simple_scene(shapes=[S.Shape("plate", quad(1.0, "plate"), np.eye(4), "plate")],
                               materials={"plate": plate}, world=S.ConstantWorld((0.5, 0.5, 0.5)))
    export.export_folder(description, S.RenderSettings(spp=4), base / "good")
    export.export_folder(simple_scene(world=S.ConstantWorld((0.5, 0.5, 0.5))), S.RenderSettings(spp=4),
                         base / "plain")
    return base


def variant_of(good, name, edit):
    """A copy of the good folder with one thing broken by ``edit(folder)``."""
    import shutil

    folder = good / name
    if not folder.exists():
        shutil.copytree(good / "good", folder)
        edit(folder)
    return folder


def xml_edit(old, new):
    def edit(folder):
        text = (folder / "scene.xml").read_text()
        assert old in text, old
        (folder / "scene.xml").write_text(text.replace(old, new))
    return edit


def write(relative, data):
    def edit(folder):
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / relative).write_bytes(data)
    return edit


def remove(relative):
    return lambda folder: (folder / relative).unlink()


def extreme_file(field: str, value) -> bytes:
    """The bytes of a scratch file of 50 scratches with ``field`` set to ``value`` (written by numpy, unchecked)."""
    import io

    arrays = scratch.random_scratches(50, seed=1).as_dict()
    arrays[field] = value(arrays[field].copy())
    stream = io.BytesIO()
    np.savez(stream, format=np.array(scratch.FORMAT), **arrays)
    return stream.getvalue()


def _set(index, value):
    def change(array):
        array[index] = value
        return array
    return change


# (name, argv with {good} {plain} {out} {dir} placeholders, folder edit or None, expected words in the error)
CASES = [
    ("no arguments", ["render"], None, "required"),
    ("no output", ["render", "{good}"], None, "-o/--output"),
    ("unknown command", ["paint"], None, "invalid choice"),
    ("unknown option", ["render", "{good}", "-o", "{out}", "--fast"], None, "unrecognized arguments"),
    ("missing folder", ["render", "{dir}/nothing", "-o", "{out}"], None, "no such scene file"),
    ("folder without scene", ["render", "{dir}", "-o", "{out}"], None, "no such scene file"),
    ("spp -1", ["render", "{good}", "-o", "{out}", "--spp", "-1"], None, "--spp must be at least 1"),
    ("spp 0", ["render", "{good}", "-o", "{out}", "--spp", "0"], None, "--spp must be at least 1"),
    ("spp text", ["render", "{good}", "-o", "{out}", "--spp", "many"], None, "invalid int value"),
    ("seed -1", ["render", "{good}", "-o", "{out}", "--seed", "-1"], None, "--seed must be between"),
    ("seed 2**32", ["render", "{good}", "-o", "{out}", "--seed", str(2 ** 32)], None, "--seed must be between"),
    ("output folder missing", ["render", "{good}", "-o", "{dir}/no/such/out.exr"], None, "does not exist"),
    ("output is a folder", ["render", "{good}", "-o", "{dir}"], None, "must end in"),
    ("output .exr folder", ["render", "{good}", "-o", "{dir}/folder.exr"], None, "is a folder"),
    ("output .jpg", ["render", "{good}", "-o", "{dir}/out.jpg"], None, "must end in .exr or .png"),
    ("output without suffix", ["render", "{good}", "-o", "{dir}/out"], None, "must end in .exr or .png"),
    ("spp far too many", ["render", "{good}", "-o", "{out}", "--spp", "99999999999"], None,
     "render calls (at most 1,048,576)"),
    ("chunk 0/3", ["render", "{good}", "-o", "{out}", "--chunk", "0/3"], None, "K must be between 1 and N"),
    ("chunk 4/3", ["render", "{good}", "-o", "{out}", "--chunk", "4/3"], None, "K must be between 1 and N"),
    ("chunk text", ["render", "{good}", "-o", "{out}", "--chunk", "half"], None, "--chunk expects K/N"),
    ("chunk too many parts", ["render", "{good}", "-o", "{out}", "--chunk", "3/9", "--spp", "4"], None,
     "splits into at most 1 part, not 9"),
    ("chunk into png", ["render", "{good}", "-o", "{dir}/part.png", "--chunk", "1/2"], None, "a part is always an EXR"),
    ("unknown variant", ["render", "{good}", "-o", "{out}", "--variant", "magic"], None, "not part of this Mitsuba"),
    ("rgb variant", ["render", "{good}", "-o", "{out}", "--variant", "scalar_rgb"], None, "not spectral"),
    ("scene not xml", ["render", "{case}", "-o", "{out}"], write("scene.xml", b"garbage<"), "cannot load"),
    ("empty scene", ["render", "{case}", "-o", "{out}"], write("scene.xml", b'<scene version="3.0.0"/>'),
     "has no sensor"),
    ("unknown plugin", ["render", "{case}", "-o", "{out}"], xml_edit('type="path"', 'type="magic"'), "cannot load"),
    ("missing mesh", ["render", "{case}", "-o", "{out}"], remove("meshes/plate.ply"), "cannot load"),
    ("corrupt mesh", ["render", "{case}", "-o", "{out}"], write("meshes/plate.ply", b"ply\nformat nonsense\n"),
     "cannot load"),
    ("missing scratch file", ["render", "{case}", "-o", "{out}"], remove("scratches/plate.npz"), "does not exist"),
    ("corrupt scratch file", ["render", "{case}", "-o", "{out}"],
     write("scratches/plate.npz", b"PK\x03\x04" + bytes(300)), "scratch file"),
    # values beyond the format's bounds (docs/scratch-format.md): refused by name, never an internal error
    ("depth variation 1e300", ["render", "{case}", "-o", "{out}"],
     write("scratches/plate.npz", extreme_file("depth_variation", _set((0, 0), 1e300))),
     "amplitude must be at most 10"),
    ("variation frequency 1e300", ["render", "{case}", "-o", "{out}"],
     write("scratches/plate.npz", extreme_file("width_variation", _set((3, 1), 1e300))), "frequency at most 1"),
    ("uv spread to 1e300", ["render", "{case}", "-o", "{out}"],
     write("scratches/plate.npz", extreme_file("uv", _set((7, 0), 1e300))), "must lie within ±10000 UV units"),
    ("negative coherence diameter", ["render", "{case}", "-o", "{out}"],
     xml_edit('name="coherence_diameter" value="3e-05"', 'name="coherence_diameter" value="-3e-05"'),
     "coherence_diameter"),
    ("generate into a missing folder", ["generate", "{dir}/no/such/x.npz"], None, "does not exist"),
    ("generate -5 scratches", ["generate", "{dir}/x.npz", "--count", "-5"], None, "--count must be at least 1"),
    ("generate 1-vertex scratches", ["generate", "{dir}/x.npz", "--vertices", "1"], None, "at least 2 vertices"),
    ("generate inverted lengths", ["generate", "{dir}/x.npz", "--length-min", "2", "--length-max", "1"], None,
     "--length-min <= --length-max"),
    ("merge nothing", ["merge", "-o", "{out}"], None, "required"),
    ("merge missing part", ["merge", "{dir}/none.exr", "-o", "{out}"], None, "no such file"),
    ("merge to .jpg", ["merge", "{dir}/none.exr", "-o", "{dir}/m.jpg"], None, "must end in .exr or .png"),
]


@pytest.mark.parametrize("name, argv, edit, expected", CASES, ids=[case[0] for case in CASES])
def test_bad_input_gets_one_line_and_a_non_zero_status(good, tmp_path, capsys, name, argv, edit, expected):
    (tmp_path / "folder.exr").mkdir()
    case = variant_of(good, name.replace(" ", "_"), edit) if edit else None
    out = tmp_path / "out.exr"
    args = [a.format(good=good / "good", plain=good / "plain", out=out, dir=tmp_path, case=case) for a in argv]
    if args[0] == "render" and "--variant" not in args:
        args += LLVM
    try:
        status = main(args)
    except SystemExit as stop:  # argparse exits by itself
        status = stop.code
    err = capsys.readouterr().err.strip()
    assert status not in (0, None), err
    assert err.count("\n") == 0 and err.startswith("error: ") and "Traceback" not in err, err
    assert expected in err, err
    assert not out.exists() and not list(tmp_path.glob(".*tmp*"))


def test_a_corrupt_scratch_file_in_a_fresh_process_prints_one_line(good):
    folder = variant_of(good, "corrupt_scratch_file", write("scratches/plate.npz", b"PK\x03\x04" + bytes(300)))
    result = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(folder), "-o",
                             str(good / "x.exr"), *LLVM], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("error: cannot load"), result.stderr


def test_png_output_is_a_real_png(good, tmp_path):
    assert main(["render", str(good / "plain"), "-o", str(tmp_path / "out.png"), "--spp", "4", "-q", *LLVM]) == 0
    data = (tmp_path / "out.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    import mitsuba as mi

    image = np.asarray(mi.Bitmap(str(tmp_path / "out.png")))
    assert image.shape == (24, 32, 4) and image.dtype == np.uint8 and image[..., :3].max() > 0


def test_a_failed_write_keeps_the_previous_image(good, tmp_path, monkeypatch, capsys):
    from scratch_iridescence.mitsuba_bridge.files import images as output

    out = tmp_path / "out.exr"
    assert main(["render", str(good / "plain"), "-o", str(out), "--spp", "4", "-q", *LLVM]) == 0
    before = out.read_bytes()

    def full_disk(path, image, **kwargs):
        Path(path).write_bytes(b"half an EXR")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(output, "write_exr", full_disk)
    assert main(["render", str(good / "plain"), "-o", str(out), "--spp", "8", "-q", *LLVM]) == 1
    err = capsys.readouterr().err
    assert "No space left on device" in err and "previous file is unchanged" in err
    assert out.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["out.exr"]


def test_ctrl_c_ends_cleanly_with_status_130(good, tmp_path):
    """The child gets SIGINT's default disposition whatever the suite inherited: a suite started as a
    background job of a shell script (`make test-stress &`) ignores SIGINT, and so would the child."""
    out = tmp_path / "out.exr"
    write_exr(out, np.ones((2, 2, 3), np.float32))
    process = subprocess.Popen([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render", str(good / "plain"), "-o", str(out),
                                "--spp", "1000000", *LLVM], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, cwd=ROOT, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert "spp" in process.stdout.readline()  # loaded: the render is under way
    time.sleep(0.5)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130 and err.strip() == "interrupted: nothing was written", err
    assert read_exr(out).shape == (2, 2, 3)  # the previous file is untouched


def test_ctrl_c_while_a_python_plugin_loads_is_an_interruption_not_a_load_error(good, tmp_path, capsys):
    """Mitsuba's parser turns a KeyboardInterrupt raised in a Python plugin's constructor (a Ctrl-C during
    the seconds a dense scratch set takes to build) into a RuntimeError that carries only the traceback's
    text: it still ends as an interruption (130), not as "cannot load". The plugin raises what Python's
    SIGINT handler raises: a real signal would be handled on the main thread, and the parser builds plugins
    on worker threads too, so where the interrupt lands would depend on the thread."""
    import gc
    import shutil

    import mitsuba as mi

    class InterruptedLoad(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            raise KeyboardInterrupt

    mi.register_bsdf("test_interrupted_load", InterruptedLoad)
    folder = tmp_path / "interrupted-load"
    shutil.copytree(good / "plain", folder)
    text = (folder / "scene.xml").read_text()
    start = text.index('<bsdf type="diffuse"')
    end = text.index("</bsdf>", start) + len("</bsdf>")
    (folder / "scene.xml").write_text(text[:start] + '<bsdf type="test_interrupted_load" name="bsdf"/>' + text[end:])
    out = tmp_path / "out.exr"
    try:
        assert main(["render", str(folder), "-o", str(out), *LLVM]) == 130
    finally:
        gc.collect()
    assert capsys.readouterr().err.strip() == "interrupted: nothing was written" and not out.exists()


def test_a_mesh_file_with_nan_vertices_is_refused_by_name(variant, tmp_path, capsys):
    """Mitsuba's PLY reader checks vertices itself (meshes built in memory are checked by mitsuba_bridge.finite)."""
    positions = quad(4.0).positions.copy()
    positions[0, 2] = np.nan
    broken = S.MeshData("floor", positions, quad().faces, None, quad().uvs)
    export.export_folder(simple_scene(shapes=[S.Shape("floor", broken, np.eye(4), "grey")],
                                      world=S.ConstantWorld((0.5, 0.5, 0.5))), S.RenderSettings(), tmp_path / "nan")
    assert main(["render", str(tmp_path / "nan"), "-o", str(tmp_path / "out.exr"), "--spp", "4", "-q", *LLVM]) == 1
    err = capsys.readouterr().err
    assert '"floor.ply": mesh contains invalid vertex position data' in err and err.count("\n") == 1


def test_a_render_bigger_than_free_memory_is_refused_before_rendering(variant, tmp_path, capsys):
    export.export_folder(simple_scene(film=S.Film(60_000, 60_000), world=S.ConstantWorld((0.5, 0.5, 0.5))),
                         S.RenderSettings(), tmp_path / "huge")
    started = time.perf_counter()
    assert main(["render", str(tmp_path / "huge"), "-o", str(tmp_path / "out.exr"), "--spp", "4", *LLVM]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: a 60000 x 60000 render needs about ") and "GiB of memory" in err, err
    assert "only" in err and "is allowed (" in err and "\n" not in err
    assert time.perf_counter() - started < 30  # refused up front, not after allocating


def test_a_render_too_big_for_ulimit_v_is_refused_not_a_crash(variant, tmp_path):
    """Under ``ulimit -v 6000000`` a 10000 x 10000 render passed the old free-memory check and died with SIGSEGV."""
    import resource

    export.export_folder(simple_scene(film=S.Film(10_000, 10_000), world=S.ConstantWorld((0.5, 0.5, 0.5))),
                         S.RenderSettings(), tmp_path / "huge")

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (6_000_000 * 1024, resource.RLIM_INFINITY))

    result = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "render",
                             str(tmp_path / "huge"), "-o", str(tmp_path / "out.exr"), "--spp", "4", *LLVM],
                            capture_output=True, text=True, cwd=ROOT, timeout=300, preexec_fn=limit)
    assert result.returncode == 1, result.stderr
    err = result.stderr.strip()
    assert err.startswith("error: a 10000 x 10000 render needs about ") and "\n" not in err, err
    assert "is allowed (address-space limit, ulimit -v 5.7 GiB" in err and not (tmp_path / "out.exr").exists()


def test_a_render_too_big_for_its_container_s_cgroup_is_refused(variant, tmp_path, capsys, farm_cgroup):
    """A farm worker's cgroup v2 limit, laid out as /proc/self/cgroup and /sys/fs/cgroup are."""
    farm_cgroup(256, 100)
    export.export_folder(simple_scene(film=S.Film(1_500, 1_000), world=S.ConstantWorld((0.5, 0.5, 0.5))),
                         S.RenderSettings(), tmp_path / "big")
    assert main(["render", str(tmp_path / "big"), "-o", str(tmp_path / "out.exr"), "--spp", "4", *LLVM]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: a 1500 x 1000 render needs about ") and "\n" not in err, err
    assert "but only 156.0 MiB is allowed (cgroup v2 memory.max 256.0 MiB of /farm/worker, 100.0 MiB in use)" in err
