"""Command line: ``python -m mitsuba_bridge <command> ...``.

Commands
--------
info FILE...      summary of scratch files (validates them)
generate OUT      write a random scratch file for a flat UV square
render FOLDER     render a folder exported from Blender ("Export Mitsuba scene") to EXR
validate OUT      the plugin against a brute-force wave field over the direction-cosine plane (figure + numbers)
"""
from __future__ import annotations

import argparse
import sys

from . import scratch


def _info(args) -> int:
    status = 0
    for path in args.files:
        try:
            scratches = scratch.load(path)
        except (scratch.ScratchFormatError, OSError) as error:
            print(f"error: {error}", file=sys.stderr)
            status = 1
            continue
        print(f"{path}: {scratches!r}")
        if scratches.count:
            lengths = scratch.scratch_lengths(scratches.uv, scratches.offsets)
            print(f"  width  {scratches.width.min() * 1e6:.4g} .. {scratches.width.max() * 1e6:.4g} um")
            print(f"  depth  {scratches.depth.min() * 1e9:.4g} .. {scratches.depth.max() * 1e9:.4g} nm")
            print(f"  length {lengths.min():.4g} .. {lengths.max():.4g} (UV units)")
            profiles = {p.name.lower(): int((scratches.profile == p).sum()) for p in scratch.Profile}
            print("  profiles " + ", ".join(f"{name} {n}" for name, n in profiles.items()))
    return status


def _generate(args) -> int:
    try:
        width = scratch.parse_distribution(args.width, "um")
        depth = scratch.parse_distribution(args.depth, "nm")
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    try:  # every argument is checked before anything is drawn or written
        scratches = scratch.random_scratches(
            args.count, seed=args.seed, width=width, depth=depth, length=(args.length_min, args.length_max),
            vertices=args.vertices, curvature=args.curvature,
            profile=scratch.Profile[args.profile.upper()],
            depth_variation=tuple(args.depth_variation), width_variation=tuple(args.width_variation))
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    scratch.save(scratches, args.output, compress=args.compress)
    print(f"wrote {args.output}: {scratches!r}")
    return 0


def _render(args) -> int:
    import time

    from .exr import write_exr
    from .export import load_folder
    from .render import render_passes
    from .variants import VariantError, activate

    try:
        variant = activate(args.variant)
    except (ImportError, VariantError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    started = time.perf_counter()
    try:
        scene = load_folder(args.folder)
    except (OSError, RuntimeError) as error:
        print(f"error: cannot load {args.folder}: {error}", file=sys.stderr)
        return 1
    spp = args.spp or scene.sensors()[0].sampler().sample_count()
    width, height = scene.sensors()[0].film().crop_size()
    print(f"{args.folder}: {width} x {height}, {spp} spp, {variant}, loaded in {time.perf_counter() - started:.2f} s",
          flush=True)
    progress = None
    for progress in render_passes(scene, spp, seed=args.seed):
        if not args.quiet:
            print(f"  {progress.spp_done:6d}/{spp} spp  {100 * progress.fraction:5.1f} %  {progress.seconds:7.1f} s",
                  flush=True)
    write_exr(args.output, progress.image)
    print(f"wrote {args.output} ({progress.seconds:.1f} s of rendering)")
    return 0


def _validate(args) -> int:
    from . import validation

    results = validation.run(args.output)
    for name, entry in results["configs"].items():
        errors = entry["plugin_vs_height_field"]["550"]
        print(f"{name}: plugin vs height field at 550 nm: {100 * errors['all']:.3g} % relative L2 "
              f"({100 * errors['off_lobe']:.3g} % off the mirror lobe); crossing share "
              f"{100 * entry['crossing_share']:.3g} %")
    print(f"wrote {args.output}/validation.png and validation.json in {results['seconds']:.0f} s")
    return 0


def main(argv=None) -> int:
    """Entry point of ``python -m mitsuba_bridge``."""
    parser = argparse.ArgumentParser(prog="python -m mitsuba_bridge", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)

    info = commands.add_parser("info", help="summarise and validate scratch files")
    info.add_argument("files", nargs="+")
    info.set_defaults(run=_info)

    gen = commands.add_parser("generate", help="write a random scratch file for a flat UV square")
    gen.add_argument("output")
    gen.add_argument("--count", type=int, default=3000)
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument("--width", default="G[4, 1.3]", help="micrometres: U[a, b], G[mean, std] or a value")
    gen.add_argument("--depth", default="G[250, 80]", help="nanometres: U[a, b], G[mean, std] or a value")
    gen.add_argument("--length-min", type=float, default=0.2, help="UV units")
    gen.add_argument("--length-max", type=float, default=0.6, help="UV units")
    gen.add_argument("--vertices", type=int, default=8)
    gen.add_argument("--curvature", type=float, default=0.0, help="largest curvature, 1/UV units")
    gen.add_argument("--profile", choices=["rectangular", "triangular"], default="rectangular")
    gen.add_argument("--depth-variation", type=float, nargs=2, default=(1.1, 0.04), metavar=("AMP", "FREQ"))
    gen.add_argument("--width-variation", type=float, nargs=2, default=(0.0, 0.0), metavar=("AMP", "FREQ"))
    gen.add_argument("--compress", action="store_true")
    gen.set_defaults(run=_generate)

    render = commands.add_parser("render", help="render an exported scene folder to a linear EXR")
    render.add_argument("folder", help="folder written by Blender's Export > Mitsuba Scene (or its scene.xml)")
    render.add_argument("-o", "--output", required=True, help="output .exr (linear RGBA)")
    render.add_argument("--spp", type=int, default=0, help="samples per pixel (default: the scene's)")
    render.add_argument("--seed", type=int, default=0)
    render.add_argument("--variant", default="auto",
                        help="Mitsuba variant (default auto: cuda_ad_spectral when available, else llvm_ad_spectral)")
    render.add_argument("-q", "--quiet", action="store_true", help="no per-pass progress lines")
    render.set_defaults(run=_render)

    validate = commands.add_parser("validate", help="compare the plugin with a brute-force wave field (needs "
                                                    "scipy and matplotlib: the dev extras)")
    validate.add_argument("output", help="folder for validation.png and validation.json")
    validate.set_defaults(run=_validate)

    args = parser.parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
