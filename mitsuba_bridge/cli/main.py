"""Command line: ``python -m scratch_iridescence.mitsuba_bridge <command> ...``.

Commands
--------
info FILE...      summary of scratch files (validates them)
generate OUT      write a random scratch file for a flat UV square
render FOLDER     render a folder exported from Blender ("Export Mitsuba scene") to EXR or PNG
                  (--chunk K/N: only part K of N of the samples, for render farms;
                  --cluster ADDRESS: every chunk as a task on a Dask cluster)
render-frames B   render frames of a .blend (--frames 1-240 -o out/frame_####.exr [--cluster ADDRESS])
export-frames B   export frames of a .blend as scene folders (pip's bpy, no Blender binary)
merge PART...     combine the parts of one render into its image (bit for bit the whole render)
validate OUT      the plugin against a brute-force wave field over the direction-cosine plane (figure + numbers)
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import batch, farm
from .. import scratch
from ..device.memory import NotEnoughMemory, check_memory, format_bytes
from ..errors import ParameterError
from ..scratch.scratchset import MAX_SCRATCHES, MAX_VERTICES


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
    except ParameterError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    if args.count < 1:
        raise batch.CommandError(f"--count must be at least 1, got {args.count}", 2)
    if args.vertices < 2:
        raise batch.CommandError(f"--vertices: a scratch needs at least 2 vertices, got {args.vertices}", 2)
    needed = scratch.estimate_generate_bytes(args.count, args.vertices)
    if args.count > MAX_SCRATCHES or args.count * args.vertices > MAX_VERTICES:
        raise batch.CommandError(
            f"--count {args.count:,} of {args.vertices} vertices: a scratch file holds at most {MAX_SCRATCHES:,} "
            f"scratches and {MAX_VERTICES:,} vertices (these would also need about {format_bytes(needed)} of "
            "memory to generate)", 2)
    try:
        check_memory(needed, f"generating {args.count:,} scratches of {args.vertices} vertices",
                     advice="ask for fewer")
    except NotEnoughMemory as error:
        raise batch.CommandError(str(error)) from None
    if not 0 < args.length_min <= args.length_max:
        raise batch.CommandError(f"need 0 < --length-min <= --length-max, got {args.length_min} and "
                                 f"{args.length_max}", 2)
    if not Path(args.output).parent.is_dir():
        raise batch.CommandError(f"{args.output}: the folder {Path(args.output).parent} does not exist", 2)
    try:
        scratches = scratch.random_scratches(
            args.count, seed=args.seed, width=width, depth=depth, length=(args.length_min, args.length_max),
            vertices=args.vertices, curvature=args.curvature,
            profile=scratch.Profile[args.profile.upper()],
            depth_variation=tuple(args.depth_variation), width_variation=tuple(args.width_variation))
    except ValueError as error:
        raise batch.CommandError(str(error), 2) from None
    try:
        scratch.save(scratches, args.output, compress=args.compress)
    except OSError as error:
        raise batch.CommandError(f"cannot write {args.output}: {error}") from None
    print(f"wrote {args.output}: {scratches!r}")
    return 0


def _validate(args) -> int:
    try:
        from ..validation import fig15 as validation
    except ImportError as error:  # the extension zip leaves the validation and its reference out
        print(f"error: the validation is not part of this installation ({error}); run it from a source "
              "checkout: python -m scratch_iridescence.mitsuba_bridge validate OUT", file=sys.stderr)
        return 1

    results = validation.run(args.output)
    for name, entry in results["configs"].items():
        errors = entry["plugin_vs_height_field"]["550"]
        print(f"{name}: plugin vs height field at 550 nm: {100 * errors['all']:.3g} % relative L2 "
              f"({100 * errors['off_lobe']:.3g} % off the mirror lobe); crossing share "
              f"{100 * entry['crossing_share']:.3g} %")
    print(f"wrote {args.output}/validation.png and validation.json in {results['seconds']:.0f} s")
    return 0


def _whole_number(text: str) -> int:
    """An integer argument, also written as a float with no fraction (``1e9``, ``2.0``)."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid whole number: {text!r}") from None
    if not value.is_integer():  # (NaN and infinities are not integers either)
        raise argparse.ArgumentTypeError(f"invalid whole number: {text!r}")
    return int(value)


class _Parser(argparse.ArgumentParser):
    """Usage mistakes end in one line, like every other error of the command line."""

    def error(self, message):
        self.exit(2, f"error: {message} (see {self.prog} --help)\n")


def main(argv=None) -> int:
    """Entry point of ``python -m scratch_iridescence.mitsuba_bridge``: 0 on success, 1 on errors, 2 on usage errors, 130 on Ctrl-C."""
    try:
        return _main(argv)
    except batch.CommandError as error:
        print(f"error: {error}", file=sys.stderr)
        return error.status
    except KeyboardInterrupt:
        print("interrupted: nothing was written", file=sys.stderr)
        return 130


def _main(argv) -> int:
    parser = _Parser(prog="python -m scratch_iridescence.mitsuba_bridge", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    info = commands.add_parser("info", help="summarise and validate scratch files")
    info.add_argument("files", nargs="+")
    info.set_defaults(run=_info)

    gen = commands.add_parser("generate", help="write a random scratch file for a flat UV square")
    gen.add_argument("output")
    gen.add_argument("--count", type=_whole_number, default=3000, help="scratches (1e6 is read as 1000000)")
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument("--width", default="G[4, 1.3]", help="micrometres: U[a, b], G[mean, std] or a value")
    gen.add_argument("--depth", default="G[250, 80]", help="nanometres: U[a, b], G[mean, std] or a value")
    gen.add_argument("--length-min", type=float, default=0.2, help="UV units")
    gen.add_argument("--length-max", type=float, default=0.6, help="UV units")
    gen.add_argument("--vertices", type=_whole_number, default=8)
    gen.add_argument("--curvature", type=float, default=0.0, help="largest curvature, 1/UV units")
    gen.add_argument("--profile", choices=["rectangular", "triangular"], default="rectangular")
    gen.add_argument("--depth-variation", type=float, nargs=2, default=(1.1, 0.04), metavar=("AMP", "FREQ"))
    gen.add_argument("--width-variation", type=float, nargs=2, default=(0.0, 0.0), metavar=("AMP", "FREQ"))
    gen.add_argument("--compress", action="store_true")
    gen.set_defaults(run=_generate)

    render = commands.add_parser("render", help="render an exported scene folder to a linear EXR (or a PNG)")
    render.add_argument("folder", help="folder written by Blender's Export > Mitsuba Scene (or its scene.xml)")
    render.add_argument("-o", "--output", required=True,
                        help="output .exr (linear RGBA) or .png (8-bit sRGB, clipped); written only when complete")
    render.add_argument("--spp", type=int, default=None, help="samples per pixel (default: the scene's)")
    render.add_argument("--seed", type=int, default=None,
                        help="0 .. 2**32-1 (default: the scene's, as Blender's F12); the same seed gives the same image")
    render.add_argument("--chunk", metavar="K/N", help="render only part K of N of the sample schedule into an "
                                                       "EXR part file; combine all N with 'merge'")
    render.add_argument("--variant", default="auto",
                        help="Mitsuba variant (default auto: cuda_ad_spectral, else metal_ad_spectral when available, "
                             "else llvm_ad_spectral)")
    render.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    render.add_argument("--cluster", metavar="ADDRESS",
                        help="render the chunks as tasks on a Dask cluster: a scheduler address (tcp://host:8786) or "
                             "local:N (N worker processes here); the image is the one-machine render, bit for bit")
    render.add_argument("--chunks-per-task", type=int, metavar="N",
                        help="with --cluster: chunks per task, a power of two (default 1, grouped only for schedules "
                             "far longer than the workers)")
    render.set_defaults(run=farm.render_command)

    frames = commands.add_parser("render-frames", help="render frames of a .blend (exported with pip's bpy), here or "
                                                       "on a Dask cluster")
    frames.add_argument("blend", help="the .blend file (external files packed when workers share no disk)")
    frames.add_argument("--frames", required=True, help="frames: 1-240, 1..240, 1,5,10-12, 1-240:2")
    frames.add_argument("-o", "--output", required=True, help="image per frame: out/frame_####.exr (# = frame number)")
    frames.add_argument("--spp", type=int, default=None, help="samples per pixel (default: the scene's)")
    frames.add_argument("--seed", type=int, default=None, help="0 .. 2**32-1 (default: the scene's)")
    frames.add_argument("--variant", default="auto", help="Mitsuba variant (default auto)")
    frames.add_argument("--cluster", metavar="ADDRESS", help="a Dask scheduler address or local:N (see render)")
    frames.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    frames.set_defaults(run=farm.render_frames_command)

    exports = commands.add_parser("export-frames", help="export frames of a .blend as scene folders (pip's bpy)")
    exports.add_argument("blend")
    exports.add_argument("--frames", required=True, help="frames: 1-240, 1,5,10-12")
    exports.add_argument("-o", "--output", required=True, help="folder per frame: out/scene_#### (# = frame number)")
    exports.set_defaults(run=farm.export_frames_command)

    merge = commands.add_parser("merge", help="combine the parts of one render (render --chunk K/N) into its image")
    merge.add_argument("parts", nargs="+", help="part files (.exr) of the same render, every chunk exactly once "
                                                "(a folder: every .exr in it)")
    merge.add_argument("-o", "--output", required=True, help="output .exr or .png")
    merge.add_argument("--frame", type=int, help="frame number for the # runs of -o (frame_####.exr)")
    merge.set_defaults(run=farm.merge_command)

    validate = commands.add_parser("validate", help="compare the plugin with a brute-force wave field (needs "
                                                    "scipy and matplotlib: the dev extras)")
    validate.add_argument("output", help="folder for validation.png and validation.json")
    validate.set_defaults(run=_validate)

    args = parser.parse_args(argv)
    return args.run(args)

