"""``render --chunk K/N`` and ``merge``: parts of one render combine into exactly the whole render."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import simple_scene
from scratch_iridescence.mitsuba_bridge.folder import export
from scratch_iridescence.mitsuba_bridge.render import parts, schedule
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.cli.main import main
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

ROOT = Path(__file__).resolve().parents[3]
VARIANT = ["--variant", "llvm_ad_spectral"]
SPP = "31"  # 32 x 24 pixels: seven chunks of 4 spp, then 2 and 1 (nine chunks: uneven trees)


@pytest.fixture(scope="module", params=S.SAMPLERS)
def folder(variant, tmp_path_factory, request):
    """The scene exported with each sampler (the stratified default and the independent one): parts of either
    merge into its whole render."""
    path = tmp_path_factory.mktemp("chunks") / "scene"
    description = simple_scene(lights=[S.PointLight((0, 0, 2), (1.0, 1.0, 1.0))],
                               world=S.ConstantWorld((0.2, 0.2, 0.2)))
    export.export_folder(description, S.RenderSettings(spp=4, sampler=request.param), path)
    return path


def render(folder, output, *extra):
    assert main(["render", str(folder), "-o", str(output), "--spp", SPP, "--seed", "3", "-q", *VARIANT,
                 *extra]) == 0
    return output


@pytest.fixture(scope="module")
def whole(folder):
    return read_exr(render(folder, folder.parent / "whole.exr"))


def test01_parts_carry_their_chunks_and_sample_count(folder, tmp_path):
    import OpenEXR

    render(folder, tmp_path / "p2.exr", "--chunk", "2/3")
    with OpenEXR.File(str(tmp_path / "p2.exr"), separate_channels=True) as file:
        header = dict(file.header())  # the live header is emptied when the file closes
    chunks = schedule.sample_schedule(31, 32 * 24, 3)
    run = schedule.part_range(2, 3, len(chunks))
    assert (header["chunkFirst"], header["chunkStop"]) == (run.start, run.stop) == (3, 6)
    assert header["samples"] == sum(c.spp for c in chunks[3:6]) == 12
    assert header["render.spp"] == 31 and header["render.chunk_count"] == 9
    assert read_exr(tmp_path / "p2.exr").shape == (24, 32, 4)  # its own mean, viewable as it is


@pytest.mark.parametrize("count", [1, 2, 4, 9])
def test02_merged_parts_equal_the_whole_render_bit_for_bit(folder, whole, tmp_path, count):
    files = [render(folder, tmp_path / f"part{k}.exr", "--chunk", f"{k}/{count}") for k in range(1, count + 1)]
    assert main(["merge", *map(str, reversed(files)), "-o", str(tmp_path / "merged.exr")]) == 0  # any order
    merged = read_exr(tmp_path / "merged.exr")
    assert merged.tobytes() == whole.tobytes()


def test03_parts_of_different_splits_merge_too(folder, whole, tmp_path):
    """Part 1 of 2 (chunks 0-3) with parts 3 and 4 of 4 (chunks 4-5 and 6-8): every chunk once."""
    files = [render(folder, tmp_path / "a.exr", "--chunk", "1/2"), render(folder, tmp_path / "b.exr", "--chunk", "3/4"),
             render(folder, tmp_path / "c.exr", "--chunk", "4/4")]
    image, _ = parts.merge_parts(files)
    assert image.tobytes() == whole.tobytes()


def test04_two_whole_renders_are_identical(folder, whole, tmp_path):
    assert read_exr(render(folder, tmp_path / "again.exr")).tobytes() == whole.tobytes()


@pytest.fixture(scope="module")
def thirds(folder, tmp_path_factory):
    path = tmp_path_factory.mktemp("thirds")
    return [render(folder, path / f"t{k}.exr", "--chunk", f"{k}/3") for k in (1, 2, 3)]


def refused(capsys, *argv):
    status = main(["merge", *map(str, argv)])
    err = capsys.readouterr().err.strip()
    assert status == 1 and "\n" not in err and err.startswith("error: "), err
    return err


def test05_missing_and_duplicated_chunks_are_refused(thirds, tmp_path, capsys):
    out = tmp_path / "m.exr"
    assert "chunks 3-5 of 9 are missing" in refused(capsys, thirds[0], thirds[2], "-o", out)
    assert "chunks 3-5 are in both" in refused(capsys, *thirds, thirds[1], "-o", out)
    assert not out.exists()


def test06_parts_of_other_renders_are_refused(folder, thirds, tmp_path, capsys):
    other_seed = tmp_path / "seed.exr"
    assert main(["render", str(folder), "-o", str(other_seed), "--spp", SPP, "--seed", "4", "-q", *VARIANT,
                 "--chunk", "2/3"]) == 0
    message = refused(capsys, thirds[0], other_seed, thirds[2], "-o", tmp_path / "m.exr")
    assert "different renders: seed 4 vs 3" in message
    other_spp = tmp_path / "spp.exr"
    assert main(["render", str(folder), "-o", str(other_spp), "--spp", "30", "--seed", "3", "-q", *VARIANT,
                 "--chunk", "2/3"]) == 0
    assert "different renders: spp 30 vs 31" in refused(capsys, thirds[0], other_spp, "-o", tmp_path / "m.exr")


def test07_parts_of_another_scene_are_refused(folder, thirds, tmp_path, capsys):
    moved = tmp_path / "scene"
    export.export_folder(simple_scene(lights=[S.PointLight((0, 0, 2), (2.0, 1.0, 1.0))],
                                      world=S.ConstantWorld((0.2, 0.2, 0.2))), S.RenderSettings(spp=4), moved)
    other = render(moved, tmp_path / "other.exr", "--chunk", "2/3")
    assert "different renders: scene" in refused(capsys, thirds[0], other, thirds[2], "-o", tmp_path / "m.exr")


def test08_files_that_are_not_parts_are_refused(whole, folder, thirds, tmp_path, capsys):
    assert "not a render part" in refused(capsys, folder.parent / "whole.exr", "-o", tmp_path / "m.exr")
    (tmp_path / "text.exr").write_text("not an image")
    assert "not an EXR file" in refused(capsys, tmp_path / "text.exr", "-o", tmp_path / "m.exr")
    assert "no such file" in refused(capsys, tmp_path / "none.exr", "-o", tmp_path / "m.exr")
    (tmp_path / "cut.exr").write_bytes(thirds[0].read_bytes()[:300])  # an interrupted copy
    assert "not a readable render part" in refused(capsys, tmp_path / "cut.exr", "-o", tmp_path / "m.exr")


def test09_parts_made_with_other_software_are_refused(thirds, tmp_path, capsys, monkeypatch):
    import OpenEXR

    with OpenEXR.File(str(thirds[1]), separate_channels=True) as file:
        header, channels = dict(file.header()), {name: c.pixels for name, c in file.channels().items()}
    header["render.software"] = "mitsuba 3.0.0, drjit 0.4.0"
    OpenEXR.File(header, channels).write(str(tmp_path / "old.exr"))
    assert "different renders: software 'mitsuba 3.0.0, drjit 0.4.0' vs" in refused(
        capsys, thirds[0], tmp_path / "old.exr", thirds[2], "-o", tmp_path / "m.exr")


def test10_merge_runs_as_a_command(thirds, whole, tmp_path):
    result = subprocess.run([sys.executable, "-m", "scratch_iridescence.mitsuba_bridge", "merge", *map(str, thirds), "-o",
                             str(tmp_path / "m.exr")], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    assert "31 spp from 3 parts" in result.stdout
    assert read_exr(tmp_path / "m.exr").tobytes() == whole.tobytes()
