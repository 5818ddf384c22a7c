"""The machine code of Dr.Jit's CPU kernels: ``vzeroupper`` before every call out of a kernel (x86-64).

Dr.Jit compiles its CPU kernels for the host processor as LLVM names it (like
``-march=native``), with LLVM's tuning for that processor.  For some Intel CPUs
with AVX-512 (the 2-core Xeon of 2026-12-06, which LLVM calls ``rocketlake``)
that tuning omits ``vzeroupper`` before calls, so a kernel calls into Embree
(Mitsuba's ray tracer, per SIMD packet of rays) with the upper halves of the
vector registers still dirty.  Intel CPUs then run legacy-SSE code at a heavy
penalty (AMD ones do not): Embree's dispatch over its sub-hierarchies, taken
whenever a scene mixes triangle meshes with an analytic shape such as the
sphere of a point light, spent 91 % of its time on one SSE comparison.  Measured
on the paper's scenes (docs/bsdf.md, Performance, "vzeroupper before calls"):
+17 to +28 % samples per core-second where a sphere lamp lights the scratched
plate, scenes without such a shape unchanged, images identical bit for bit
(``vzeroupper`` computes nothing).

:func:`configure` adds LLVM's ``+vzeroupper`` tuning feature to the backend's
target once per process (idempotent), before the variant compiles its first
kernel (:func:`mitsuba_bridge.device.variants.set_variant`).  Dr.Jit 1.5 has no Python
binding for ``jit_llvm_set_target``; its core library exports it with C++
linkage, so it is called through ctypes by its mangled name.  A Dr.Jit without
these symbols leaves the target as it is (:func:`configure` returns ``False``).
"""
from __future__ import annotations

import ctypes
import functools
import os
import platform
from dataclasses import dataclass

__all__ = ["VZEROUPPER", "Target", "target", "configure"]

#: LLVM's x86 tuning feature "insert vzeroupper before calls and returns that leave AVX code".
VZEROUPPER = "+vzeroupper"
#: drjit-core's exported functions (C++ linkage): set_target(cpu, features, width), and the getters.
_SYMBOLS = {"set": "_Z19jit_llvm_set_targetPKcS0_j", "cpu": "_Z19jit_llvm_target_cpuv",
            "features": "_Z24jit_llvm_target_featuresv", "width": "_Z21jit_llvm_vector_widthv"}


@dataclass(frozen=True)
class Target:
    """What the CPU backend compiles for: LLVM's CPU name, its feature list, SIMD lanes per packet."""

    cpu: str
    features: str
    vector_width: int

    @property
    def inserts_vzeroupper(self) -> bool:
        return VZEROUPPER in self.features.split(",")


@functools.lru_cache(maxsize=None)
def _core_functions(library: str | None = None):
    """drjit-core's target functions as ctypes callables (looked up once), or ``None`` when it lacks them."""
    if library is None:
        import drjit as dr

        library = os.path.join(os.path.dirname(dr.__file__), "libdrjit-core.so")
    try:
        core = ctypes.CDLL(library)
        functions = {key: getattr(core, name) for key, name in _SYMBOLS.items()}
    except (OSError, AttributeError):
        return None
    functions["cpu"].restype = functions["features"].restype = ctypes.c_char_p
    functions["width"].restype = ctypes.c_uint32
    functions["set"].argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32]
    functions["set"].restype = None
    return functions


def target(library: str | None = None) -> Target | None:
    """The CPU backend's current target; ``None`` when the backend is not initialised or not reachable."""
    functions = _core_functions(library)
    if functions is None:
        return None
    cpu, features = functions["cpu"](), functions["features"]()
    if cpu is None:  # LLVM not loaded (yet): jit_llvm_set_target would do nothing either
        return None
    return Target(cpu.decode(), (features or b"").decode(), int(functions["width"]()))


def configure(*, vzeroupper: bool = True, vector_width: int | None = None, library: str | None = None) -> bool:
    """Set the CPU backend's target: ``+vzeroupper`` on or off (x86-64 only), optionally the SIMD width.

    Call with the LLVM variant set and before the kernels it should affect are traced (kernels
    already compiled keep their code; the target is part of a kernel's cache key, so a changed
    target compiles anew).  Changes nothing when the target already is that one, so calling it at
    every render is free.  Returns whether the target now is the requested one.
    """
    current = target(library)  # None also when the library lacks the functions
    if current is None:
        return False
    features = [feature for feature in current.features.split(",") if feature and feature != VZEROUPPER]
    if vzeroupper and platform.machine().lower() in ("x86_64", "amd64"):
        features.append(VZEROUPPER)  # an unknown feature elsewhere: LLVM would warn at every kernel
    wanted = Target(current.cpu, ",".join(features), vector_width or current.vector_width)
    if wanted != current:
        _core_functions(library)["set"](wanted.cpu.encode(), wanted.features.encode(), wanted.vector_width)
    return target(library) == wanted
