"""Benchmark: what a render of an exported scene spends on the scratch BSDF, by variants rendered alternately.

docs/bsdf.md (Performance, "Where a grating sample's time goes") asks where the time of a sample goes in
a paper scene whose target is tight (the incoherent Fig. 9 grating).  This script renders one exported
folder (File > Export > Mitsuba Scene; ``bench_scenes.py --export out/scenes fig09_grating``) with
``mi.render`` in one process, in rounds, each round every variant once (CPU time, so the figure is
samples per core-second; the best round counts, the machine being shared):

* ``scratched``: the scene as exported;
* ``diffuse``, ``roughconductor`` (Al, GGX α 0.1), ``conductor`` (Al): Mitsuba's own BSDFs in the scratch
  BSDF's place — a smooth BSDF that the path tracer samples lights for, Mitsuba's glossy metal, and a
  delta BSDF (no light sampled: not a fair floor for a glossy BSDF);
* ``no-scan``, ``no-lookups``, ``one-fresnel``: the scratch BSDF with parts of its model switched off by
  patching them for that render only (wrong pictures, right costs): the search for pieces in the window,
  that search and the periodic families' lookup, and the conductor Fresnel's per-wavelength arithmetic
  (one η, k for all four wavelengths, so Dr.Jit evaluates it once per lane);
* ``search-again``: every fold over the window's pieces searches the grid anew instead of replaying the
  pieces that the light sample's evaluation found (``model._fold_pieces``; the same picture): a path's
  vertex on the plate then searches three times instead of once, so the difference to ``scratched`` is
  the price of two searches;
* ``no-vzeroupper``: the scene as exported, its kernels compiled without the ``vzeroupper`` before
  calls out of a kernel that the add-on asks LLVM for (``mitsuba_bridge/device/llvm_target.py``; Intel CPUs
  with AVX-512 otherwise enter Embree's SSE code at a penalty);
* ``no-amplitude``: each piece's far-field amplitude (along factor and cross-section, the Faddeeva
  evaluations; coherent sets: the incoherent mode sums intensities instead) replaced by zero, its
  sampling weights and densities kept: an upper bound of what the amplitudes cost (paths that a scratch
  would have carried on end there, which saves their later vertices too).

``--llvm-widths 16 32`` renders every variant at each SIMD width of Dr.Jit's CPU backend (lanes per
packet; the backend's own choice is the widest vector register, 16 with AVX-512), the scene loaded anew at
each (Embree's packet entry point is chosen when the scene is built), through
``mitsuba_bridge.device.llvm_target.configure``.  docs/bsdf.md (Performance, "vzeroupper
before calls") has what that showed.

Prints each variant's best samples per core-second and its ratio to ``scratched``, and, when the folder
has the paper's time (``index.json`` of ``--export``), the ratio per wavelength sample against the paper.

    .venv/bin/python tests/bench/bench_render_costs.py [out/scenes/fig09_grating-incoherent] [--rounds 3] [--spp 64]
        [--variants scratched diffuse ...] [--llvm-widths 16 32]
"""
from __future__ import annotations

import argparse
import contextlib
import json
import re
import resource
import sys
from pathlib import Path

DEFAULT_FOLDER = Path("out/scenes/fig09_grating-incoherent")  #: rendered when none is named (``make bench``)
#: Mitsuba's BSDFs put in the scratch BSDF's place (its id kept, so the shapes still refer to it)
SWAPS = {
    "diffuse": '<bsdf type="diffuse"{id}/>',
    "roughconductor": '<bsdf type="roughconductor"{id}><string name="material" value="Al"/>'
                      '<float name="alpha" value="0.1"/></bsdf>',
    "conductor": '<bsdf type="conductor"{id}><string name="material" value="Al"/></bsdf>',
}
PATCHES = ("no-scan", "no-lookups", "one-fresnel", "search-again", "no-amplitude")
#: Variants that render the scene as exported with another code generation target.
TARGETS = ("no-vzeroupper",)
#: Wavelengths per path here (Mitsuba's spectral variants) and per sample in the paper's renderer.
WAVELENGTHS, PAPER_WAVELENGTHS = 4, 16


def cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def scene_text(folder: Path, swap: str | None) -> str:
    text = (folder / "scene.xml").read_text()
    if swap is None:
        return text
    text, count = re.subn(r'<bsdf type="scratch_diffraction"(\s+id="[^"]*")\s*>.*?</bsdf>',
                          lambda match: SWAPS[swap].format(id=match.group(1)), text, flags=re.S)
    if not count:
        raise SystemExit(f"{folder}: no scratch_diffraction BSDF to swap for {swap}")
    return text


def load(folder: Path, swap: str | None):
    """The folder's scene (with ``swap`` in the scratch BSDF's place), its relative paths resolved there."""
    import mitsuba as mi

    resolver = mi.file_resolver()
    resolver.prepend(str(folder.resolve()))
    try:
        return mi.load_string(scene_text(folder, swap), parallel=False)  # (serial: export.load_folder)
    finally:
        del resolver[0]


@contextlib.contextmanager
def patched(name: str | None):
    """The scratch model with one part switched off while the scene is traced (``PATCHES``)."""
    import drjit as dr
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge.bsdf import model
    from scratch_iridescence.mitsuba_bridge.bsdf.maths.complexmath import Cx
    from scratch_iridescence.mitsuba_bridge.bsdf.fresnel import fresnel_conductor

    saved = {"for_each_segment": model.for_each_segment, "find_family": model.find_family,
             "_reflectance": model.Model._reflectance, "_fold_pieces": model._fold_pieces,
             "amplitude": model.amplitude}
    if name in ("no-scan", "no-lookups"):
        scan = saved["for_each_segment"]
        model.for_each_segment = lambda grid, jac, radius, state, body, active: scan(
            grid, jac, radius, state, body, mi.Bool(False))
    if name == "no-lookups":
        find = saved["find_family"]
        model.find_family = lambda grid, jac, sigma, active: find(grid, jac, sigma, mi.Bool(False))
    if name == "one-fresnel":
        def reflectance(self, si, cos_theta, active):
            eta, k = (texture.eval(si, active)[0] for texture in (self.eta, self.k))
            return fresnel_conductor(cos_theta, mi.Spectrum(eta), mi.Spectrum(k))
        model.Model._reflectance = reflectance
    if name == "search-again":
        fold = saved["_fold_pieces"]
        model._fold_pieces = lambda grid, jac, radius, state, body, scanning, found: fold(
            grid, jac, radius, state, body, scanning, None)
    if name == "no-amplitude":
        model.amplitude = lambda segment, xi_x, xi_y, k_z, sigma: Cx(dr.zeros(mi.Spectrum), dr.zeros(mi.Spectrum))
    try:
        yield
    finally:
        for key, value in saved.items():
            setattr(model.Model if key == "_reflectance" else model, key, value)


def paper_rate(folder: Path) -> float | None:
    index = folder.parent / "index.json"
    if not index.is_file():
        return None
    entry = next((e for e in json.loads(index.read_text()) if e.get("name") == folder.name), None)
    return None if entry is None else entry.get("paper_samples_per_core_second")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", type=Path)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--variants", nargs="*", default=["scratched", *SWAPS, *PATCHES, *TARGETS])
    parser.add_argument("--llvm-widths", nargs="*", type=int, default=[],
                        help="SIMD widths (lanes per packet: 4, 8, 16 or 32) to render each variant at")
    args = parser.parse_args()
    if any(width not in (4, 8, 16, 32) for width in args.llvm_widths):
        parser.error("--llvm-widths: Embree takes packets of 4, 8, 16 or 32 rays")
    folder = args.folder or DEFAULT_FOLDER
    if not (folder / "scene.xml").is_file():  # `make bench` runs every benchmark without arguments
        print(f"no exported scene in {folder}: export it first "
              "(tests/bench/bench_scenes.py --export out/scenes fig09_grating)")
        return 0 if args.folder is None else 2

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_spectral")
    from scratch_iridescence import mitsuba_bridge
    from scratch_iridescence.mitsuba_bridge.device import llvm_target
    from scratch_iridescence.mitsuba_bridge.render.passes import film_pixels

    mitsuba_bridge.register_plugins()
    widths = args.llvm_widths or [None]
    labels = [(variant, width, variant if width is None else f"{variant}@{width}")
              for width in widths for variant in args.variants]
    best: dict[str, float] = {}
    for round_ in range(args.rounds + 1):  # round 0 compiles every variant's kernels
        for variant, width, label in labels:
            # as activate() sets it, or as asked; a changed target compiles the kernels anew
            if not llvm_target.configure(vzeroupper=variant != "no-vzeroupper", vector_width=width):
                raise SystemExit("this Dr.Jit exports no jit_llvm_set_target: --llvm-widths and "
                                 "no-vzeroupper cannot be measured")
            scene = load(folder, variant if variant in SWAPS else None)
            pixels = film_pixels(scene)
            with patched(variant if variant in PATCHES else None):
                spp = 4 if round_ == 0 else args.spp
                start = cpu_seconds()
                dr.eval(mi.render(scene, spp=spp, seed=round_))
                dr.sync_thread()
                rate = pixels * spp / (cpu_seconds() - start)
            if round_:
                best[label] = max(best.get(label, 0.0), rate)
            del scene
        if round_:
            print(f"round {round_}: " + ", ".join(f"{label} {best[label]:.3g}" for *_, label in labels), flush=True)
    reference = best.get(labels[0][2])
    paper = paper_rate(folder)
    print(f"{folder.name}, {args.spp} spp, best of {args.rounds} rounds, samples per core-second:")
    for *_, label in labels:
        line = f"  {label:18s} {best[label]:.3g}"
        if reference:
            line += f"  ({best[label] / reference:.2f}x {labels[0][2]})"
        if paper:
            line += f"  {best[label] / paper * WAVELENGTHS / PAPER_WAVELENGTHS:.2f}x the paper per wavelength sample"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
