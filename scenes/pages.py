"""``docs/gallery.md`` and ``docs/benchmarks.md`` from the figure records and the measured statistics (no bpy).

:mod:`.paper` calls :func:`write` after rendering; the pages only ever show
numbers measured by that run (or, for pictures not re-rendered, by the last
run whose statistics are still in the output folder).
"""
from __future__ import annotations

import json
import os
import platform
import shutil
import time
from pathlib import Path

from .figure import PAPER_CORES, PAPER_SPP, PAPER_WAVELENGTHS

__all__ = ["write", "load_records", "load_reference", "benchmark_rows", "rate"]

GALLERY_DIR = "gallery"


def load_records(output: Path) -> dict:
    """{picture name: statistics} of every picture rendered into ``output`` (``<name>.json``)."""
    records = {}
    for path in sorted(Path(output).glob("*.json")):
        record = json.loads(path.read_text())
        if "figure" in record and "render_s" in record:
            records[record["name"]] = record
    return records


def _minutes(seconds: float) -> str:
    return f"{seconds / 60:.1f} min" if seconds >= 60 else f"{seconds:.0f} s"


def _machine() -> str:
    cores = os.cpu_count() or 0
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cores} cores ({cpu})"


def rate(value: float | None) -> str:
    """A samples-per-core-second figure as the benchmark table prints it ("—": not measurable)."""
    return "—" if value is None else f"{value:.3g}"


def _settings(record: dict, render) -> str:
    """"W × H × spp", and make paper's own settings where a run scaled them down (--scale, --samples-scale)."""
    shown = f"{record['width']} × {record['height']} × {record['spp']}"
    if (record['width'], record['height'], record['spp']) != (*render.resolution, render.samples) and \
            (record.get("samples_scale", 1.0) != 1.0 or record.get("resolution_scale", 1.0) != 1.0):
        shown += f" (make paper: {render.resolution[0]} × {render.resolution[1]} × {render.samples})"
    return shown


def benchmark_rows(figures, records: dict) -> list[dict]:
    """One row per rendered picture: throughput here and in the paper, memory, load time."""
    rows = []
    for module, figure in figures:
        for render in figure.renders:
            name = f"{module.__name__.rsplit('.', 1)[-1]}-{render.name}"
            record = records.get(name)
            if record is None:
                continue
            samples = record["width"] * record["height"] * record["spp"]
            passes_s = record.get("passes_s") or record["render_s"]
            setup_s = max(record["render_s"] - passes_s, 0.0)  # gather, scratch tables, first compile
            rows.append({
                "name": name, "label": f"{figure.label} {render.name}", "samples": samples, "spp": record["spp"],
                "pixels": _settings(record, render),
                "render_s": record["render_s"], "passes_s": passes_s, "cpu_s": record["render_cpu_s"],
                "per_core_s": samples / record["render_cpu_s"],
                # Setup is mostly single-threaded: charge it one core, the rest to the passes.
                # (None where the set-up's wall time reaches half the render's CPU time: on a shared machine
                # the set-up did not have a core to itself, and its wall time says nothing of its CPU)
                "passes_per_core_s": samples / (record["render_cpu_s"] - setup_s)
                if setup_s < 0.5 * record["render_cpu_s"] else None,
                "paper_minutes": render.paper_minutes, "paper_mp": render.paper_megapixels,
                "paper_per_core_s": render.paper_samples_per_core_second,
                "paper_wavelengths": render.paper_wavelengths, "wavelength_factor": render.wavelength_factor,
                # spp and seconds at which the footprint-filtered BSDF reaches this picture's noise (None: not
                # measured yet; the filter is being built)
                "filtered": record.get("filtered_same_noise"),
                "peak_mb": record["peak_mb"], "load_s": record["scratch_load_s"],
                "tables_read": record.get("tables_read"), "tables_built": record.get("tables_built"),
                "scratches": record["scratches"], "segments": record["segments"],
                "build_s": record["build_s"], "total_s": record["total_s"],
                # the same picture at make paper's own settings: the passes scale with pixels × spp
                "full_settings_s": record["total_s"] + passes_s * (
                    render.resolution[0] * render.resolution[1] * render.samples / samples - 1.0),
                # the machine reference of the run that rendered this picture (None before they were kept)
                "reference": record.get("reference"),
                "traced": record.get("traced"),  # the engine's note when its passes could not be frozen
            })
    return rows


def _copy_pictures(docs: Path, records: dict, validation: dict | None, output: Path) -> None:
    gallery = docs / GALLERY_DIR
    gallery.mkdir(parents=True, exist_ok=True)
    for name, record in records.items():
        shutil.copyfile(record["png"], gallery / f"{name}.png")
    figure = output / "validation" / "validation.png"
    if validation is not None and figure.exists():
        shutil.copyfile(figure, gallery / "validation.png")


# -------------------------------------------------------------------- gallery
def _figure_section(module, figure, records: dict) -> list[str]:
    key = module.__name__.rsplit(".", 1)[-1]
    done = [(render, records.get(f"{key}-{render.name}")) for render in figure.renders]
    done = [(render, record) for render, record in done if record is not None]
    if not done:
        return []
    lines = [f"## {figure.label}: {figure.title}", "",
             f"**The paper's figure.** {figure.paper}", "",
             f"**Scratches.** {figure.scratches}.", "",
             f"**Scene** (`scenes/{key}.py`). {figure.design}", ""]
    lines.append("| " + " | ".join(render.name for render, _ in done) + " |")
    lines.append("|" + "---|" * len(done))
    lines.append("| " + " | ".join(f"![{figure.label} {render.name}]({GALLERY_DIR}/{key}-{render.name}.png)"
                                   for render, _ in done) + " |")
    lines.append("| " + " | ".join(render.caption for render, _ in done) + " |")
    lines += ["", "| picture | resolution × spp | here: build + render (2 cores) | paper (72 cores) |",
              "|---|---|---|---|"]
    for render, record in done:
        paper_res = "4 MP" if render.paper_megapixels == 4.0 else f"{render.paper_megapixels:g} MP"
        wavelengths = "" if render.paper_wavelengths == PAPER_WAVELENGTHS else \
            f", {render.paper_wavelengths} wavelengths per sample"
        paper = f"{render.paper_minutes:g} min at {paper_res} × {PAPER_SPP} spp{wavelengths}" \
            if render.paper_minutes else "— (beyond the paper)"
        lines.append(f"| {render.name} | {_settings(record, render)} | "
                     f"{record['build_s']:.1f} s + {record['render_s']:.0f} s | {paper} |")
    return lines + [""]


def _validation_section(validation: dict) -> list[str]:
    single = validation["configs"]["single"]
    ten = validation["configs"]["ten"]
    pct = lambda value: f"{100 * value:.3g} %"  # noqa: E731
    lines = ["## Numerical validation (supplement Figs. 15 and 16)", "",
             "The supplement validates the model against the radiance computed numerically from explicit "
             "height maps of one scratch and of ten random scratches (Fig. 16), at 9, 36 and 144 MP: the "
             "discretisation's ghosting fades as the height map refines, while the parallelogram-shaped "
             "features of scratch–scratch crossings are not reproduced by the model (Fig. 15).", "",
             "Here (`python -m scratch_iridescence.mitsuba_bridge validate OUT`, "
             "`mitsuba_bridge/validation/fig15.py`): the BRDF of one "
             f"coherence area (σ = {validation['sigma_um']:g} µm, δ_c = 30 µm, perfect mirror base) at normal "
             "incidence over the whole plane of outgoing direction cosines "
             f"({validation['plane_samples']}² directions), at 650, 550 and 450 nm. Brute force: the height "
             f"field rasterised at {1e3 * validation['pitch_um']:g} nm over ±25 µm ({int(50 / validation['pitch_um'])}² "
             "pixels) and Fourier-summed pixel by pixel with the exact Gaussian window "
             "(`mitsuba_bridge/validation/reference.py`, the BSDF tests' reference); where scratches cross, the deeper "
             "one sets the height. Plugin: `scratch_diffraction`'s `eval` at one shading point.", "",
             f"![BRDF over the direction-cosine plane, brute force against plugin]({GALLERY_DIR}/validation.png)", "",
             "| configuration | crossing share of the scratched area | plugin vs height field (all / off the mirror "
             "lobe), 550 nm | plugin vs the raster summed as the model does |",
             "|---|---|---|---|"]
    for name, entry in (("one scratch", single), ("ten random scratches", ten)):
        a = entry["plugin_vs_height_field"]["550"]
        b = entry["plugin_vs_summed_raster"]["550"]
        lines.append(f"| {name} | {pct(entry['crossing_share'])} | {pct(a['all'])} / {pct(a['off_lobe'])} | "
                     f"{pct(b['all'])} / {pct(b['off_lobe'])} |")
    lines += ["", "Other wavelengths (all / off-lobe): " + "; ".join(
        f"{name} {wl} nm {pct(entry['plugin_vs_height_field'][wl]['all'])} / "
        f"{pct(entry['plugin_vs_height_field'][wl]['off_lobe'])}"
        for name, entry in (("one", single), ("ten", ten)) for wl in ("650", "450")) + ".", ""]
    lines += ["**One scratch.** Without crossings the model is exact and so is the plugin (exact window across "
              "the scratch, complex error functions along it): it matches the height field to float32 precision. "
              "Refining the raster (the supplement's 9/36/144 MP rows) changes nothing measurable here, because a "
              "tilted scratch's pixel-centre edges average out along its length (550 nm, all / off-lobe): "
              + ", ".join(f"{pitch} {pct(e['all'])} / {pct(e['off_lobe'])}"
                          for pitch, e in validation["single_convergence_550nm"].items()) + ".", "",
              "**Ten scratches: crossings.** The plugin agrees with the same raster summed the model's way "
              "(every footprint counted, T = 1 + Σ(T_k − 1)) to float32 precision, so the whole difference from the "
              "height field is the model's treatment of crossings, as the paper states: where footprints overlap "
              "the transfer functions are added, |T| is no longer 1, and the overlap's parallelogram shapes "
              "scatter light into a speckled background between the diffraction lines that the brute force shows "
              "and the plugin does not (fourth column; the fifth compares the plugin with the raster summed the model's way). The diffraction lines themselves agree. The error grows "
              "with the share of the scratched area that overlaps (550 nm, ten random scratches of "
              "W ∈ U[0.5, 3] µm, D ∈ U[0.1, 0.5] µm, centres within ±2σ to ±5σ):", "",
              "| centres within | seed | crossing share | relative L2, all | off the mirror lobe |",
              "|---|---|---|---|---|"]
    for row in sorted(validation["crossing_sweep_550nm"], key=lambda r: r["crossing_share"]):
        lines.append(f"| ±{row['spread_sigma']:g}σ | {row['seed']} | {pct(row['crossing_share'])} | "
                     f"{pct(row['all'])} | {pct(row['off_lobe'])} |")
    lines += ["", "A few per cent of overlap costs a few to tens of per cent of the far field; ten scratches "
              "piled into one coherence area (a fifth or more overlapping) are beyond the model. In the rendered "
              "scenes crossings inside one 30 µm window are rare except in the painted clusters of the dining "
              "table (Fig. 1), and absent from the CD and the ruled plate.", ""]
    return lines


def _gallery(figures, records: dict, validation: dict | None) -> str:
    rows = benchmark_rows(figures, records)
    render_total = sum(r["total_s"] for r in rows)
    # The pictures may come from several runs (--only): add up what each took, not this run's wall time.
    # the benchmark table's filtered column (scenes/noise.py) is measured beside the pictures
    noise_s = _column_seconds(rows)
    total_s = render_total + (validation or {}).get("seconds", 0.0) + noise_s
    noise_part = (f", {_minutes(noise_s)} measuring the Footprint Filter's column of [benchmarks.md](benchmarks.md)"
                  if noise_s else "")
    large = sorted({r["spp"] for r in rows if r["scratches"] >= 100_000})
    large_spp = f"{large[0]}–{large[-1]}" if len(large) > 1 else f"{large[0]}" if large else "few"
    scaled = [r for r in rows if abs(r["full_settings_s"] - r["total_s"]) > 1e-9]
    scaled_note = "" if not scaled else (
        f" {len(scaled)} of the pictures were rendered below make paper's settings (their tables say which); "
        f"at its own settings (their passes scaled by pixels × spp) the page would take about "
        f"{_minutes(total_s + sum(r['full_settings_s'] - r['total_s'] for r in scaled))}.")
    lines = ["# Gallery: the paper's scenes, reproduced", "",
             "Werner, Velinov, Jakob, Hullin: *Scratch iridescence: Wave-optical rendering of diffractive "
             "surface structure* (SIGGRAPH Asia 2017). Every scene below is built in code by a module of "
             "`scenes/` with the add-on's own operators (Generate, the Pen and Spray brushes replayed "
             "along strokes, Import) and the supplement's scratch parameters, then rendered through the Mitsuba "
             "Scratch engine. `make paper` rebuilds everything on this page and on "
             "[benchmarks.md](benchmarks.md).", "",
             "We do not have the paper's pictures: each section says what the paper's figure shows and how our "
             "scene shows the same effect. Our renders are far cheaper than the paper's (4 MP × 16 384 spp on 72 "
             "cores): "
             f"{_machine()}, {_minutes(total_s)} for this whole page ({_minutes(render_total)} of it building and "
             f"rendering the pictures{noise_part}), so resolution and samples are a small fraction of the "
             f"paper's and the pictures keep some Monte Carlo noise: the samples per pixel are set so that the "
             f"pictures render in about half an hour on these cores, {large_spp} spp for the scenes of 10⁵ "
             f"scratches and more (the paper's 16 384 on 72 cores is out of reach).{scaled_note} Pictures are "
             "display-referred PNGs "
             "(Blender's Standard view with each scene's exposure: AgX would wash the diffraction colours out); "
             "the linear EXRs are in `out/paper/`.", "",
             "| figure | scratches | pictures | time here | paper |", "|---|---|---|---|---|"]
    for module, figure in figures:
        mine = [r for r in rows if r["name"].startswith(module.__name__.rsplit(".", 1)[-1] + "-")]
        if not mine:
            continue
        lines.append(f"| [{figure.label}](#{_anchor(figure)}) {figure.title} | {mine[0]['scratches']:,} "
                     f"({mine[0]['segments']:,} segments) | {len(mine)} | "
                     f"{_minutes(sum(r['total_s'] for r in mine))}{_full_settings(mine)} | "
                     + " / ".join(f"{r['paper_minutes']:g}" for r in mine if r["paper_minutes"]) + " min |")
    lines.append("")
    for module, figure in figures:
        lines += _figure_section(module, figure, records)
    if validation is not None:
        lines += _validation_section(validation)
    lines += ["## Reproducing", "",
              "```", "make paper                      # every scene, the validation, docs/gallery.md and "
              "docs/benchmarks.md",
              ".venv/bin/python -m scratch_iridescence.scenes.paper --only fig06_cd --scale 0.5 --no-docs",
              "```", "",
              "Each picture is built in one process (saved as `out/paper/<picture>.blend`, which opens in "
              "Blender with the scratches, lights and camera) and rendered in a fresh one, as "
              "`blender -b out/paper/<picture>.blend -E MITSUBA_SCRATCH -f 1` would.", ""]
    return "\n".join(lines)


def _full_settings(rows: list[dict]) -> str:
    """" (about N at make paper's settings)" for a figure rendered below them, else ""."""
    full_s = sum(r["full_settings_s"] for r in rows)
    if abs(full_s - sum(r["total_s"] for r in rows)) < 1e-9:
        return ""
    return f" (about {_minutes(full_s)} at make paper's settings)"


def _anchor(figure) -> str:
    text = f"{figure.label}: {figure.title}".lower()
    keep = "".join(c for c in text if c.isalnum() or c in " -")
    return keep.replace(" ", "-")


# ----------------------------------------------------------------- benchmarks
def load_reference(output: Path) -> dict | None:
    """The machine reference measured by the run that rendered into ``output`` (None before any)."""
    path = Path(output) / "reference.json"
    return json.loads(path.read_text()) if path.exists() else None


def _tables_source(row: dict) -> str:
    """Whether the render built its scratch tables or read them from the disk cache ("—": not recorded)."""
    read, built = row.get("tables_read"), row.get("tables_built")
    if read is None:
        return "—"
    if read and not built:
        return "read"
    return "built" if not read else "built and read"


def _column_seconds(rows: list[dict]) -> float:
    """Seconds spent measuring the filtered column (scenes/noise.py) of these rows."""
    return sum(r["filtered"].get("total_s", 0.0) for r in rows if r["filtered"])


def _filtered(measured: dict | None) -> str:
    """The footprint-filtered BSDF's spp for this picture's noise and its render time, or "—" (not measured)."""
    if not measured:
        return "—"
    if not measured.get("reached", True):
        return f"not reached at {measured['spp']} spp (noise {measured['noise']:.3g} > {measured['point_noise']:.3g})"
    return (f"{measured['spp']} spp ({_minutes(measured['render_s'])}; noise {measured['noise']:.3g} ≤ "
            f"{measured['point_noise']:.3g}, mean ×{measured['mean_ratio']:.3f})")


def _reference_lines(rows: list[dict]) -> list[str]:
    references = [r["reference"] for r in rows if r["reference"]]
    runs = list({json.dumps(reference, sort_keys=True): reference for reference in references}.values())
    if not runs:
        return ["**Machine reference**: not measured (statistics from before `make paper` measured it).", ""]
    measured = "; ".join(f"{reference['before']:.3g} and {reference['after']:.3g}" for reference in runs)
    which = ("" if len(runs) == 1 else
             f" The pictures come from {len(runs)} runs (`--only`); each row is divided by its own run's reference.")
    unmeasured = len(rows) - len(references)
    if unmeasured:
        which += f" {unmeasured} rows come from runs before the reference was kept: no *÷ reference* there."
    return [f"**Machine reference** = Mitsuba's own Cornell box (`mi.cornell_box()`, 256², 64 spp, same variant, "
            f"no add-on code; four renders timed after one that compiles) in a fresh process before the first "
            f"picture and after the last: {measured} samples/core-s.{which} The paper's times are fixed, so "
            "the ratios against them move with the machine (two development machines of this project differed "
            "by 1.8× running the same code); *÷ reference* (samples/core-s over the reference's mean) compares "
            "across machines and runs.", ""]


def _benchmarks(figures, records: dict) -> str:
    rows = benchmark_rows(figures, records)
    lines = ["# Benchmarks: the paper's scenes", "",
             f"Measured by `make paper` ({time.strftime('%Y-%m-%d')}) on the development machine: {_machine()}, "
             "shared with other work, so wall times are noisy; CPU times (core-seconds) less so. Every picture "
             "is rendered in a fresh process that opens the saved scene and renders it through the engine "
             "(`bpy.ops.render.render`), CPU variant `llvm_ad_spectral`.", "",
             "**Samples per core-second** = pixels × spp / CPU seconds of the render call. The paper's figure "
             f"comes from the supplement's times on {PAPER_CORES} cores: pixels × {PAPER_SPP} spp / (minutes × 60 "
             f"× {PAPER_CORES}), 4 MP unless noted. The paper traced 16 wavelengths per sample (3 for Fig. 12), "
             "we trace 4 per path (hero wavelength sampling, docs/model.md §5–6), so one of our samples carries a "
             "quarter of the spectral information of one of theirs (4/3 of one of Fig. 12's): per wavelength "
             "sample, multiply the ratio by 4/N_λ. The render "
             "call includes gathering the scene, building the scratch tables and compiling the kernels; "
             "*passes only* charges that set-up (mostly one thread) to one core and counts the rest (\"—\" where "
             "the set-up's wall time reaches half the render's CPU time: on a loaded machine it did not have a "
             "core). Kernels and tables come from their caches where an earlier render of the same scene "
             "compiled or built them, as for any render after a user's first: column *tables* says whether this "
             "render built them or read "
             "them from the disk cache (docs/rendering.md); *scratch set → BSDF* is the build's own time either "
             "way.", "",
             "**Per wavelength sample** is that ratio times 4/N_λ (N_λ: the paper's wavelengths per sample, 16 "
             "unless the *paper* column says otherwise); the target (issue 12) is at least 2× "
             "the paper per core and per wavelength sample on every scene. Renders beyond the paper (options the "
             "paper does not have) have no paper time.", "",
             *_reference_lines(rows),
             "| picture | pixels × spp | render (wall) | of it passes | samples / core-s | passes only | "
             "÷ reference | paper | paper samples / core-s | ratio | per wavelength sample | peak memory | "
             "scratch set → BSDF | tables | scratches (segments) | filtered BSDF: spp for the same noise (time) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["paper_per_core_s"]:
            notes = [f"{r['paper_mp']:g} MP"] if r["paper_mp"] != 4.0 else []
            notes += [f"N_λ = {r['paper_wavelengths']}"] if r["paper_wavelengths"] != PAPER_WAVELENGTHS else []
            paper = f"{r['paper_minutes']:g} min" + (f" ({', '.join(notes)})" if notes else "")
            ratio = r["per_core_s"] / r["paper_per_core_s"]
            shown = f"{ratio:.0f}" if ratio >= 10 else f"{ratio:.2g}"  # (.2g writes 102 as 1e+02)
            versus = f"{r['paper_per_core_s']:.3g} | {shown}× | {ratio * r['wavelength_factor']:.2f}×"
        else:
            paper, versus = "—", "— | — | —"
        relative = f"{r['per_core_s'] / r['reference']['samples_per_core_s']:.3f}" if r["reference"] else "—"
        lines.append(
            f"| {r['label']} | {r['pixels']} | {r['render_s']:.0f} s | {r['passes_s']:.0f} s | "
            f"{r['per_core_s']:.3g} | {rate(r['passes_per_core_s'])} | "
            f"{relative} | {paper} | {versus} | {r['peak_mb']:,.0f} MB | "
            f"{r['load_s']:.2f} s | {_tables_source(r)} | {r['scratches']:,} ({r['segments']:,}) | "
            f"{_filtered(r['filtered'])} |")
    traced = [r for r in rows if r["traced"]]
    lines += [""]
    if traced:
        lines.append("* **Traced passes**: " + "; ".join(f"{r['label']}: {r['traced']}" for r in traced) + ". "
                     "These pictures re-traced the integrator and the BSDF for every chunk instead of replaying "
                     "one recording ([rendering.md](rendering.md), Render): the same image, a slower render.")
    measured = [r["filtered"] for r in rows if r["filtered"]]
    column_s = _column_seconds(rows)
    lines += ["* **Filtered BSDF: spp for the same noise**: the samples per pixel at which the picture rendered "
              "with the Footprint Filter (the closed-form expected scratch BSDF over each sample's share of the "
              "pixel, docs/model.md §11; off by default, docs/rendering.md) is as noisy as the point-sampled "
              "picture of this row, and that render's wall time (the second of a pair: kernels compiled; compare "
              "with *of it passes*). Noise = RMS deviation over the pixels relative to the mean, from two seeds; "
              "the point picture's from a pair at 1/16 of its spp; the filtered spp found by probing from 1 spp "
              "and predicting by 1/sqrt(spp) (the first spp tried that reaches the noise: the least lies below "
              "it), up to ⅛ of the picture's spp (*not reached at*: beyond it a filtered sample's cost leaves no time saved). "
              "*mean ×* is the filtered pair's mean over the point pair's (bias check). `scenes/noise.py`; part of "
              "`make paper` "
              + (f"(this column: {_minutes(column_s)} of measuring in all)." if measured else
                 "(not measured by the runs whose statistics these are: \"—\").")]
    lines += [
              "* **Peak memory** is the render process's maximum resident set (`ru_maxrss`): Blender (bpy), "
              "Mitsuba and Dr.Jit themselves take about 400 MB of it, the rest is the scene, the scratch tables "
              "and the image.",
              "* **Scratch set → BSDF**: decoding the object's stored scratch file and `mi.load_dict` of the "
              "`scratch_diffraction` plugin with it and the object's settings (the UV grid of segments; the "
              "periodic families of dense sets; the crossing pairs of `crossings = \"height_field\"`), "
              "timed on its own after the render (the disk cache off), once per scratch set and options in a run: "
              "the pictures of one object share it.",
              "* The CD was the slow case of the model: a query evaluates the ~25 track pieces inside the coherence "
              "window, and finding them costs about twice what evaluating them does. Its tracks now sum in closed "
              "form wherever a window lies among them (periodic families, [model.md](model.md) §3.5; "
              "[bsdf.md](bsdf.md), Performance), also across a chord's kink.",
              "* **GPU.** `make paper` renders on the CPU variant. The same scenes, exported, on one NVIDIA H200 "
              "(`cuda_ad_spectral`, `tests/bench/bench_scenes.py`) are in [bsdf.md](bsdf.md), Performance, GPU: "
              "the paper's 16 384 spp in 21 s to 8 min a picture. On this CPU, 16 384 spp at the resolutions above would take the passes' time × 16 384 / "
              "spp: " + "; ".join(f"{r['label']} {_minutes(r['passes_s'] * PAPER_SPP / r['spp'])}" for r in rows) + ".",
              ""]
    return "\n".join(lines)


#: benchmarks.md keeps what follows this line: figures measured by other benchmarks than ``make paper``.
KEPT_BENCHMARKS = "<!-- measured outside make paper: kept when make paper rewrites this page -->"


def write(docs: Path, records: dict, validation: dict | None, figures, output: Path) -> None:
    """Write ``gallery.md``, ``benchmarks.md`` and ``gallery/*.png`` into ``docs``."""
    docs = Path(docs)
    _copy_pictures(docs, records, validation, output)
    (docs / "gallery.md").write_text(_gallery(figures, records, validation))
    previous = (docs / "benchmarks.md").read_text() if (docs / "benchmarks.md").is_file() else ""
    kept = previous[previous.index(KEPT_BENCHMARKS):] if KEPT_BENCHMARKS in previous else ""
    (docs / "benchmarks.md").write_text(_benchmarks(figures, records) + ("\n\n" + kept if kept else ""))
