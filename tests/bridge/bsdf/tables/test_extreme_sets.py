"""Sets at the scratch format's bounds (docs/scratch-format.md) render, or are refused with an estimate before any
table is built; never an internal error (mitsuba_bridge/bsdf/tables/grid.py, builder.check_tables_memory)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bridge_scenes import quad, simple_scene
from scratch_iridescence.mitsuba_bridge import builder, scratch
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.bsdf.tables import grid
from scratch_iridescence.mitsuba_bridge.device.memory import NotEnoughMemory
from scratch_iridescence.mitsuba_bridge.scratch.scratchset import (MAX_UV_COORDINATE, MAX_VARIATION_AMPLITUDE,
                                                                   MAX_VARIATION_FREQUENCY)

ROOT = Path(__file__).resolve().parents[4]


def spread(extent: float, count: int = 50) -> scratch.ScratchSet:
    """``count`` ordinary scratches, two of them moved out to ``±extent`` UV units, the variations at their bounds."""
    base = scratch.random_scratches(count, seed=1, vertices=3,
                                    depth_variation=(MAX_VARIATION_AMPLITUDE, MAX_VARIATION_FREQUENCY),
                                    width_variation=(MAX_VARIATION_AMPLITUDE, MAX_VARIATION_FREQUENCY))
    uv = base.uv.copy()
    uv[0], uv[4] = (extent, extent), (-extent, extent)
    return scratch.ScratchSet(**{**base.as_dict(), "uv": uv})


def plate(scratches):
    metal = S.ScratchedMetal(scratches, coherence_diameter_m=30e-6)
    return simple_scene(shapes=[S.Shape("plate", quad(1.0, "plate"), np.eye(4), "plate")],
                        materials={"plate": metal}, lights=[S.PointLight((0, 0, 2), (3.0,) * 3)])


def test01_scratches_far_apart_keep_the_grid_within_its_cell_limit():
    # (two scratches 2 000 UV units apart made the cell-size search allocate 244 GiB)
    tables = grid.build_tables(spread(1e3))
    assert tables.shape[0] * tables.shape[1] <= grid.MAX_CELLS and tables.piece_count > 10_000  # (cut at 1/64)


def test02_a_set_at_the_variation_bounds_and_far_apart_renders(variant):
    from scratch_iridescence.mitsuba_bridge.render import passes

    image = passes.render_image(builder.load_scene(plate(spread(300.0)), S.RenderSettings(spp=2)), 2)
    assert np.all(np.isfinite(image)) and image.max() > 0


def long_scratches() -> scratch.ScratchSet:
    """A thousand scratches 2·10⁴ UV units long: within the format's bounds, beyond any machine's tables."""
    lines = [np.array([[-MAX_UV_COORDINATE, -9e3 + k], [MAX_UV_COORDINATE, 9e3 - k]]) for k in range(1000)]
    return scratch.ScratchSet.from_polylines(lines, width=1e-6, depth=1e-7)


REFUSAL = r"building the tables of 1,000 scratches needs about 298.0 GiB of memory \(at least 1,280,000,000 pieces "


def test03_tables_that_cannot_fit_are_refused_with_an_estimate_before_anything_is_built(variant):
    long_set = long_scratches()
    assert grid.least_pieces(long_set) == 1000 * 64 * 20_000
    with pytest.raises(NotEnoughMemory, match=REFUSAL + r".*\) but only .* is allowed"):
        builder.load_scene(plate(long_set), S.RenderSettings(spp=1))


def test03b_met_inside_mitsuba_s_loader_the_refusal_is_still_the_user_error(variant, monkeypatch):
    """Mitsuba's parser turns a Python plugin's exception into a RuntimeError quoting its traceback; the loader
    hands on the user error itself, Mitsuba's kept as its cause (mitsuba_bridge/errors.py)."""
    import gc

    from scratch_iridescence.mitsuba_bridge.render import passes

    monkeypatch.setattr(builder, "check_tables_memory", lambda description: None)  # the plugin's own build meets it
    gc.collect()
    gc.disable()  # the BSDF whose build failed must go at once, not at the next garbage collection: Dr.Jit calls
    try:  # every live BSDF of the variant, and a half-built one failed the next render (it has no 'model')
        with pytest.raises(NotEnoughMemory, match=REFUSAL) as refused:
            builder.load_scene(plate(long_scratches()), S.RenderSettings(spp=1))
        cause = refused.value.__cause__
        assert isinstance(cause, RuntimeError) and "scratch_diffraction" in str(cause), cause
        del refused, cause  # (as a caller that reported the error)
        image = passes.render_image(builder.load_scene(plate(spread(1.0)), S.RenderSettings(spp=1)), 1)
    finally:
        gc.enable()
    assert np.all(np.isfinite(image)) and image.max() > 0


@pytest.mark.slow
def test04_a_set_spread_over_the_whole_uv_range_renders(variant):
    from scratch_iridescence.mitsuba_bridge.render import passes

    image = passes.render_image(builder.load_scene(plate(spread(MAX_UV_COORDINATE)), S.RenderSettings(spp=1)), 1)
    assert np.all(np.isfinite(image))
