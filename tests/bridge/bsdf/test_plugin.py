"""The plugin as other parts of the product use it: creation, parameters, errors, traversal, kernels."""
from __future__ import annotations

import subprocess
import sys

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from scratch_iridescence import mitsuba_bridge
from scratch_iridescence.mitsuba_bridge.validation import reference
import shading
from scratch_iridescence.mitsuba_bridge import bsdf as scratch_bsdf
from scratch_iridescence.mitsuba_bridge import scratch
from scratch_iridescence.mitsuba_bridge.bsdf import parameters, tensors
from scratch_iridescence.mitsuba_bridge.bsdf.plugin import MANUAL, plugin_class


@pytest.fixture(scope="module")
def plate():
    return scratch.random_scratches(60, seed=11, width=scratch.Gaussian(4e-6, 1.3e-6),
                                    depth=scratch.Gaussian(250e-9, 80e-9), depth_variation=(1.1, 0.04))


def evaluate(bsdf, count=2000, seed=0, uv_spread=0.3):
    """eval + pdf at random points of the plate (unit_scale 1 mm), as numpy."""
    rng = np.random.default_rng(seed)
    si = shading.interaction(count, shading.direction(35, 10))
    si.uv = mi.Point2f(shading.floats(rng.uniform(0.5 - uv_spread, 0.5 + uv_spread, count)),
                       shading.floats(rng.uniform(0.5 - uv_spread, 0.5 + uv_spread, count)))
    wo = mi.warp.square_to_uniform_hemisphere(mi.Point2f(shading.floats(rng.random(count)),
                                                         shading.floats(rng.random(count))))
    value, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, wo)
    return np.asarray(value), np.asarray(pdf)


def test01_create_from_memory_file_and_nothing(plate, tmp_path):
    path = scratch.save(plate, tmp_path / "plate.npz")
    from_memory = mi.load_dict(scratch_bsdf.plugin_dict(plate, unit_scale=1e-3))
    from_file = mi.load_dict(scratch_bsdf.plugin_dict(filename=path, unit_scale=1e-3))
    assert isinstance(from_memory, mi.BSDF)
    assert "scratches=60" in str(from_file) and "scratches=60" in str(from_memory)
    for a, b in zip(evaluate(from_memory), evaluate(from_file)):
        np.testing.assert_array_equal(a, b)
    assert np.count_nonzero(evaluate(from_memory)[0]) > 0
    unscratched = mi.load_dict({"type": parameters.PLUGIN_NAME})
    assert "scratches=0" in str(unscratched) and "material=Al" in str(unscratched)
    assert unscratched.flags() & mi.BSDFFlags.GlossyReflection
    assert not unscratched.flags() & mi.BSDFFlags.DiffuseReflection


def test02_registration_is_idempotent_and_importing_has_no_side_effects():
    mitsuba_bridge.register_plugins()
    mitsuba_bridge.register_plugins()
    assert isinstance(mi.load_dict({"type": parameters.PLUGIN_NAME}), mi.BSDF)
    code = ("import sys, scratch_iridescence.mitsuba_bridge.bsdf, scratch_iridescence.mitsuba_bridge.bsdf.parameters; "
            "print('mitsuba' in sys.modules, 'drjit' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.stdout.split() == ["False", "False"], result.stderr


def test03_manual_documents_every_parameter():
    assert plugin_class().__doc__ == MANUAL
    for name in ("filename", "coherence_diameter", "unit_scale", "material", "eta, k", "diffuse_reflectance",
                 "coherent", "cell_size", "depth_phase", "scratch_uv", "load_dict", "30e-6", "metres"):
        assert name in MANUAL, name


def test04_rgb_variant_is_refused_with_a_clear_error():
    mi.set_variant("llvm_ad_rgb")
    mitsuba_bridge.register_plugins()
    with pytest.raises(RuntimeError, match="spectral.*llvm_ad_spectral"):
        mi.load_dict({"type": parameters.PLUGIN_NAME})


def test05_missing_and_malformed_files_name_file_and_field(plate, tmp_path):
    missing = tmp_path / "nowhere.npz"
    with pytest.raises(RuntimeError, match=f"filename.*{missing}.*does not exist"):
        mi.load_dict(scratch_bsdf.plugin_dict(filename=missing))
    bad = tmp_path / "bad.npz"
    arrays = plate.as_dict()
    arrays["depth"] = -arrays["depth"]
    np.savez(bad, format=np.array(scratch.FORMAT), **arrays)
    with pytest.raises(RuntimeError, match=f"{bad}: field 'depth'"):
        mi.load_dict(scratch_bsdf.plugin_dict(filename=bad))
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(RuntimeError, match=f"{junk}: not a scratch file"):
        mi.load_dict(scratch_bsdf.plugin_dict(filename=junk))


@pytest.mark.parametrize("extra, message", [
    ({"eta": {"type": "spectrum", "value": 1.2}}, "'eta' and 'k' go together"),
    ({"material": "Au", "eta": 1.0, "k": 2.0}, "either 'material' or 'eta' and 'k'"),
    ({"material": "Unobtainium"}, "unknown material 'Unobtainium'"),
    ({"coherence_diameter": -1e-6}, "'coherence_diameter' must be a positive length"),
    ({"unit_scale": 0.0}, "'unit_scale' must be a positive length"),
    ({"filename": "a.npz", "scratch_uv": mi.TensorXf64(np.zeros((1, 0, 2)))}, "either 'filename' or"),
    ({"depth_phase": "fresnel"}, "'depth_phase' must be one of kirchhoff, incidence, bounded, got 'fresnel'"),
])
def test06_bad_parameters_are_refused_at_load(extra, message):
    with pytest.raises(RuntimeError, match=message):
        mi.load_dict(dict({"type": parameters.PLUGIN_NAME}, **extra))


def test07_plugin_dict_matches_the_contract(plate, tmp_path):
    d = scratch_bsdf.plugin_dict(plate, coherence_diameter=20e-6, unit_scale=0.01, material="Cu",
                                 diffuse_reflectance=0.2, coherent=False)
    assert d["type"] == "scratch_diffraction" and d["material"] == "Cu" and d["coherent"] is False
    assert d["coherence_diameter"] == 20e-6 and d["unit_scale"] == 0.01
    assert set(scratch_bsdf.scratch_parameters(plate)) <= set(d)
    custom = scratch_bsdf.plugin_dict(eta=1.5, k=7.0)
    assert "material" not in custom and custom["eta"] == {"type": "spectrum", "value": 1.5}
    assert scratch_bsdf.plugin_dict(filename=tmp_path / "x.npz")["filename"] == str(tmp_path / "x.npz")
    with pytest.raises(ValueError):
        scratch_bsdf.plugin_dict(plate, filename="x.npz")
    bsdf = mi.load_dict(d)
    assert "incoherent" in str(bsdf) and bsdf.flags() & mi.BSDFFlags.DiffuseReflection


def test08_traverse_swaps_the_scratch_set_without_reloading(plate):
    other = scratch.random_scratches(37, seed=12, width=scratch.Constant(3e-6), depth=scratch.Constant(300e-9))
    scene = mi.load_dict({"type": "scene", "plate": {"type": "rectangle", "bsdf": scratch_bsdf.plugin_dict(
        plate, unit_scale=1e-3)}})
    params = mi.traverse(scene)
    for key in list(scratch_bsdf.scratch_parameters(plate)) + ["coherence_diameter", "unit_scale"]:
        assert "plate.bsdf." + key in params
    bsdf = scene.shapes()[0].bsdf()
    before = evaluate(bsdf)
    scratch_bsdf.update_scratches(params, other)
    assert scene.shapes()[0].bsdf() is bsdf and "scratches=37" in str(bsdf)
    # the traversed tensors hold the new set too (update_scratches hands it over without reading them back)
    held = tensors.from_values({key: params["plate.bsdf." + key] for key in tensors.KEYS})
    assert held.count == 37 and np.array_equal(held.uv, other.uv) and np.array_equal(held.depth, other.depth)
    fresh = mi.load_dict(scratch_bsdf.plugin_dict(other, unit_scale=1e-3))
    for a, b in zip(evaluate(bsdf), evaluate(fresh)):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(before[0], evaluate(bsdf)[0])

    params["plate.bsdf.coherence_diameter"] = 12e-6
    params.update()
    fresh = mi.load_dict(scratch_bsdf.plugin_dict(other, unit_scale=1e-3, coherence_diameter=12e-6))
    np.testing.assert_allclose(evaluate(bsdf)[0], evaluate(fresh)[0], rtol=1e-6, atol=1e-12)


def test09_another_scratch_count_reuses_the_compiled_kernels(plate):
    """Counts, grid sizes and σ are data, not literals: no kernel is compiled twice.  Which profiles occur is
    a Python choice (``lookup.Grid.triangular``): a set of V-grooves compiles its own kernels, once, and
    the flat-bottomed ones are reused after it."""
    def launches(bsdf):
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            evaluate(bsdf, seed=1)
            si = shading.interaction(500, shading.direction(20))
            u = shading.floats(np.linspace(0, 1, 500))
            dr.eval(bsdf.sample(mi.BSDFContext(), si, u, mi.Point2f(u, 0.3)))
            return [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]

    def reused(kernels):
        return kernels and all(k["cache_hit"] for k in kernels)

    assert launches(mi.load_dict(scratch_bsdf.plugin_dict(plate, unit_scale=1e-3)))
    for profile in (scratch.Profile.RECTANGULAR, scratch.Profile.TRIANGULAR):
        bigger = scratch.random_scratches(411, seed=3, width=scratch.Uniform(1e-6, 5e-6),
                                          depth=scratch.Constant(200e-9), profile=profile)
        bsdf = mi.load_dict(scratch_bsdf.plugin_dict(bigger, unit_scale=2e-3, coherence_diameter=25e-6))
        assert bsdf.model.grid.triangular is (profile == scratch.Profile.TRIANGULAR)
        kernels = launches(bsdf)
        if profile == scratch.Profile.RECTANGULAR:
            assert reused(kernels), [k["hash"] for k in kernels if not k["cache_hit"]]
        assert reused(launches(bsdf))
    assert reused(launches(mi.load_dict(scratch_bsdf.plugin_dict(plate, unit_scale=1e-3))))


def test10_empty_set_is_the_mirror_lobe_of_the_base_metal():
    sigma_um = 5.0
    bsdf = mi.load_dict({"type": parameters.PLUGIN_NAME, "material": "Au"})  # default δ_c = 30 µm
    wi = shading.direction(30, 40)
    lam = 0.55
    xi = np.column_stack([np.linspace(-0.05, 0.05, 21), np.linspace(0.02, -0.03, 21)])
    wo, _ = reference.directions(xi, lam, wi)
    f = shading.eval_brdf(bsdf, wi, wo, (550, 550, 550, 550))[:, 0]
    half = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    eta, k = scratch_bsdf.fresnel.material_textures("Au")
    si = mi.SurfaceInteraction3f()
    si.wavelengths = mi.Spectrum(550.0)
    index = mi.Complex2f(float(np.asarray(eta.eval(si)).ravel()[0]), float(np.asarray(k.eval(si)).ravel()[0]))
    fresnel = np.asarray(mi.fresnel_conductor(mi.Float(half @ wi), index))
    lobe = (2 * np.pi * sigma_um ** 2 * np.exp(-2 * np.pi ** 2 * sigma_um ** 2 * np.sum(xi ** 2, axis=1))) ** 2
    np.testing.assert_allclose(f, fresnel * lobe / (lam ** 2 * np.pi * sigma_um ** 2), rtol=2e-4)


def test11_diffuse_base_adds_a_lambertian_term_and_obeys_the_context():
    wi, wo = shading.direction(20), np.array([shading.direction(60, 180)])
    plain = mi.load_dict({"type": parameters.PLUGIN_NAME, "material": "none"})
    based = mi.load_dict({"type": parameters.PLUGIN_NAME, "material": "none", "diffuse_reflectance": 0.3})
    f = shading.eval_brdf(based, wi, wo) - shading.eval_brdf(plain, wi, wo)
    np.testing.assert_allclose(f, 0.3 / np.pi, rtol=1e-5)
    si = shading.interaction(1, wi)
    glossy_only = mi.BSDFContext(mi.TransportMode.Radiance, mi.BSDFFlags.GlossyReflection)
    assert np.all(np.asarray(based.eval(glossy_only, si, shading.vector(wo))) == 0)


def test12_a_context_without_a_component_neither_samples_nor_weights_it():
    scratches = scratch.random_scratches(30, seed=2, region=((0.49, 0.49), (0.51, 0.51)), length=(0.01, 0.02))
    bsdf = mi.load_dict(scratch_bsdf.plugin_dict(scratches, unit_scale=1e-3, diffuse_reflectance=0.4))
    si = shading.interaction(4000, shading.direction(30))
    u = shading.floats(np.linspace(0, 1, 4000, endpoint=False))
    for flags, component in ((mi.BSDFFlags.DiffuseReflection, mi.BSDFFlags.DiffuseReflection),
                             (mi.BSDFFlags.GlossyReflection, mi.BSDFFlags.GlossyReflection)):
        ctx = mi.BSDFContext(mi.TransportMode.Radiance, flags)
        bs, weight = bsdf.sample(ctx, si, u, mi.Point2f(u, 0.37))
        sampled = np.asarray(bs.sampled_type)[np.asarray(bs.pdf) > 0]
        assert len(sampled) and np.all(sampled == int(component))
        value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
        np.testing.assert_allclose(np.asarray(pdf), np.asarray(bs.pdf), rtol=1e-4)
    only_glossy = mi.BSDFContext(mi.TransportMode.Radiance, mi.BSDFFlags.GlossyReflection)
    only_diffuse = mi.BSDFContext(mi.TransportMode.Radiance, mi.BSDFFlags.DiffuseReflection)
    wo = shading.vector([shading.direction(60, 100)] * 4000)
    assert np.all(np.asarray(bsdf.pdf(only_diffuse, si, wo)) == pytest.approx(np.cos(np.radians(60)) / np.pi,
                                                                              rel=1e-5))
    np.testing.assert_allclose(np.asarray(bsdf.eval(only_diffuse, si, wo)), 0.4 * 0.5 / np.pi, rtol=1e-5)
    full = np.asarray(bsdf.eval(mi.BSDFContext(), si, wo))
    np.testing.assert_allclose(np.asarray(bsdf.eval(only_glossy, si, wo)), full - 0.4 * 0.5 / np.pi,
                               rtol=1e-4, atol=1e-6)


def test13_material_spectra_compile_the_same_kernels_wherever_numpy_put_the_grid(monkeypatch):
    """A named material's spectra are resampled by one kernel each at every load; Dr.Jit maps numpy's memory
    and its alignment changed that kernel (a kernel-cache miss) from one process to the next."""
    from scratch_iridescence.mitsuba_bridge.bsdf import fresnel

    original = fresnel._wavelength_grid_nm

    def shifted(array, offset_bytes):  # the same values `offset_bytes` past a 64-byte boundary
        raw = np.zeros(array.nbytes + 128, np.uint8)
        start = (-raw.ctypes.data) % 64 + offset_bytes
        view = raw[start:start + array.nbytes].view(array.dtype)
        view[...] = array
        return view

    def kernels(offset_bytes):
        monkeypatch.setattr(fresnel, "_wavelength_grid_nm", lambda texture: shifted(original(texture), offset_bytes))
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory, True):
            dr.kernel_history_clear()
            eta, k = fresnel.material_textures("Al")
            return [kernel["hash"] for kernel in dr.kernel_history() if kernel["type"] == dr.KernelType.JIT], eta

    aligned, eta = kernels(0)
    unaligned, eta_unaligned = kernels(4)
    assert aligned and unaligned == aligned
    assert str(eta) == str(eta_unaligned)
