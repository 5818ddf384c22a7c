"""Which Mitsuba variant renders: spectral always (diffraction colours need wavelengths), a GPU when present.

``"auto"`` takes CUDA (NVIDIA), then Metal (Apple GPUs: Mitsuba's macOS arm64
wheels ship ``metal_ad_spectral``; not run on Apple hardware by this project,
docs/rendering.md), then the CPU (LLVM).  The CPU variant is chosen only after
:func:`mitsuba_bridge.device.llvm_library.llvm_problem` found a usable libLLVM:
with an old one the first compiled kernel aborts the whole process (Blender
included), so it is refused here, before any kernel.  The GPU variants need no
LLVM.
"""
from __future__ import annotations

from . import llvm_library
from ..errors import ScratchUserError

__all__ = ["SPECTRAL_VARIANTS", "VariantError", "choose_variant", "set_variant", "on_gpu"]

#: In order of preference for ``"auto"``.
SPECTRAL_VARIANTS = ("cuda_ad_spectral", "metal_ad_spectral", "llvm_ad_spectral")
#: The Dr.Jit backend each variant prefix runs on (by name: ``dr.JitBackend`` is imported lazily).
_BACKENDS = {"cuda": "CUDA", "metal": "Metal", "llvm": "LLVM"}


def is_gpu_variant(variant: str) -> bool:
    """Whether ``variant`` renders on a GPU (CUDA or Metal): warps of 32 lanes, no CPU threads' blocks."""
    return variant.startswith(("cuda", "metal"))


def on_gpu() -> bool:
    """Whether the active Mitsuba variant renders on a GPU (CUDA or Metal) rather than the CPU."""
    import mitsuba as mi

    return is_gpu_variant(mi.variant() or "")


class VariantError(ScratchUserError, RuntimeError):
    """No usable spectral Mitsuba variant (or an unusable one was asked for)."""


def choose_variant(requested: str = "auto") -> str:
    """The Mitsuba variant to use for ``requested`` (``"auto"`` or a variant name).

    ``"auto"`` takes CUDA when Dr.Jit finds a CUDA device, else Metal when this
    Mitsuba build has the Metal variants and Dr.Jit finds a Metal device, else
    LLVM (CPU) when its libLLVM is usable.  Raises :class:`VariantError` with a
    fix when none works; compiles no kernel.
    """
    import drjit as dr
    import mitsuba as mi

    available = set(mi.variants())
    if requested != "auto":
        if requested not in available:
            raise VariantError(f"Mitsuba variant '{requested}' is not part of this Mitsuba build "
                               f"(available: {', '.join(sorted(available))})")
        if "spectral" not in requested:
            raise VariantError(f"variant '{requested}' is not spectral: diffraction colours need a "
                               f"spectral variant such as {' or '.join(SPECTRAL_VARIANTS)}")
        backend = _backend(requested)
        if backend is not None and not dr.has_backend(backend):
            raise VariantError(_missing_backend_message(requested))
        if backend == dr.JitBackend.LLVM and (problem := _llvm_problem()):
            raise VariantError(problem)
        return requested
    for variant in SPECTRAL_VARIANTS:
        backend = _backend(variant)
        if variant in available and backend is not None and dr.has_backend(backend):
            if backend == dr.JitBackend.LLVM and (problem := _llvm_problem()):
                raise VariantError(problem)
            return variant
    raise VariantError(_missing_backend_message("llvm_ad_spectral"))


def _backend(variant: str):
    """The ``dr.JitBackend`` a variant runs on, or None (scalar variants; a Dr.Jit without that backend)."""
    import drjit as dr

    name = _BACKENDS.get(variant.split("_")[0])
    return getattr(dr.JitBackend, name, None) if name else None


def _llvm_problem() -> str | None:
    """The version check (instant), then the crash probe in a child process (once per process)."""
    return llvm_library.llvm_problem() or llvm_library.probe_problem()


def _missing_backend_message(variant: str) -> str:
    if variant.startswith("cuda"):
        return (f"Mitsuba variant '{variant}' needs an NVIDIA GPU with a CUDA driver; none was found. "
                "Choose 'Automatic' or the CPU (LLVM) variant")
    if variant.startswith("metal"):
        return (f"Mitsuba variant '{variant}' needs an Apple GPU (macOS on Apple silicon); none was found. "
                "Choose 'Automatic' or the CPU (LLVM) variant")
    return llvm_library.llvm_problem() or "Mitsuba's CPU backend is unavailable"


def set_variant(requested: str = "auto") -> str:
    """Set the variant :func:`choose_variant` picks for ``requested``; returns it.

    On the CPU, first makes its kernels clear the vector registers' upper halves before calling out
    (:func:`.llvm_target.configure`: Intel CPUs otherwise run Embree's SSE code at a penalty).
    Registers no plugin: :func:`...render.activation.activate` is what renders call.
    """
    import mitsuba as mi

    from . import llvm_target

    variant = choose_variant(requested)
    if mi.variant() != variant:
        mi.set_variant(variant)
    if variant.startswith("llvm"):
        llvm_target.configure()
    return variant
