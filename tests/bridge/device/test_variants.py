"""Variant choice: spectral always, CUDA, else Metal when Dr.Jit finds a device, else LLVM (renders tested on LLVM
only; the GPUs' availability is mocked)."""
import pytest

from scratch_iridescence.mitsuba_bridge.device import variants

dr = pytest.importorskip("drjit")


def test01_auto_prefers_cuda_when_a_device_is_present(monkeypatch):
    monkeypatch.setattr(dr, "has_backend", lambda backend: True)
    assert variants.choose_variant("auto") == "cuda_ad_spectral"


def test02_auto_falls_back_to_llvm_without_a_gpu(monkeypatch):
    monkeypatch.setattr(dr, "has_backend", lambda backend: backend == dr.JitBackend.LLVM)
    assert variants.choose_variant("auto") == "llvm_ad_spectral"


def test03_without_llvm_the_error_says_how_to_install_it(monkeypatch):
    monkeypatch.setattr(dr, "has_backend", lambda backend: False)
    with pytest.raises(variants.VariantError, match="libllvm"):
        variants.choose_variant("auto")


def test04_rgb_and_unknown_variants_are_refused():
    with pytest.raises(variants.VariantError, match="not spectral"):
        variants.choose_variant("llvm_ad_rgb")
    with pytest.raises(variants.VariantError, match="not part of"):
        variants.choose_variant("vulkan_spectral")


def test05_set_variant_sets_the_llvm_variant_here():
    import mitsuba as mi

    assert variants.set_variant("llvm_ad_spectral") == "llvm_ad_spectral" == mi.variant()


# Apple GPUs.  Mitsuba's macOS arm64 wheel lists the metal_ad_* variants and Dr.Jit finds a Metal device there;
# neither exists on this Linux machine, so both answers are mocked (the choice is all that is tested here: the
# Metal variant has not rendered on Apple hardware in this project, docs/rendering.md).
MAC_VARIANTS = ["scalar_spectral", "llvm_ad_spectral", "metal_ad_spectral", "metal_ad_rgb", "llvm_ad_rgb"]


@pytest.fixture
def mac_wheel(monkeypatch):
    import mitsuba as mi

    monkeypatch.setattr(mi, "variants", lambda: list(MAC_VARIANTS))


def backends(*names):
    return lambda backend: backend in {getattr(dr.JitBackend, name) for name in names}


def test06_auto_takes_metal_on_an_apple_gpu(mac_wheel, monkeypatch):
    monkeypatch.setattr(dr, "has_backend", backends("Metal", "LLVM"))
    assert variants.choose_variant("auto") == "metal_ad_spectral"


def test07_metal_needs_no_llvm(mac_wheel, monkeypatch):
    # An unusable LLVM (here 15) refuses only the CPU variant; the GPU renders.
    monkeypatch.setattr(dr, "has_backend", backends("Metal", "LLVM"))
    monkeypatch.setattr(dr.detail, "llvm_version", lambda: (15, 0, 6))
    assert variants.choose_variant("auto") == "metal_ad_spectral"
    with pytest.raises(variants.VariantError, match="found LLVM 15"):
        variants.choose_variant("llvm_ad_spectral")


def test08_cuda_comes_before_metal_and_metal_before_llvm(monkeypatch):
    import mitsuba as mi

    monkeypatch.setattr(mi, "variants", lambda: [*MAC_VARIANTS, "cuda_ad_spectral"])
    monkeypatch.setattr(dr, "has_backend", backends("CUDA", "Metal", "LLVM"))
    assert variants.choose_variant("auto") == "cuda_ad_spectral"
    monkeypatch.setattr(dr, "has_backend", backends("LLVM"))  # a Mac without a usable GPU (a VM)
    assert variants.choose_variant("auto") == "llvm_ad_spectral"


def test09_a_build_without_metal_variants_never_chooses_metal(monkeypatch):
    # The Linux and Windows wheels (this one) have no metal_ad_*: a Metal backend alone does not make one.
    monkeypatch.setattr(dr, "has_backend", backends("Metal", "LLVM"))
    assert variants.choose_variant("auto") == "llvm_ad_spectral"
    with pytest.raises(variants.VariantError, match="not part of this Mitsuba build"):
        variants.choose_variant("metal_ad_spectral")


def test10_asking_for_metal_without_an_apple_gpu_says_so(mac_wheel, monkeypatch):
    monkeypatch.setattr(dr, "has_backend", backends("LLVM"))
    with pytest.raises(variants.VariantError, match="needs an Apple GPU"):
        variants.choose_variant("metal_ad_spectral")
    with pytest.raises(variants.VariantError, match="not spectral"):
        variants.choose_variant("metal_ad_rgb")


def test11_metal_renders_with_the_gpu_schedule_and_whole_passes():
    from scratch_iridescence.mitsuba_bridge.render.schedule import GPU_CHUNK_SPP, sample_schedule, stratified_size

    assert variants.is_gpu_variant("metal_ad_spectral") and variants.is_gpu_variant("cuda_ad_spectral")
    assert not variants.is_gpu_variant("llvm_ad_spectral")
    chunks = sample_schedule(4096, 32 * 24, gpu=variants.is_gpu_variant("metal_ad_spectral"))
    # a pixel's samples within one 32-lane SIMD group, in a count the stratified sampler takes (16)
    assert max(chunk.spp for chunk in chunks) == stratified_size(GPU_CHUNK_SPP) == 16


def test12_the_plugin_accepts_every_unpolarised_spectral_jit_variant(monkeypatch):
    # Its check reads Mitsuba's flags, not variant names: metal_ad_spectral passes as cuda_ad_spectral does.
    import mitsuba as mi

    from scratch_iridescence.mitsuba_bridge.bsdf import plugin

    variants.set_variant("llvm_ad_spectral")
    monkeypatch.setattr(mi, "variant", lambda: "metal_ad_spectral")
    monkeypatch.setattr(mi, "is_spectral", True, raising=False)
    monkeypatch.setattr(mi, "is_polarized", False, raising=False)
    plugin._check_variant()
    monkeypatch.setattr(mi, "variant", lambda: "metal_ad_rgb")
    monkeypatch.setattr(mi, "is_spectral", False, raising=False)
    with pytest.raises(ValueError, match=r"metal_ad_rgb.*mi\.set_variant\('metal_ad_spectral'\) \(Apple GPU\)"):
        plugin._check_variant()
