"""Which Mitsuba variant renders: spectral always (diffraction colours need wavelengths), CUDA when present.

The CPU variant is chosen only after :func:`mitsuba_bridge.device.llvm_library.llvm_problem`
found a usable libLLVM: with an old one the first compiled kernel aborts the
whole process (Blender included), so it is refused here, before any kernel.
"""
from __future__ import annotations

from . import llvm_library
from ..errors import ScratchUserError

__all__ = ["SPECTRAL_VARIANTS", "VariantError", "choose_variant", "set_variant", "on_gpu"]

#: In order of preference for ``"auto"``.
SPECTRAL_VARIANTS = ("cuda_ad_spectral", "llvm_ad_spectral")


def on_gpu() -> bool:
    """Whether the active Mitsuba variant renders on an NVIDIA GPU (CUDA) rather than the CPU."""
    import mitsuba as mi

    return mi.variant().startswith("cuda")


class VariantError(ScratchUserError, RuntimeError):
    """No usable spectral Mitsuba variant (or an unusable one was asked for)."""


def choose_variant(requested: str = "auto") -> str:
    """The Mitsuba variant to use for ``requested`` (``"auto"`` or a variant name).

    ``"auto"`` takes CUDA when Dr.Jit finds a CUDA device, else LLVM (CPU) when
    its libLLVM is usable.  Raises :class:`VariantError` with a fix when neither
    works; compiles no kernel.
    """
    import drjit as dr
    import mitsuba as mi

    available = set(mi.variants())
    backends = {"cuda_ad_spectral": dr.JitBackend.CUDA, "llvm_ad_spectral": dr.JitBackend.LLVM}
    if requested != "auto":
        if requested not in available:
            raise VariantError(f"Mitsuba variant '{requested}' is not part of this Mitsuba build "
                               f"(available: {', '.join(sorted(available))})")
        if "spectral" not in requested:
            raise VariantError(f"variant '{requested}' is not spectral: diffraction colours need a "
                               f"spectral variant such as {' or '.join(SPECTRAL_VARIANTS)}")
        backend = backends.get(requested)
        if backend is not None and not dr.has_backend(backend):
            raise VariantError(_missing_backend_message(requested))
        if backend == dr.JitBackend.LLVM and (problem := _llvm_problem()):
            raise VariantError(problem)
        return requested
    for variant in SPECTRAL_VARIANTS:
        if variant in available and dr.has_backend(backends[variant]):
            if backends[variant] == dr.JitBackend.LLVM and (problem := _llvm_problem()):
                raise VariantError(problem)
            return variant
    raise VariantError(_missing_backend_message("llvm_ad_spectral"))


def _llvm_problem() -> str | None:
    """The version check (instant), then the crash probe in a child process (once per process)."""
    return llvm_library.llvm_problem() or llvm_library.probe_problem()


def _missing_backend_message(variant: str) -> str:
    if variant.startswith("cuda"):
        return (f"Mitsuba variant '{variant}' needs an NVIDIA GPU with a CUDA driver; none was found. "
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
