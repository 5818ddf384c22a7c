"""Variant choice: spectral always, CUDA when Dr.Jit finds a device, else LLVM (tested on LLVM only)."""
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
