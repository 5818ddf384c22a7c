"""The CPU backend's target: ``vzeroupper`` before calls out of a kernel (mitsuba_bridge/device/llvm_target.py)."""
import ctypes.util
import platform

import numpy as np
import pytest

from scratch_iridescence.mitsuba_bridge.device import llvm_target, variants

dr = pytest.importorskip("drjit")
X86_64 = platform.machine().lower() in ("x86_64", "amd64")


def test01_setting_the_cpu_variant_asks_for_vzeroupper_once():
    variants.set_variant("llvm_ad_spectral")
    current = llvm_target.target()
    assert current is not None and current.cpu
    assert current.vector_width in (4, 8, 16, 32)
    assert current.inserts_vzeroupper == X86_64
    assert current.features.split(",").count(llvm_target.VZEROUPPER) == (1 if X86_64 else 0)


def test02_configuring_again_changes_nothing():
    variants.set_variant("llvm_ad_spectral")
    before = llvm_target.target()
    assert llvm_target.configure() and variants.set_variant("llvm_ad_spectral")
    assert llvm_target.target() == before


@pytest.mark.skipif(not X86_64, reason="vzeroupper is an x86-64 instruction")
def test03_the_same_image_bit_for_bit_with_and_without_vzeroupper():
    """vzeroupper computes nothing: a scene that takes Embree's mixed-geometry path renders the same bits."""
    import mitsuba as mi

    variants.set_variant("llvm_ad_spectral")
    description = mi.cornell_box()
    # a box filter: a sample adds to its own pixel only, so no two threads add to one pixel in either order
    description["sensor"]["film"].update(width=32, height=32, rfilter={"type": "box"})
    # an analytic sphere next to the box's meshes: Embree dispatches over two sub-hierarchies
    description["ball"] = {"type": "sphere", "center": [0.3, -0.6, 0.3], "radius": 0.3, "bsdf": {"type": "diffuse"}}
    images, targets = [], []
    try:
        for vzeroupper in (False, True):
            assert llvm_target.configure(vzeroupper=vzeroupper)
            targets.append(llvm_target.target())
            images.append(np.array(mi.render(mi.load_dict(description), spp=16, seed=3)))
    finally:
        llvm_target.configure()
    assert targets[0].inserts_vzeroupper is False and targets[1].inserts_vzeroupper is True
    assert images[0].mean() > 0.01
    assert np.array_equal(images[0], images[1])


def test04_a_library_without_the_target_functions_is_left_alone():
    libc = ctypes.util.find_library("c")
    if libc is None:
        pytest.skip("no C library to stand for a Dr.Jit without the symbols")
    assert llvm_target.target(libc) is None
    assert llvm_target.configure(library=libc) is False
