"""Benchmark: render throughput of the paper's Fig. 7(b) plate, in samples per core-second.

3 000 scratches drawn as in the supplement (G_D[250, 80] nm, G_W[4, 1.3] µm,
depth variation D[1.1, 0.04], length 0.2 to 0.6 of the plate) on a 10 cm
aluminium plate under Mitsuba's ``sunsky`` emitter, 512 x 512 pixels, 64 spp
rendered in passes of ``--pass-spp``, path tracer of depth 3, llvm_ad_spectral.

Core-seconds are the process's CPU time (user + system, every thread), so the
figure does not depend on how many cores are free on a shared machine.  Target
(issue 3): at least 1e6 samples per core-second; the paper rendered this figure
at about 2.5e5 (docs/model.md §10).  ``roughconductor`` on the same plate gives the
cost of everything but the scratch BSDF.

Run: ``.venv/bin/python tests/bench/bench_render.py [--out out/plate.png]``.
"""
from __future__ import annotations

import argparse
import os
import resource
import time
from pathlib import Path


def cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--variant", default="llvm_ad_spectral", help="cuda_ad_spectral: on an NVIDIA GPU")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--pass-spp", type=int, default=8)
    parser.add_argument("--out", default="out/bench_plate.png", help="image written here (not tracked)")
    args = parser.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    from scratch_iridescence import mitsuba_bridge
    from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
    from scratch_iridescence.mitsuba_bridge import scratch

    mitsuba_bridge.register_plugins()
    start = time.perf_counter()
    scratches = scratch.random_scratches(
        3000, seed=7, width=scratch.Gaussian(4e-6, 1.3e-6), depth=scratch.Gaussian(250e-9, 80e-9),
        depth_variation=(1.1, 0.04), length=(0.2, 0.6), vertices=6, curvature=1.5)
    plate_bsdf = scratch_bsdf.plugin_dict(scratches, unit_scale=0.05, material="Al")  # 2 units = 10 cm

    def scene(bsdf):
        return mi.load_dict({
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 3},
            "sensor": {
                "type": "perspective", "fov": 38,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, -2.3, 1.9], target=[0, 0.1, 0],
                                                           up=[0, 0, 1]),
                "film": {"type": "hdrfilm", "width": args.size, "height": args.size,
                         "rfilter": {"type": "box"}},
                "sampler": {"type": "independent"},
            },
            "sky": {"type": "sunsky", "sun_direction": [0.0, 0.62, 0.78], "turbidity": 3.0},
            "plate": {"type": "rectangle", "bsdf": bsdf},
        })

    loaded = scene(plate_bsdf)
    print(f"scene: {loaded.shapes()[0].bsdf()}; built and loaded in {time.perf_counter() - start:.2f} s")

    def render(s, label):
        passes = args.spp // args.pass_spp
        total = None
        timings = []
        for i in range(passes):
            c0, w0 = cpu_seconds(), time.perf_counter()
            image = mi.render(s, spp=args.pass_spp, seed=i)
            dr.eval(image)
            dr.sync_thread()
            timings.append((cpu_seconds() - c0, time.perf_counter() - w0))
            total = image if total is None else total + image
        samples = args.size * args.size * args.pass_spp
        cpu = sum(t[0] for t in timings)
        steady = sum(t[0] for t in timings[1:])
        wall = sum(t[1] for t in timings)
        print(f"{label}: {passes} passes of {args.pass_spp} spp, wall {wall:.1f} s, cpu {cpu:.1f} core-s "
              f"(first pass, with kernel compilation: {timings[0][0]:.1f} core-s)")
        print(f"  {samples * passes / cpu:.3g} samples per core-second overall, "
              f"{samples * (passes - 1) / max(steady, 1e-9):.3g} after the first pass; "
              f"{samples * (passes - 1) / max(sum(t[1] for t in timings[1:]), 1e-9):.3g} samples per wall second "
              "after the first pass (the figure for a GPU)")
        return total / passes

    image = render(loaded, "scratch_diffraction")
    render(scene({"type": "roughconductor", "material": "Al", "alpha": 0.05}), "roughconductor (reference)")
    print("target: >= 1e6 samples per core-second (paper: 2.5e5); "
          f"machine: {os.cpu_count()} cores, shared")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    mi.util.write_bitmap(str(out), image)
    print(f"image: {out}")


if __name__ == "__main__":
    main()
