"""The Flamenco 3 job type (farm/flamenco/): compiled with node against a stand-in for Flamenco's documented
``author`` API, then its commands run here in dependency order, Blender's command line read by
``blender_cli.py`` on pip's bpy: the merged frame must equal the one-machine render, bit for bit."""
import json
import os
import shlex
import shutil
import subprocess
import sys

import pytest

from farm_paths import HERE, ROOT, VARIANT
from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

NODE = shutil.which("node")
pytestmark = pytest.mark.skipif(NODE is None, reason="node is not installed (make setup installs Debian's nodejs "
                                                     "where apt can)")
JOB_TYPE = ROOT / "farm" / "flamenco" / "scratch_iridescence_render.js"
CHUNKS = 3


def compile_job(tmp_path, **settings):
    (tmp_path / "settings.json").write_text(json.dumps(settings))
    result = subprocess.run([NODE, str(HERE / "flamenco_author.js"), str(JOB_TYPE), str(tmp_path / "settings.json")],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.fixture(scope="module")
def job(blend, tmp_path_factory):
    folder = tmp_path_factory.mktemp("flamenco")
    return compile_job(folder, filepath=str(blend), frames="1", chunks=CHUNKS, render_output_root=str(folder / "out"),
                       variant=VARIANT), folder / "out"


def test01_each_frame_is_an_export_n_chunks_and_a_merge_that_depends_on_them(blend, tmp_path):
    compiled = compile_job(tmp_path, filepath=str(blend), frames="1-2", chunks=CHUNKS,
                           render_output_root=str(tmp_path / "out"))
    tasks = {task["name"]: task for task in compiled["tasks"]}
    for frame in (1, 2):
        chunks = [f"chunk-{frame}-{k}" for k in range(1, CHUNKS + 1)]
        assert set(chunks + [f"export-{frame}", f"merge-{frame}"]) <= set(tasks)
        assert all(tasks[name]["dependencies"] == [f"export-{frame}"] for name in chunks)
        assert sorted(tasks[f"merge-{frame}"]["dependencies"]) == chunks
        chunk_args = [tasks[name]["commands"][0]["parameters"]["args"] for name in chunks]
        assert [args[args.index("--chunk") + 1] for args in chunk_args] == [f"{k}/{CHUNKS}" for k in range(1, 4)]
    assert len(tasks) == 2 * (CHUNKS + 2)
    for task in compiled["tasks"]:  # every Blender enables the extension itself: workers start factory-fresh
        command = task["commands"][0]
        assert command["name"] == "blender-render" and command["parameters"]["blendfile"] == str(blend)
        before = command["parameters"]["argsBefore"]
        assert before[:4] == ["-b", "--factory-startup", "--addons", "bl_ext.user_default.scratch_iridescence"]


def run_command(command, blender_user, log):
    """A blender-render command as Flamenco's worker builds it: {exe} {exeArgs} {argsBefore} {blendfile} {args},
    with the {blender} variable pointing at the bpy-based stand-in and {blenderargs} empty."""
    parameters = command["parameters"]
    assert command["name"] == "blender-render"
    exe = parameters["exe"].replace("{blender}", shlex.join([sys.executable, str(HERE / "blender_cli.py")]))
    argv = shlex.split(exe) + shlex.split(parameters.get("exeArgs", "").replace("{blenderargs}", "")) + \
        parameters.get("argsBefore", []) + [parameters["blendfile"]] + parameters.get("args", [])
    result = subprocess.run(argv, capture_output=True, text=True, timeout=600,
                            env={**os.environ, "BLENDER_USER_RESOURCES": str(blender_user)})
    log.append((argv, result.stdout, result.stderr))
    assert result.returncode == 0, f"{shlex.join(argv)}\n{result.stdout}\n{result.stderr}"
    return result


def test02_the_compiled_commands_render_the_one_machine_frame_bit_for_bit(job, blender_user, reference_frames):
    compiled, out = job
    out.mkdir(parents=True, exist_ok=True)
    (out / "work").mkdir(exist_ok=True)
    done, log = set(), []
    for task in compiled["tasks"]:  # job order; every dependency must have run before
        assert set(task["dependencies"]) <= done, task["name"]
        for command in task["commands"]:
            run_command(command, blender_user, log)
        done.add(task["name"])
    assert "wrote" in log[-1][1] and f"16 spp from {CHUNKS} parts" in log[-1][1], log[-1]
    merged = read_exr(out / "frame_0001.exr")
    assert merged.tobytes() == read_exr(reference_frames / "frame_0001.exr").tobytes()
