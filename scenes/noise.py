"""The benchmark table's last column: at how many spp the footprint-filtered BSDF matches a picture's noise.

``make paper`` renders every picture point-sampled (the paper's way).  For each one,
this worker opens the saved scene again and finds the samples per pixel at which
the same picture with the Footprint Filter on (docs/model.md §11; docs/rendering.md)
is as noisy as the point-sampled picture, and how long that render takes.

**Noise** of a picture: the RMS over its pixels and RGB channels of its deviation
from its expected value, relative to the picture's mean; estimated from two renders
with independent seeds as ``rms(A - B) / sqrt(2) / mean((A + B) / 2)``, on the
display-referred values the PNG shows (the scene's exposure, Blender's Standard
view: sRGB encoding, clipped to [0, 1]), so that a lamp seen directly, thousands of
times brighter than white, weighs as the white it is shown as.

**The picture's noise** at its N spp comes from a pair at N/16 spp (an eighth of a
picture's cost) scaled by 1/4: point samples of the independent sampler are
independent, so each pixel's variance falls exactly as 1/spp.

**The filtered search.**  A filtered render's noise falls more slowly than
1/sqrt(spp), because each sample's footprint (its share of the pixel) shrinks as
the samples grow.  The search probes at 1 spp, predicts the spp of equal noise
by 1/sqrt(spp) from the last probe (with a 10 % margin), and renders a pair there,
until a pair's noise is at most the picture's or N/8 spp is reached: a filtered
sample costs several point samples (docs/rendering.md), so beyond N/8 the filter
saves no time, and the limit keeps the column's cost near one picture's.  The reported spp
is the first tried that reaches it (the least lies between the last one that did
not and it); its time is the wall time of the second render of its pair, which
reuses the kernels the first compiled, as any render after a user's first.  The ratio of the
filtered pair's mean to the point pair's is kept as a check of bias.
"""
from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["relative_noise", "display_referred", "next_probe", "noise_worker", "MAX_PROBES"]

#: Filtered pairs rendered at most per picture (the probe at 1 spp included).
MAX_PROBES = 5
#: The point pair's spp and the filtered search's limit, as fractions of the picture's spp (module docstring).
POINT_FRACTION, FILTERED_LIMIT_FRACTION = 1 / 16, 1 / 8
#: Predicted spp are raised by this factor: noise falls more slowly than 1/sqrt(spp) when filtered.
PREDICTION_MARGIN = 1.1


def relative_noise(first: np.ndarray, second: np.ndarray) -> float:
    """Relative RMS noise of one image, from two renders of it with independent seeds (module docstring)."""
    first, second = np.asarray(first, np.float64), np.asarray(second, np.float64)
    if first.shape != second.shape:
        raise ValueError(f"images of different shapes: {first.shape} and {second.shape}")
    mean = 0.5 * float(np.mean(first + second))
    if not mean > 0.0:
        raise ValueError("a black image has no relative noise")
    return float(np.sqrt(np.mean((first - second) ** 2) / 2.0)) / mean


def display_referred(linear: np.ndarray, exposure: float) -> np.ndarray:
    """Linear RGB as Blender's Standard view shows it: ``2**exposure`` times, clipped to [0, 1], sRGB-encoded."""
    value = np.clip(np.asarray(linear, np.float64) * 2.0 ** exposure, 0.0, 1.0)
    return np.where(value <= 0.0031308, 12.92 * value, 1.055 * value ** (1 / 2.4) - 0.055)


def next_probe(spp: int, noise: float, target: float, limit: int) -> int:
    """The next spp to try after ``spp`` gave ``noise`` above ``target``: the 1/sqrt(spp) prediction with
    a margin, at least one more than ``spp`` and at most ``limit``."""
    predicted = math.ceil(spp * (noise / target) ** 2 * PREDICTION_MARGIN)
    return int(min(limit, max(spp + 1, predicted)))


def _render(bpy, scene, path: Path, spp: int, seed: int, filtered: bool):
    """Render ``scene`` through the engine with these settings; (linear RGB image, wall seconds)."""
    from ..mitsuba_bridge.files.exr import read_exr

    settings = scene.scratch_iridescence
    settings.samples, settings.seed, settings.footprint_filter = int(spp), int(seed), bool(filtered)
    scene.render.filepath = str(path)
    began = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    wall_s = time.perf_counter() - began
    return read_exr(path)[..., :3], wall_s


def _pair(bpy, scene, folder: Path, spp: int, filtered: bool, exposure: float) -> dict:
    """Two renders at ``spp`` with seeds 1 and 2 (the picture itself used seed 0): noise, mean, and the
    second render's wall time (the first compiled what it needed)."""
    kind = "filtered" if filtered else "point"
    images, times = [], []
    for seed in (1, 2):
        image, wall_s = _render(bpy, scene, folder / f"{kind}-{spp}-{seed}.exr", spp, seed, filtered)
        images.append(image)
        times.append(wall_s)
    shown = [display_referred(image, exposure) for image in images]
    return {"spp": int(spp), "noise": relative_noise(*shown), "mean": float(np.mean(images[0] + images[1]) / 2),
            "render_s": times[1], "first_render_s": times[0]}


def noise_worker(blend: Path, bpy) -> dict:
    """Open ``blend`` (a picture's saved scene) and measure the filtered column (module docstring).

    Returns ``{spp, render_s, noise, point_noise, point_spp, mean_ratio, probes, reached, total_s}``:
    ``spp`` the first tried spp whose filtered noise is at most the point-sampled picture's
    (``reached`` False where the search's limit, N/8, did not), ``probes`` every filtered pair tried.
    """
    started = time.perf_counter()
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "32", "ZIP"
    picture_spp = int(scene.scratch_iridescence.samples)
    if scene.view_settings.view_transform != "Standard":
        raise ValueError(f"{blend.name}: noise is measured on Blender's Standard view, not "
                         f"{scene.view_settings.view_transform!r}")
    exposure = float(scene.view_settings.exposure)
    with tempfile.TemporaryDirectory(prefix="noise-") as temporary:
        folder = Path(temporary)
        point_spp = max(1, round(picture_spp * POINT_FRACTION))
        limit = max(1, round(picture_spp * FILTERED_LIMIT_FRACTION))
        point = _pair(bpy, scene, folder, point_spp, filtered=False, exposure=exposure)
        target = point["noise"] * math.sqrt(point_spp / picture_spp)
        probes, spp = [], 1
        while True:
            probe = _pair(bpy, scene, folder, spp, filtered=True, exposure=exposure)
            probes.append(probe)
            if probe["noise"] <= target or spp >= limit or len(probes) >= MAX_PROBES:
                break
            spp = next_probe(spp, probe["noise"], target, limit)
    last = probes[-1]
    return {"spp": last["spp"], "render_s": last["render_s"], "noise": last["noise"], "point_noise": target,
            "point_spp": picture_spp, "reached": last["noise"] <= target,
            "mean_ratio": last["mean"] / point["mean"], "probes": probes, "point_pair": point,
            "total_s": time.perf_counter() - started}
