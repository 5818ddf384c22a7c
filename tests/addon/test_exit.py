"""A process that ends while the Rendered viewport's worker renders exits cleanly.

Before the exit handler of ``addon/render/viewport.py``, the interpreter and then Dr.Jit's C++ state were
torn down under the worker's running kernel: "terminate called without an active exception" and SIGABRT,
three runs in three (the script below, 256 x 192, passes without end).
"""
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("bpy")

HERE = Path(__file__).resolve().parent

EXIT_WITH_A_PASS_IN_FLIGHT = r"""
import sys, time
from types import SimpleNamespace
sys.path.insert(0, sys.argv[-1])
import bpy
import scratch_iridescence
scratch_iridescence.register()
from render_scenes import add_camera, add_light, set_world, setup_render
from scratch_iridescence.addon.render.viewport import ViewportRender

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_plane_add(size=2.0)
scene = setup_render(bpy.context.scene, 256, 192)
scene.scratch_iridescence.viewport_samples = 100000  # passes without end: one is always in flight
camera = add_camera(scene, location=(0, 0, 3))
add_light(scene, "POINT", location=(0.3, 0.5, 2.0), energy=200.0)
set_world(scene, colour=(0.1, 0.1, 0.1))
depsgraph = bpy.context.evaluated_depsgraph_get()
region_data = SimpleNamespace(view_matrix=camera.matrix_world.inverted(),
                              window_matrix=camera.calc_matrix_camera(depsgraph, x=256, y=192), is_perspective=True)
viewport = ViewportRender()
viewport.view_update(SimpleNamespace(region=SimpleNamespace(width=256, height=192), region_data=region_data),
                     depsgraph)
end = time.monotonic() + 300
while (viewport.latest()[0] is None or viewport.latest()[0].spp_done < 2) and time.monotonic() < end:
    time.sleep(0.02)
print("PASSES RUNNING", viewport.latest()[0].spp_done, flush=True)
"""


@pytest.mark.slow  # ~20 s of a fresh Blender rendering; `make test-blender` ends every Blender of its matrix this way too
def test_exit_while_a_viewport_pass_is_in_flight_is_clean(tmp_path):
    result = subprocess.run([sys.executable, "-c", EXIT_WITH_A_PASS_IN_FLIGHT, str(HERE)], capture_output=True,
                            text=True, cwd=tmp_path, timeout=600)
    log = result.stdout + result.stderr
    assert "PASSES RUNNING" in result.stdout, log
    assert "terminate called" not in log
    assert result.returncode == 0, (result.returncode, -signal.SIGABRT, log)
