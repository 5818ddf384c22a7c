"""The numerical validation (``python -m scratch_iridescence.mitsuba_bridge validate``) on a coarse plane:
whole-plane brute force against the plugin, the crossing bookkeeping of the height-field raster, the figure."""
import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.validation import fig15 as validation
from scratch_iridescence.mitsuba_bridge.validation import reference as ref


@pytest.fixture
def coarse(monkeypatch):
    """41² directions and a 40 nm raster: a second instead of a minute and a half."""
    monkeypatch.setattr(validation, "PLANE_SAMPLES", 41)
    monkeypatch.setattr(validation, "PITCH_UM", 0.04)
    monkeypatch.setattr(validation, "CONVERGENCE_PITCHES_UM", (0.08, 0.04))
    monkeypatch.setattr(validation, "CROSSING_SWEEP", ((16, 5.0),))


def test01_raster_gives_a_crossing_to_the_deeper_scratch():
    shallow = ref.Scratch((-10.0, 0.0), (10.0, 0.0), 2.0, 0.1)
    deep = ref.Scratch((0.0, -10.0), (0.0, 10.0), 1.0, 0.4)
    x, footprints, deepest = ref.raster_footprints([shallow, deep], 0.05, 12.0)
    overlap = np.intersect1d(footprints[0], footprints[1])
    assert overlap.size == pytest.approx((2.0 / 0.05) * (1.0 / 0.05), rel=0.1)  # the 2 × 1 µm crossing
    assert np.intersect1d(deepest[0], overlap).size == 0 and np.isin(overlap, deepest[1]).all()
    assert len(deepest[0]) + len(deepest[1]) == len(np.union1d(*footprints))


def test02_windowed_dft_of_one_scratch_matches_the_per_scratch_reference():
    s = ref.Scratch((-30.0, 1.0), (30.0, 1.0), 1.0, 0.25)
    x, footprints, _ = ref.raster_footprints([s], 0.02, 15.0)
    xi = np.linspace(-1.0, 1.0, 9)
    grid = ref.windowed_dft(footprints[0], x, 2.0, xi, xi)
    # The same sum from the scratch's own aligned raster, with κ = k_z D = π so that T - 1 = -2 on it.
    xi_rows = np.stack(np.meshgrid(xi, xi, indexing="xy"), -1).reshape(-1, 2)
    k_z = np.full(len(xi_rows), np.pi / 0.25)
    expected = -0.5 * (ref.field_scratch_frames([s], xi_rows, k_z, 2.0) - ref.flat_field(xi_rows, 2.0))
    np.testing.assert_allclose(grid.ravel(), expected, rtol=0, atol=1e-3 * np.abs(expected).max())


# (the whole validation run with its brute-force height fields: ~40 s here; under the slow marker)
@pytest.mark.slow
def test03_plugin_matches_the_height_field_without_crossings_and_differs_with_them(coarse, variant, tmp_path):
    results = validation.run(tmp_path)
    single, ten = results["configs"]["single"], results["configs"]["ten"]
    assert single["crossing_share"] == 0.0 < ten["crossing_share"]
    assert all(e["all"] < 1e-3 for e in single["plugin_vs_height_field"].values())
    assert all(e["all"] < 1e-3 for e in ten["plugin_vs_summed_raster"].values())  # the model's sum, exactly
    assert all(e["off_lobe"] > 0.1 for e in ten["plugin_vs_height_field"].values())  # crossings: its limitation
    corrected = ten["height_field_plugin_vs_height_field"]  # crossings = "height_field" (docs/model.md §3.4)
    assert all(corrected[k]["off_lobe"] < 0.5 * e["off_lobe"] for k, e in ten["plugin_vs_height_field"].items())
    assert all(e["all"] < 1e-3 for e in single["height_field_plugin_vs_height_field"].values())
    assert set(results["single_convergence_550nm"]) == {"80 nm", "40 nm"}
    assert (tmp_path / "validation.png").stat().st_size > 10_000 and (tmp_path / "validation.json").exists()
