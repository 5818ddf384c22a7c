"""Benchmark: 1 000 instances of a mesh against 1 000 copies of it.

The same scene twice: a 5 120-triangle sphere placed 1 000 times on a grid,
once as collection instances (one mesh, 1 000 placements: the builder emits one
``shapegroup`` and 1 000 ``instance`` shapes) and once as 1 000 separate objects
each owning a copy of the mesh. For each: gather (depsgraph → description),
build + load (``mi.load_dict``, BVH included), and the process's resident
memory growth while building and loading. Target: memory grows with the unique
meshes, so instances need a small fraction of the copies' memory.

Each case runs in its own process (memory figures do not mix); times are the
best of ``--repeat`` runs. Run: ``.venv/bin/python tests/bench/bench_instancing.py``.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
COUNT = 1000


def resident_bytes() -> int:
    """Current resident set size (Linux ``/proc``; 0 elsewhere)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
    except (OSError, IndexError, ValueError):
        return 0
    import os

    return pages * os.sysconf("SC_PAGE_SIZE")


def build_scene(case: str) -> None:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=5, radius=0.4)
    ball = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    side = int(COUNT ** 0.5) + 1
    positions = [((i % side) - side / 2, (i // side) - side / 2, 0.0) for i in range(COUNT)]
    if case == "instances":
        source = bpy.data.collections.new("Ball")
        scene.collection.objects.unlink(ball)
        source.objects.link(ball)
        for index, position in enumerate(positions):
            empty = bpy.data.objects.new(f"Instance{index}", None)
            empty.instance_type, empty.instance_collection = "COLLECTION", source
            empty.location = position
            scene.collection.objects.link(empty)
    else:
        for index, position in enumerate(positions):
            copy = ball.copy()
            copy.data = ball.data.copy()
            copy.location = position
            scene.collection.objects.link(copy)
        bpy.data.objects.remove(ball)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    camera.location = (0, 0, 60)
    scene.camera = camera


def measure(case: str, repeat: int) -> dict:
    import bpy

    from scratch_iridescence.addon.render.gather import gather_scene, gather_settings
    from scratch_iridescence.mitsuba_bridge import builder
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    build_scene(case)
    activate("llvm_ad_spectral")
    settings = gather_settings(bpy.context.scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    gather_times, load_times = [], []
    description = None
    for _ in range(repeat):
        start = time.perf_counter()
        description = gather_scene(depsgraph)
        gather_times.append(time.perf_counter() - start)
    before = resident_bytes()
    scenes = []
    for _ in range(repeat):
        start = time.perf_counter()
        scenes.append(builder.load_scene(description, settings))
        load_times.append(time.perf_counter() - start)
        if len(scenes) == 1:
            grown = resident_bytes() - before  # the first load: nothing cached yet
    return {"case": case, "shapes": len(description.shapes), "unique_meshes": len({id(s.mesh) for s in description.shapes}),
            "triangles": description.triangle_count, "gather_s": min(gather_times), "load_s": min(load_times),
            "memory_mb": grown / 2 ** 20}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--case", choices=("instances", "copies"), help="measure one case (used internally)")
    arguments = parser.parse_args()
    if arguments.case:
        import scratch_iridescence

        scratch_iridescence.register()
        print(json.dumps(measure(arguments.case, arguments.repeat)))
        return
    results = {}
    for case in ("instances", "copies"):
        output = subprocess.run([sys.executable, __file__, "--case", case, "--repeat", str(arguments.repeat)],
                                check=True, capture_output=True, text=True, cwd=ROOT).stdout
        results[case] = json.loads(output.strip().splitlines()[-1])
    print(f"{COUNT} placements of a {results['instances']['triangles'] // COUNT}-triangle sphere "
          f"(best of {arguments.repeat}):")
    print(f"{'':12}{'unique meshes':>15}{'gather s':>11}{'build+load s':>14}{'memory MB':>12}")
    for case, result in results.items():
        print(f"{case:12}{result['unique_meshes']:>15}{result['gather_s']:>11.3f}{result['load_s']:>14.3f}"
              f"{result['memory_mb']:>12.1f}")
    instances, copies = results["instances"], results["copies"]
    print(f"instances / copies: memory {instances['memory_mb'] / max(copies['memory_mb'], 1e-9):.3f}, "
          f"build+load time {instances['load_s'] / copies['load_s']:.3f}, "
          f"gather time {instances['gather_s'] / copies['gather_s']:.3f}  (target: memory ratio ≪ 1)")


if __name__ == "__main__":
    main()
