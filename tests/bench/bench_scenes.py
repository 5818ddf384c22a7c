"""Benchmark: exported scenes (File > Export > Mitsuba Scene) rendered as the command line renders them.

The paper's scenes need Blender to be built (``make paper``); exported, they
render anywhere Mitsuba runs, a GPU machine without Blender too.  For each
folder: load it (the scratch tables are built here), render ``--warm-spp``
twice (the first compiles the kernels; the second gives the rate), then the
largest power of two of samples per pixel, at most ``--max-spp``, that the
rate says fits in ``--seconds``, timed.  Rendering goes through the
bridge's own chunked, frozen passes (``render.render_chunks``, the same
schedule as ``render FOLDER``), so the figures are those a user gets.

Prints one line per scene: load seconds, first (compiling) pass, spp, seconds
and samples per second (wall: the figure for a GPU; the CPU benchmarks use core-seconds).
``--out DIR`` writes ``<scene>.png`` and ``means.npz`` (each image's 8×8-pixel block means, to
compare renders of other variants or machines without moving whole images) and ``scenes.json``.

Exporting the paper's scenes (needs bpy, ~3 min on 2 cores)::

    .venv/bin/python tests/bench/bench_scenes.py --export out/scenes [fig07_plate ...]

Rendering them (here, or with ``--variant cuda_ad_spectral`` on an NVIDIA GPU)::

    .venv/bin/python tests/bench/bench_scenes.py out/scenes/* --out out/bench_scenes
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

BLOCK = 8  #: pixels per side of the blocks whose means ``means.npz`` keeps
DEFAULT_FOLDER = Path("out/scenes")  #: rendered when no folder is named (``make bench``)


def export(folder: Path, only: list[str]) -> None:
    """Build each selected paper render's scene with the add-on (as ``make paper`` does) and export it."""
    from scratch_iridescence.scenes import paper

    folder.mkdir(parents=True, exist_ok=True)
    import bpy

    from scratch_iridescence import register  # the add-on, as Blender enables it

    register()
    index = []
    for module, figure in paper.figures(only or None):
        for render in figure.renders:
            bpy.ops.wm.read_factory_settings(use_empty=True)
            began = time.perf_counter()
            module.build_scene(bpy.context.scene, resolution=tuple(render.resolution), samples=render.samples,
                               **render.options)
            name = f"{module.__name__.rsplit('.', 1)[1]}-{render.name}"
            result = bpy.ops.scratch.export_mitsuba(directory=str(folder / name))
            if "FINISHED" not in result:
                raise RuntimeError(f"{name}: export did not finish: {result}")
            print(f"{name}: built and exported in {time.perf_counter() - began:.1f} s", flush=True)
            index.append({"name": name, "label": f"{figure.label} {render.name}",
                          "paper_minutes": render.paper_minutes,
                          "paper_samples_per_core_second": render.paper_samples_per_core_second})
    (folder / "index.json").write_text(json.dumps(index, indent=1))


def block_means(image: np.ndarray) -> np.ndarray:
    """Means of ``BLOCK`` × ``BLOCK`` pixel blocks (edges cropped), float32."""
    height, width = (image.shape[0] // BLOCK) * BLOCK, (image.shape[1] // BLOCK) * BLOCK
    cropped = image[:height, :width].astype(np.float64)
    return cropped.reshape(height // BLOCK, BLOCK, width // BLOCK, BLOCK, -1).mean(axis=(1, 3)).astype(np.float32)


def render_folders(folders: list[Path], args) -> list[dict]:
    from scratch_iridescence.mitsuba_bridge.cli import batch
    from scratch_iridescence.mitsuba_bridge.render import passes as render
    from scratch_iridescence.mitsuba_bridge.folder.export import load_folder
    from scratch_iridescence.mitsuba_bridge.files.images import write_image
    from scratch_iridescence.mitsuba_bridge.render.schedule import sample_schedule
    from scratch_iridescence.mitsuba_bridge.device.variants import on_gpu
    from scratch_iridescence.mitsuba_bridge.render.activation import activate

    variant = activate(args.variant)
    out = Path(args.out) if args.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    results, means = [], {}

    def timed_render(scene, spp, pixels):
        began = time.perf_counter()
        progress = None
        for progress in render.render_chunks(scene, sample_schedule(spp, pixels, args.seed, gpu=on_gpu()), spp):
            pass
        return time.perf_counter() - began, progress

    for folder in folders:
        name = folder.name
        try:
            began = time.perf_counter()
            scene = load_folder(folder)
            load_s = time.perf_counter() - began
            width, height = (int(c) for c in scene.sensors()[0].film().crop_size())
            pixels = width * height
            first_s, _ = timed_render(scene, args.warm_spp, pixels)
            warm_s, _ = timed_render(scene, args.warm_spp, pixels)
            rate = pixels * args.warm_spp / max(warm_s, 1e-6)
            spp = args.warm_spp
            while spp * 2 <= args.max_spp and pixels * spp * 2 / rate <= args.seconds:
                spp *= 2
            seconds, progress = timed_render(scene, spp, pixels)
        except Exception as error:  # noqa: BLE001 - one scene failing must not cost the others' figures
            print(f"{name}: FAILED: {batch.one_line(error)}", flush=True)
            results.append({"name": name, "error": batch.one_line(error)})
            continue
        image = progress.image
        row = {"name": name, "variant": variant, "width": width, "height": height, "load_s": load_s,
               "first_pass_s": first_s, "spp": spp, "seconds": seconds, "samples_per_s": pixels * spp / seconds,
               "mean_rgb": [float(v) for v in image[..., :3].reshape(-1, 3).mean(axis=0)],
               "traced_note": progress.traced_note}
        results.append(row)
        print(f"{name}: {width} x {height}, load {load_s:.1f} s, first {args.warm_spp} spp {first_s:.1f} s, "
              f"{spp} spp in {seconds:.1f} s = {row['samples_per_s']:.3g} samples/s"
              + (f" ({progress.traced_note})" if progress.traced_note else ""), flush=True)
        if out:  # after every scene: a run cut short keeps what it measured
            write_image(out / f"{name}.png", image)
            means[name] = block_means(image)
            np.savez_compressed(out / "means.npz", **means)
            (out / "scenes.json").write_text(json.dumps({"variant": variant, "cpu_count": os.cpu_count(),
                                                         "scenes": results}, indent=1))
        del scene
    return results


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--export", type=Path, help="build and export the paper's scenes into this folder")
    parser.add_argument("--variant", default="auto", help="llvm_ad_spectral, cuda_ad_spectral or auto")
    parser.add_argument("--warm-spp", type=int, default=16)
    parser.add_argument("--max-spp", type=int, default=16384, help="the paper's 16 384 by default")
    parser.add_argument("--seconds", type=float, default=20.0, help="time aimed at per scene")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="folder for PNGs, means.npz and scenes.json")
    args = parser.parse_args()
    if args.export:
        export(args.export, [str(f) for f in args.folders])
        return 0
    given = args.folders or sorted(DEFAULT_FOLDER.glob("*"))
    folders = [f for f in given if (f / "scene.xml").is_file()]
    if not folders:  # `make bench` runs every benchmark without arguments: say what this one needs
        print(f"no exported scenes in {', '.join(map(str, given)) or DEFAULT_FOLDER}: export them first "
              f"(--export {DEFAULT_FOLDER})")
        return 0 if not args.folders else 2
    results = render_folders(folders, args)
    return 1 if any("error" in r for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
