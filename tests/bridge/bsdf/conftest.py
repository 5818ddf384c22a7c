"""Variant and plugin registration for the BSDF tests (llvm_ad_spectral: the CPU JIT variant).

``SCRATCH_TEST_VARIANT=cuda_ad_spectral`` runs them on an NVIDIA GPU instead (docs/bsdf.md, GPU).

The variant is activated as a render activates it (:func:`...render.activation.activate`: the CPU
kernels' target, the plugins, the frozen passes' calibration) when pytest collects this folder, so
that test modules may use Mitsuba types in parametrisations; the fixtures restore it after tests
that switch variants.
"""
import os

import mitsuba as mi
import pytest

from scratch_iridescence.mitsuba_bridge.render.activation import activate

VARIANT = os.environ.get("SCRATCH_TEST_VARIANT", "llvm_ad_spectral")
activate(VARIANT)


@pytest.fixture(scope="session")
def variant():
    return VARIANT


@pytest.fixture(autouse=True)
def spectral_variant(variant):
    """Every BSDF test starts and ends in the spectral LLVM variant with the plugins registered."""
    if mi.variant() != variant:
        mi.set_variant(variant)
    yield
    if mi.variant() != variant:
        mi.set_variant(variant)
