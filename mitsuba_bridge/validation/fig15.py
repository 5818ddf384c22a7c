"""Numerical validation in the spirit of the supplement's Fig. 15
(``python -m scratch_iridescence.mitsuba_bridge validate OUT``).

The BRDF of one coherence area (δ_c = 30 µm, the plugin's default) over the
whole plane of outgoing direction cosines (α, β) at normal incidence, twice:

* **brute force**: the windowed far field of an explicit height field, rasterised
  at 10 nm on one global grid (:func:`.bsdf.reference.raster_footprints`) and
  Fourier-summed pixel by pixel (:func:`.bsdf.reference.windowed_dft`); where
  scratches cross, the deeper one sets the height, as on a real surface;
* **plugin**: ``scratch_diffraction``'s ``eval`` at one shading point
  (:mod:`.bsdf.probe`), i.e. the analytic model with its sum of transfer
  functions, T = 1 + Σ_k (T_k − 1), and with ``crossings="height_field"``
  (crossing pairs corrected to the deeper depth, docs/model.md §3.4) in the
  JSON's ``height_field_*`` entries.

for one scratch and for ten random scratches (supplement Fig. 16), at 650,
550 and 450 nm (the figure's red, green and blue).  For the ten scratches the
same raster is also summed the model's way (every footprint counted, crossings
twice), which separates the model's crossing error from the implementation's.
The single scratch is repeated at 40 and 20 nm pitch: the brute force converges
to the plugin as the raster refines (the supplement's 9, 36 and 144 MP rows).

Needs scipy and matplotlib (the project's dev extras) and a spectral variant.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

__all__ = ["SIGMA_UM", "WAVELENGTHS_NM", "single_scratch", "ten_scratches", "brdf_planes", "errors", "run", "draw"]

SIGMA_UM = 5.0                     # δ_c = 6σ = 30 µm
WAVELENGTHS_NM = (650.0, 550.0, 450.0)
PLANE_SAMPLES = 321                # α, β ∈ [-1, 1]
PITCH_UM = 0.01
CONVERGENCE_PITCHES_UM = (0.16, 0.08, 0.04, 0.02, 0.01)
#: Ten-scratch sets whose crossing share grows as their centres crowd the window: (seed, spread in σ).
CROSSING_SWEEP = tuple((seed, spread) for spread in (5.0, 3.0, 2.0) for seed in (16, 3, 7))
HALF_SIZE_UM = 5 * SIGMA_UM        # the raster covers ±5σ (window e^{-12.5} at the edge)
VISIBLE = 0.98                     # |ω_o,t|² below this (as the BSDF tests)


def single_scratch():
    """One rectangular scratch, 2 µm wide, 300 nm deep, 1.5 µm beside the shading point, 25° to the u axis."""
    from .reference import Scratch

    t = np.radians(25.0)
    d, n = np.array([np.cos(t), np.sin(t)]), np.array([-np.sin(t), np.cos(t)])
    return [Scratch(tuple(-60 * d + 1.5 * n), tuple(60 * d + 1.5 * n), 2.0, 0.3)]


def ten_scratches(seed: int = 16, spread_um: float = 3 * SIGMA_UM):
    """Ten random rectangular scratches: centres uniform within ±``spread_um``, random directions, 15–80 µm
    long (some ends inside the window), W ∈ U[0.5, 3] µm, D ∈ U[0.1, 0.5] µm."""
    from .reference import Scratch

    rng = np.random.default_rng(seed)
    scratches = []
    for _ in range(10):
        centre = rng.uniform(-spread_um, spread_um, 2)
        angle = rng.uniform(0, np.pi)
        half = 0.5 * rng.uniform(15, 80)
        d = np.array([np.cos(angle), np.sin(angle)])
        scratches.append(Scratch(tuple(centre - half * d), tuple(centre + half * d),
                                 rng.uniform(0.5, 3.0), rng.uniform(0.1, 0.5)))
    return scratches


def _plane():
    alpha = np.linspace(-1.0, 1.0, PLANE_SAMPLES)
    a, b = np.meshgrid(alpha, alpha, indexing="xy")
    visible = a ** 2 + b ** 2 < VISIBLE
    return alpha, a, b, visible


def brdf_planes(scratches, pitch_um: float = PITCH_UM, wavelengths_nm=WAVELENGTHS_NM, bsdf=None,
                height_field_bsdf=None) -> dict:
    """f_r over the direction-cosine plane: brute force (true height field, and summed as the model does)
    and, with ``bsdf``, the plugin (``"plugin"``; with ``height_field_bsdf``, the plugin with
    ``crossings="height_field"`` too, ``"plugin_height_field"``); each (len(wavelengths), S, S), zero
    outside the visible disc."""
    from . import probe, reference

    alpha, a, b, visible = _plane()
    x, footprints, deepest = reference.raster_footprints(scratches, pitch_um, HALF_SIZE_UM)
    gamma_o = np.sqrt(np.clip(1 - a ** 2 - b ** 2, 0, None))
    result = {"true": [], "model": [], "visible": visible, "x": x, "footprints": footprints, "deepest": deepest}
    for wavelength_nm in wavelengths_nm:
        lam = wavelength_nm * 1e-3
        xi = alpha / lam  # normal incidence: ξ = ω_o,t / λ
        k_z = 2 * np.pi * (1.0 + gamma_o) / lam
        mirror = reference.mirror_field(xi, xi, SIGMA_UM)
        true, model = mirror.astype(complex), mirror.astype(complex)
        for s, own, covered in zip(scratches, deepest, footprints):
            transfer = np.exp(1j * k_z * s.depth) - 1.0
            true += transfer * reference.windowed_dft(own, x, SIGMA_UM, xi, xi)
            model += transfer * reference.windowed_dft(covered, x, SIGMA_UM, xi, xi)
        for key, field in (("true", true), ("model", model)):
            result[key].append(np.where(visible, reference.brdf(field, lam, SIGMA_UM), 0.0))
    for key, plugin_bsdf in (("plugin", bsdf), ("plugin_height_field", height_field_bsdf)):
        if plugin_bsdf is None:
            continue
        rows = np.column_stack([a[visible], b[visible], gamma_o[visible]])
        lanes = (tuple(wavelengths_nm) + (550.0,) * 4)[:4]
        values = probe.eval_brdf(plugin_bsdf, (0.0, 0.0, 1.0), rows, lanes)
        plugin = np.zeros((len(wavelengths_nm),) + a.shape)
        for i in range(len(wavelengths_nm)):
            plugin[i][visible] = values[:, i]
        result[key] = list(plugin)
    for key in ("true", "model"):
        result[key] = np.array(result[key])
    return result


def errors(got, expected, visible, wavelengths_nm=WAVELENGTHS_NM) -> dict:
    """Relative L2 errors per wavelength: over the visible disc, and off the mirror lobe (|ξ| > 4 lobe widths)."""
    alpha, a, b, _ = _plane()
    out = {}
    for i, wavelength_nm in enumerate(wavelengths_nm):
        lobe = 1.0 / (2 * np.sqrt(2) * np.pi * SIGMA_UM)
        off = visible & (np.hypot(a, b) / (wavelength_nm * 1e-3) > 4 * lobe)
        g, e = np.asarray(got[i]), np.asarray(expected[i])
        rel = lambda m: float(np.sqrt(np.sum((g[m] - e[m]) ** 2) / np.sum(e[m] ** 2)))  # noqa: E731
        out[f"{wavelength_nm:.0f}"] = {"all": rel(visible), "off_lobe": rel(off)}
    return out


def _crossing_share(footprints, deepest, x) -> float:
    """Share of the scratched, window-weighted area where two or more scratches overlap."""
    n = len(x)
    weight = np.exp(-0.5 * (x / SIGMA_UM) ** 2)
    covered = np.concatenate(footprints)
    unique, counts = np.unique(covered, return_counts=True)
    rows, cols = np.divmod(unique, n)
    w = weight[rows] * weight[cols]
    return float(np.sum(w[counts > 1]) / np.sum(w))


def run(output: Path, *, figure: bool = True) -> dict:
    """Compute both configurations, write ``validation.png`` and ``validation.json`` into ``output``."""
    from ..render.activation import activate
    from . import probe

    activate("llvm_ad_spectral")  # registers the plugin for it
    output = Path(output)
    output.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    results = {"sigma_um": SIGMA_UM, "pitch_um": PITCH_UM, "wavelengths_nm": list(WAVELENGTHS_NM),
               "plane_samples": PLANE_SAMPLES, "configs": {}}
    planes = {}
    for name, scratches in (("single", single_scratch()), ("ten", ten_scratches())):
        bsdf = probe.load_bsdf(scratches, sigma_um=SIGMA_UM, material="none")
        corrected = probe.load_bsdf(scratches, sigma_um=SIGMA_UM, material="none", crossings="height_field")
        plane = brdf_planes(scratches, bsdf=bsdf, height_field_bsdf=corrected)
        planes[name] = (scratches, plane)
        entry = {"plugin_vs_height_field": errors(plane["plugin"], plane["true"], plane["visible"]),
                 "height_field_plugin_vs_height_field": errors(plane["plugin_height_field"], plane["true"],
                                                               plane["visible"]),
                 "plugin_vs_summed_raster": errors(plane["plugin"], plane["model"], plane["visible"]),
                 "summed_vs_height_field": errors(plane["model"], plane["true"], plane["visible"]),
                 "crossing_share": _crossing_share(plane["footprints"], plane["deepest"], plane["x"])}
        results["configs"][name] = entry
    convergence = {}
    scratches, _ = planes["single"]
    bsdf = probe.load_bsdf(scratches, sigma_um=SIGMA_UM, material="none")
    for pitch in CONVERGENCE_PITCHES_UM:
        if pitch == PITCH_UM:
            plane = planes["single"][1]
            got, expected, visible = plane["plugin"][1:2], plane["true"][1:2], plane["visible"]
        else:
            plane = brdf_planes(scratches, pitch, wavelengths_nm=(550.0,), bsdf=bsdf)
            got, expected, visible = plane["plugin"], plane["true"], plane["visible"]
        convergence[f"{pitch * 1e3:.0f} nm"] = errors(got, expected, visible, (550.0,))["550"]
    results["single_convergence_550nm"] = convergence
    sweep = []
    for seed, spread in CROSSING_SWEEP:
        scratches = ten_scratches(seed, spread * SIGMA_UM)
        bsdf = probe.load_bsdf(scratches, sigma_um=SIGMA_UM, material="none")
        corrected = probe.load_bsdf(scratches, sigma_um=SIGMA_UM, material="none", crossings="height_field")
        plane = brdf_planes(scratches, wavelengths_nm=(550.0,), bsdf=bsdf, height_field_bsdf=corrected)
        corrected_errors = errors(plane["plugin_height_field"], plane["true"], plane["visible"], (550.0,))["550"]
        sweep.append({"seed": seed, "spread_sigma": spread,
                      "crossing_share": _crossing_share(plane["footprints"], plane["deepest"], plane["x"]),
                      **errors(plane["plugin"], plane["true"], plane["visible"], (550.0,))["550"],
                      "height_field_all": corrected_errors["all"],
                      "height_field_off_lobe": corrected_errors["off_lobe"]})
    results["crossing_sweep_550nm"] = sweep
    results["seconds"] = time.perf_counter() - started
    (output / "validation.json").write_text(json.dumps(results, indent=1))
    if figure:
        draw(planes, results, output / "validation.png")
    return results


# ------------------------------------------------------------------- figure
def _rgb(planes_rgb, low=-2.0, high=3.0):
    """Log-scaled false colour: log10 f_r from ``low`` to ``high`` per channel (650, 550, 450 nm → R, G, B)."""
    logs = np.log10(np.maximum(np.asarray(planes_rgb), 10.0 ** low))
    return np.clip((logs - low) / (high - low), 0.0, 1.0).transpose(1, 2, 0)


def _height_field(scratches, plane):
    """The rasterised height field (µm), every 10th pixel: what the brute force sums."""
    x = plane["x"]
    n = len(x)
    height = np.zeros(n * n, dtype=np.float32)
    for s, own in zip(scratches, plane["deepest"]):
        height[own] = s.depth
    return height.reshape(n, n)[::10, ::10]


def draw(planes: dict, results: dict, path: Path) -> None:
    """The figure: per configuration the height field, brute force, plugin and two differences.

    The fourth column compares the plugin with the true height field (the model's
    error and the implementation's together), the fifth with the same raster summed
    the model's way (crossings counted twice): the implementation's error alone.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = {"single": "one scratch", "ten": "ten random scratches"}
    fig, axes = plt.subplots(len(planes), 5, figsize=(17.5, 3.7 * len(planes)), constrained_layout=True)
    extent_uv = [-1, 1, -1, 1]
    for row, (name, (scratches, plane)) in enumerate(planes.items()):
        entry = results["configs"][name]
        ax = axes[row, 0]
        half = HALF_SIZE_UM
        image = ax.imshow(_height_field(scratches, plane), origin="lower", extent=[-half, half, -half, half],
                          cmap="magma_r", vmin=0.0, vmax=0.5)
        for radius in (SIGMA_UM, 3 * SIGMA_UM):
            ax.add_patch(plt.Circle((0, 0), radius, fill=False, ls="--", lw=0.8, color="tab:blue"))
        ax.set_title(f"{names[name]}: height field (µm)\nwindow σ = {SIGMA_UM:g} µm (circles: σ, 3σ); "
                     f"{100 * entry['crossing_share']:.0f} % crossings", fontsize=9)
        ax.set_xlabel("x (µm)")
        ax.set_ylabel("y (µm)")
        fig.colorbar(image, ax=ax, shrink=0.8)
        for col, (key, label) in enumerate((("true", "brute force (height field)"), ("plugin", "plugin (model)")), 1):
            ax = axes[row, col]
            ax.imshow(_rgb(plane[key]), origin="lower", extent=extent_uv)
            ax.set_title(f"{label}\nlog10 f_r, R/G/B = 650/550/450 nm", fontsize=9)
            ax.set_xlabel("α (direction cosine)")
            ax.set_ylabel("β")
        panels = (("true", "plugin_vs_height_field", "|plugin − height field|"),
                  ("model", "plugin_vs_summed_raster", "|plugin − raster summed as the model|"))
        for col, (key, error_key, label) in enumerate(panels, 3):
            ax = axes[row, col]
            errs = entry[error_key]["550"]
            difference = np.abs(np.asarray(plane["plugin"][1]) - np.asarray(plane[key][1]))
            image = ax.imshow(np.log10(np.maximum(difference, 1e-6)), origin="lower", extent=extent_uv,
                              cmap="inferno", vmin=-4, vmax=2)
            ax.set_title(f"{label}, 550 nm (log10)\nrelative L2 {100 * errs['all']:.2g} % "
                         f"(off the mirror lobe {100 * errs['off_lobe']:.2g} %)", fontsize=9)
            ax.set_xlabel("α")
            fig.colorbar(image, ax=ax, shrink=0.8)
    fig.suptitle("BRDF of one coherence area (δ_c = 30 µm) at normal incidence over the direction-cosine plane: "
                 f"brute-force wave field of a {1e3 * PITCH_UM:g} nm height-field raster against the plugin.\n"
                 "Column 4: the model's crossing error and the implementation's; column 5: the implementation's alone",
                 fontsize=10)
    fig.savefig(path, dpi=90)
    plt.close(fig)
