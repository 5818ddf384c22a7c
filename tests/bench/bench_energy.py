"""Benchmark (physics): directional albedo of deep scratches under the depth phases (issue 12, item 2).

One long scratch through a coherence window of σ = 5 µm (the default δ_c = 30 µm) on a perfect
mirror; the albedo ∫ f_r cos θ_o dω = ∫ f_r d(ω_o,t) by the midpoint rule on a grid of direction
cosines (``--resolution`` per axis; the flat mirror integrates to 1 within 1 % at 700).  Printed:
the largest albedo over 450/550/650/750 nm at each incidence, for ``depth_phase="kirchhoff"``
(the paper's phase), ``"incidence"`` (a screen fixed by ω_i) and ``"bounded"`` (Kirchhoff divided by
max(1, Â(ω_i), Â(ω_o)), docs/model.md §4.1); ``--phases`` and ``--cases`` select.

Run: ``.venv/bin/python tests/bench/bench_energy.py``.
"""
from __future__ import annotations

import argparse

import numpy as np

CASES = {  # name: (width µm, depth µm, V-groove)
    "rect W 1, D 1 µm (Fig. 9)": (1.0, 1.0, False),
    "rect W 6, D 6 µm (Fig. 1)": (6.0, 6.0, False),
    "rect W 20, D 10 µm": (20.0, 10.0, False),
    "rect W 0.2, D 10 µm": (0.2, 10.0, False),
    "V W 2, D 1 µm": (2.0, 1.0, True),
}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", type=int, default=700)
    parser.add_argument("--incidences", type=float, nargs="*", default=[0.0, 40.0, 60.0, 80.0])
    parser.add_argument("--phases", nargs="*", default=["kirchhoff", "incidence", "bounded"])
    parser.add_argument("--cases", nargs="*", default=None, help="names (prefixes) of the cases to run")
    args = parser.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_spectral")
    from scratch_iridescence import mitsuba_bridge
    from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
    from scratch_iridescence.mitsuba_bridge.scratch import Profile, ScratchSet

    mitsuba_bridge.register_plugins()
    unit_scale, sigma_um = 1e-3, 5.0
    n = args.resolution
    x = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    gx, gy = np.meshgrid(x, x)
    keep = gx ** 2 + gy ** 2 < 1.0
    wo = mi.Vector3f(mi.Float(gx[keep]), mi.Float(gy[keep]), mi.Float(np.sqrt(1 - gx[keep] ** 2 - gy[keep] ** 2)))
    count = int(keep.sum())

    def albedo(bsdf, theta_deg):
        t = np.radians(theta_deg)
        si = dr.zeros(mi.SurfaceInteraction3f, count)
        si.uv = mi.Point2f(0.5, 0.5)
        si.dp_du, si.dp_dv = mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0)
        si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
        si.wi = mi.Vector3f(0.0, float(np.sin(t)), float(np.cos(t)))  # across the scratch (along u)
        result = []
        for lam in (450.0, 550.0, 650.0, 750.0):
            si.wavelengths = mi.Spectrum(lam, lam, lam, lam)
            value = np.array(bsdf.eval(mi.BSDFContext(), si, wo))[0]  # f_r cos θ_o, first channel
            result.append(float((value / np.array(wo.z)).sum()) * (2.0 / n) ** 2)  # dω_t = cos θ_o dω
        return max(result)

    print(f"largest albedo over 450-750 nm, σ = {sigma_um} µm, perfect mirror, {n}² direction cosines")
    print(f"{'scratch':28s} {'depth_phase':11s} " + " ".join(f"{t:6.0f}°" for t in args.incidences))
    for name, (width, depth, v_groove) in CASES.items():
        if args.cases and not any(name.startswith(c) for c in args.cases):
            continue
        half = 60e-6 / unit_scale
        scratches = ScratchSet.from_polylines([np.array([[0.5 - half, 0.5], [0.5 + half, 0.5]])],
                                              width=width * 1e-6, depth=depth * 1e-6,
                                              profile=Profile.TRIANGULAR if v_groove else Profile.RECTANGULAR)
        for phase in args.phases:
            bsdf = mi.load_dict(scratch_bsdf.plugin_dict(scratches, coherence_diameter=6 * sigma_um * 1e-6,
                                                         unit_scale=unit_scale, material="none", depth_phase=phase))
            print(f"{name:28s} {phase:11s} " + " ".join(f"{albedo(bsdf, t):7.3f}" for t in args.incidences),
                  flush=True)


if __name__ == "__main__":
    main()
