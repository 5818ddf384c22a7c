"""The paper's scenes (``scenes/fig*.py``): each builds at a small scale with the requested scratches,
through the add-on's operators; tiny renders show the effects the figures are about."""
import inspect

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import render_to, setup_render  # noqa: E402
from scipy import stats  # noqa: E402

from scratch_iridescence.addon import storage  # noqa: E402
from scratch_iridescence.scenes import (fig01_table, fig06_cd, fig07_plate, fig09_grating,  # noqa: E402
                                              fig10_base, fig17_profile, paper)
from scratch_iridescence.mitsuba_bridge import scratch  # noqa: E402

TINY = dict(resolution=(32, 24), samples=1)


def scratches_on(name):
    return storage.read_scratches(bpy.data.objects[name])


def lengths_m(scratches, metres_per_uv):
    return scratch.scratch_lengths(scratches.uv, scratches.offsets) * metres_per_uv


def assert_ready_to_render(scene):
    assert scene.render.engine == "MITSUBA_SCRATCH" and scene.camera is not None
    assert scene.scratch_iridescence.film_filter == "box"
    assert any(obj.type == "LIGHT" for obj in scene.objects) or scene.world is not None


def render(scene, path, resolution, samples):
    """Render ``scene`` through the engine at ``resolution`` × ``samples``; the linear RGB image."""
    setup_render(scene, *resolution, samples=samples)
    return render_to(scene, path)[..., :3]


def colour_spread(image, share=0.03):
    """Spread (standard deviation) of the rg chromaticities of the brightest ``share`` of the pixels:
    large for a rainbow, small for glints of one colour, whatever their brightness."""
    luminance = image.mean(axis=-1)
    bright = image[luminance >= np.quantile(luminance, 1 - share)]
    chromaticity = bright[:, :2] / bright.sum(axis=1, keepdims=True)
    return float(np.sqrt(chromaticity.var(axis=0).sum()))


# ---------------------------------------------------------------- catalogue
def test01_every_figure_has_renders_its_builder_accepts_and_the_papers_times():
    for module, figure in paper.figures():
        assert figure.renders and figure.paper and figure.scratches and figure.design
        parameters = inspect.signature(module.build_scene).parameters
        for render in figure.renders:
            assert set(render.options) <= set(parameters), (figure.key, render.name)
            assert render.samples > 0
            # a render of the paper's has its time; one beyond it (options the paper lacks) says so
            assert (render.paper_minutes > 0) != render.caption.startswith("beyond the paper"), render.name
            assert (render.paper_samples_per_core_second is None) == (render.paper_minutes == 0)
        assert figure.renders[0].paper_minutes > 0
    # docs/model.md §10: Fig. 7(b) is 1 MP × 16 384 spp in 15 min on 72 cores, about 2.5e5 samples per core-second.
    assert fig07_plate.FIGURE.renders[0].paper_samples_per_core_second == pytest.approx(2.53e5, rel=0.01)


# ------------------------------------------------------- scratch statistics
def test02_fig07_plate_carries_the_supplements_gaussian_scratches(empty_scene):
    fig07_plate.build_scene(empty_scene, count=400, **TINY)
    plate = scratches_on("Scratched plate")
    assert plate.count == 400
    # G_W[4, 1.3] µm and G_D[250, 80] nm (the redraws of values <= 0 move these by far less than the test sees)
    assert stats.kstest(plate.width, stats.norm(4e-6, 1.3e-6).cdf).pvalue > 1e-3
    assert stats.kstest(plate.depth, stats.norm(250e-9, 80e-9).cdf).pvalue > 1e-3
    np.testing.assert_allclose(plate.depth_variation, np.tile((1.1, 0.04), (400, 1)))
    length = lengths_m(plate, fig07_plate.PLATE_M)
    assert length.max() < 0.0601 and np.median(length) > 0.03  # 2-6 cm, a few cut short by the plate's edge
    assert_ready_to_render(empty_scene)


def test03_fig17_profiles_differ_only_in_the_cross_section(empty_scene):
    fig17_profile.build_scene(empty_scene, profile="RECTANGULAR", count=150, **TINY)
    rectangular = scratches_on("Scratched plate")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    fig17_profile.build_scene(bpy.context.scene, profile="TRIANGULAR", count=150, crossings="height_field", **TINY)
    triangular = scratches_on("Scratched plate")
    assert bpy.data.objects["Scratched plate"].scratch_iridescence.crossings == "height_field"
    assert np.array_equal(rectangular.uv, triangular.uv) and np.array_equal(rectangular.seed, triangular.seed)
    assert set(rectangular.profile) == {scratch.Profile.RECTANGULAR}
    assert set(triangular.profile) == {scratch.Profile.TRIANGULAR}
    for s in (rectangular, triangular):
        np.testing.assert_allclose(s.width, 2e-6)
        np.testing.assert_allclose(s.depth, 1e-6)
        np.testing.assert_allclose(s.depth_variation, np.tile((1.1, 0.03), (150, 1)))


@pytest.mark.parametrize("diffuse", [False, True])
def test04_fig10_base_is_specular_or_diffuse_with_the_same_scratches(empty_scene, diffuse):
    fig10_base.build_scene(empty_scene, diffuse=diffuse, count=100, **TINY)
    plate = bpy.data.objects["Scratched plate"]
    expected = fig10_base.DIFFUSE_REFLECTANCE if diffuse else (0.0, 0.0, 0.0)
    assert tuple(plate.scratch_iridescence.diffuse_reflectance) == pytest.approx(expected)
    s = storage.read_scratches(plate)
    assert s.count == 100
    np.testing.assert_allclose(s.width, 1e-6)
    np.testing.assert_allclose(s.depth, 250e-9)
    np.testing.assert_allclose(s.depth_variation, np.tile((1.1, 0.04), (100, 1)))


def test05_fig09_grooves_are_parallel_at_the_grating_pitch(empty_scene):
    fig09_grating.build_scene(empty_scene, grooves=80, **TINY)
    grooves = scratches_on("Grated plate")
    assert grooves.count == 80 and grooves.vertex_count == 160
    ends = grooves.uv.reshape(-1, 2, 2) * fig09_grating.PLATE_M  # metres, plate centre at 0.05
    np.testing.assert_allclose(ends[:, 0, 1], ends[:, 1, 1], atol=2e-8)  # along u (float32 stroke points)
    y = np.sort(ends[:, 0, 1]) - 0.5 * fig09_grating.PLATE_M
    bands = np.split(y, 4)
    for band, start in zip(bands, fig09_grating.BAND_Y_M):
        assert band[0] == pytest.approx(start, abs=1e-8)
        # Stroke points and the mesh's UV map are float32: ±6 nm per groove on a 2.5 µm pitch
        np.testing.assert_allclose(np.diff(band), fig09_grating.PITCH_M, atol=20e-9)
    np.testing.assert_allclose(grooves.width, 1e-6)
    np.testing.assert_allclose(grooves.depth, 1e-6)
    assert bpy.data.objects["Grated plate"].scratch_iridescence.coherent


def test06_fig06_cd_tracks_are_concentric_at_the_track_pitch(empty_scene, tmp_path):
    disc = fig06_cd.build_scene(empty_scene, coherent=False, track_radii_m=(0.040, 0.0404), workdir=tmp_path,
                                **TINY)
    tracks = storage.read_scratches(disc)
    assert tracks.count == 250 and not disc.scratch_iridescence.coherent
    assert np.all(tracks.vertex_counts == fig06_cd.CHORDS_PER_TRACK + 1)
    polylines = tracks.uv.reshape(tracks.count, -1, 2)
    np.testing.assert_array_equal(polylines[:, 0], polylines[:, -1])  # closed
    radius = np.hypot(*(polylines[:, 0] - 0.5).T) * 2 * fig06_cd.DISC_RADIUS_M
    np.testing.assert_allclose(np.diff(radius), fig06_cd.PITCH_M, rtol=1e-6)
    np.testing.assert_allclose(tracks.width, 1e-6)
    np.testing.assert_allclose(tracks.depth, 120e-9)
    # the full disc: the supplement's 3 128 400 segments within 0.01 %
    full = fig06_cd.cd_tracks()
    assert full.vertex_count - full.count == pytest.approx(3_128_400, rel=1e-4)


def test07_fig01_table_mixes_painted_wear_with_generated_uniform_scratches(empty_scene):
    top = fig01_table.build_scene(empty_scene, scale=0.01, **TINY)
    table = storage.read_scratches(top)
    assert table.count == 3000  # 1 % of the paper's 300 000, painted ones included
    for values in (table.width, table.depth):  # U[0, 6] µm
        assert values.min() > 0 and values.max() <= 6e-6
        assert stats.kstest(values, stats.uniform(0, 6e-6).cdf).pvalue > 1e-3
    # The brush work: scratch midpoints crowd the wiping annuli around the plates.
    size = np.array(fig01_table.TABLE_M)
    first, last = table.offsets[:-1], table.offsets[1:] - 1
    middles = (0.5 * (table.uv[first] + table.uv[last]) - 0.5) * size  # metres from the table's centre
    grid = np.stack(np.meshgrid(*(np.linspace(-h, h, 400) for h in 0.5 * size)), -1).reshape(-1, 2)

    def in_annuli(points):
        distance = np.min([np.hypot(*(points - plate).T) for plate in np.array(fig01_table.PLATES)], axis=0)
        return (distance > 0.08) & (distance < 0.19)

    assert in_annuli(middles).mean() > 1.5 * in_annuli(grid).mean()
    assert_ready_to_render(empty_scene)


# ------------------------------------------------------------ tiny renders
def test08_coherent_grating_bands_take_different_colours_incoherent_ones_do_not(empty_scene, tmp_path):
    plate = fig09_grating.build_scene(empty_scene, coherent=True, **TINY)
    coherent = render(empty_scene, tmp_path / "coherent.exr", (144, 90), 32)
    plate.scratch_iridescence.coherent = False
    incoherent = render(empty_scene, tmp_path / "incoherent.exr", (144, 90), 32)
    assert np.all(np.isfinite(coherent)) and np.all(np.isfinite(incoherent))
    assert colour_spread(coherent) > 0.3 > 0.15 > colour_spread(incoherent)


# (two renders of the CD's 1.6 µm tracks, ~60 s here; test08's grating keeps the coherent/incoherent contrast in
# make test: under the slow marker)
@pytest.mark.slow
def test09_coherent_cd_shows_rainbow_orders_that_vanish_incoherently(empty_scene, tmp_path):
    disc = fig06_cd.build_scene(empty_scene, coherent=True, track_radii_m=(0.030, 0.052), workdir=tmp_path, **TINY)
    coherent = render(empty_scene, tmp_path / "coherent.exr", (96, 72), 16)
    disc.scratch_iridescence.coherent = False
    incoherent = render(empty_scene, tmp_path / "incoherent.exr", (96, 72), 16)
    # Pure spectral colours lie outside sRGB, so single channels of the linear image may be negative; the
    # luminance (CIE Y, a non-negative matching function) may not.
    luminance = coherent @ np.array([0.2126, 0.7152, 0.0722])
    assert np.all(np.isfinite(coherent)) and luminance.min() >= -1e-4 * luminance.max()
    assert colour_spread(coherent) > 0.3 > 0.15 > colour_spread(incoherent)


# ------------------------------------------------------------- make paper
# (fresh worker processes import and compile everything anew: ~65 s here; under the slow marker)
@pytest.mark.slow
def test10_paper_runner_builds_renders_and_writes_the_pages(tmp_path):
    """``make paper`` in miniature: the grated plate at 5 % resolution, built and rendered by fresh worker
    processes; the pictures, the statistics and both pages read back."""
    from scratch_iridescence.scenes import pages
    from scratch_iridescence.mitsuba_bridge.files.exr import read_exr

    output, docs = tmp_path / "out", tmp_path / "docs"
    assert paper.main(["--only", "fig09_grating", "--scale", "0.05", "--samples-scale", "0.02", "--no-validation",
                       "--output", str(output), "--docs", str(docs)]) == 0
    records = pages.load_records(output)
    assert set(records) == {"fig09_grating-incoherent", "fig09_grating-coherent"}
    for name, record in records.items():
        assert (record["width"], record["height"], record["spp"]) == (36, 22, 5)
        assert record["scratches"] == fig09_grating.GROOVES and record["render_cpu_s"] > 0
        image = read_exr(record["exr"])
        assert image.shape[:2] == (22, 36) and np.all(np.isfinite(image)) and image[..., :3].max() > 0
        assert (docs / "gallery" / f"{name}.png").stat().st_size > 0
    (row,) = [r for r in pages.benchmark_rows(paper.figures(["fig09_grating"]), records)
              if r["name"] == "fig09_grating-coherent"]
    record = records["fig09_grating-coherent"]
    assert row["per_core_s"] == pytest.approx(36 * 22 * 5 / record["render_cpu_s"])
    # The supplement: 4 MP × 16 384 spp in 19 min on 72 cores.
    assert row["paper_per_core_s"] == pytest.approx(4e6 * 16384 / (19 * 60 * 72))
    gallery, benchmarks = (docs / "gallery.md").read_text(), (docs / "benchmarks.md").read_text()
    assert "](gallery/fig09_grating-coherent.png)" in gallery and "## Fig. 9" in gallery
    assert "| Fig. 9 coherent | 36 × 22 × 5 (make paper: 720 × 450 × 256) |" in benchmarks
    # The machine reference, measured before and after the pictures, divides every row.
    reference = pages.load_reference(output)
    assert reference["before"] > 0 and reference["after"] > 0
    relative = row["per_core_s"] / reference["samples_per_core_s"]
    assert f"| {pages.rate(row['passes_per_core_s'])} | {relative:.3f} |" in benchmarks
    assert f"{reference['before']:.3g} and {reference['after']:.3g} samples/core-s" in benchmarks
    assert record["reference"] == reference
    # The filtered column (scenes/noise.py): the first filtered spp tried (from 1, increasing) whose noise,
    # measured from two seeds, is at most the point picture's (a pair at 1/16 of its spp, scaled by
    # 1/sqrt(spp)), up to 1/8 of its spp.
    for name, record in records.items():
        measured = record["filtered_same_noise"]
        tried = [probe["spp"] for probe in measured["probes"]]
        assert tried[0] == 1 and tried == sorted(set(tried)) and tried[-1] == measured["spp"] == 1
        assert measured["point_pair"]["spp"] == 1 and measured["point_noise"] == pytest.approx(
            measured["point_pair"]["noise"] * np.sqrt(1 / 5))
        assert measured["reached"] == (measured["noise"] <= measured["point_noise"])
        if measured["reached"]:
            assert all(probe["noise"] > measured["point_noise"] for probe in measured["probes"][:-1])
        assert measured["render_s"] > 0 and measured["noise"] > 0
    assert f"{records['fig09_grating-coherent']['filtered_same_noise']['spp']} spp (" in benchmarks or \
        "not reached at" in benchmarks
    # A later `--only` run measures its own reference; it divides only the pictures that run rendered.
    earlier = {"before": 1.0e6, "after": 1.2e6, "samples_per_core_s": 1.1e6}
    records["fig09_grating-incoherent"]["reference"] = earlier
    mixed = pages._benchmarks(paper.figures(["fig09_grating"]), records)
    (incoherent,) = [r for r in pages.benchmark_rows(paper.figures(["fig09_grating"]), records)
                     if r["name"] == "fig09_grating-incoherent"]
    assert f"| {pages.rate(incoherent['passes_per_core_s'])} | {incoherent['per_core_s'] / 1.1e6:.3f} |" in mixed
    assert f"| {pages.rate(row['passes_per_core_s'])} | {relative:.3f} |" in mixed
    assert "from 2 runs" in mixed and "1e+06 and 1.2e+06" in mixed
    # The grating's passes replay one recording; a picture whose engine said otherwise is named on the page.
    assert "traced" not in record and "Traced passes" not in benchmarks
    records["fig09_grating-incoherent"]["traced"] = "Mitsuba Scratch: passes traced, not replayed (same image, " \
                                                    "slower): record(): simulated"
    assert "**Traced passes**: Fig. 9 incoherent: Mitsuba Scratch: passes traced" in \
        pages._benchmarks(paper.figures(["fig09_grating"]), records)
