"""Counting the kernels Dr.Jit compiles, for tests and benchmarks of the interactive session."""
from __future__ import annotations

__all__ = ["KernelCounter"]


class KernelCounter:
    """Counts kernels that Dr.Jit had to compile (or load from its disk cache).

    Reads Dr.Jit's launch statistics (``drjit.detail.launch_stats()``: launches,
    soft misses — loaded from the disk cache —, hard misses — compiled), which
    cost nothing per pass.  The kernel history (``JitFlag.KernelHistory``) gives
    the same count but keeps every launch's IR text until it is read, about
    7 ms per pass to convert on a 2-core CPU; it is the fallback where the
    statistics are missing.  Launches of kernels already in memory do not
    count: a steady viewport adds nothing.  The statistics are process-wide:
    kernels compiled by other threads meanwhile count too.
    """

    def __init__(self):
        import drjit as dr

        self._stats = getattr(getattr(dr, "detail", None), "launch_stats", None)
        self._previous = None
        if self._stats is None:
            self._previous = dr.flag(dr.JitFlag.KernelHistory)
            dr.set_flag(dr.JitFlag.KernelHistory, True)
            dr.kernel_history()  # drop what happened before
        else:
            self._misses = self._missed()
        self.compiled = 0

    def _missed(self) -> int:
        _, soft, hard = self._stats()
        return soft + hard

    def poll(self) -> int:
        """Kernels new since the last call (also added to ``compiled``)."""
        import drjit as dr

        if self._stats is not None:
            misses = self._missed()
            new, self._misses = misses - self._misses, misses
        else:
            new = sum(1 for entry in dr.kernel_history()
                      if entry["type"] == dr.KernelType.JIT
                      and (not entry.get("cache_hit", 0) or entry.get("cache_disk", 0)))
        self.compiled += new
        return new

    def close(self) -> None:
        import drjit as dr

        if self._previous is not None:
            dr.kernel_history()
            dr.set_flag(dr.JitFlag.KernelHistory, self._previous)
