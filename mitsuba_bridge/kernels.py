"""Counting the kernels Dr.Jit compiles, for tests and benchmarks of the interactive session."""
from __future__ import annotations

__all__ = ["KernelCounter"]


class KernelCounter:
    """Counts kernels that Dr.Jit had to compile (or load from its disk cache) through its kernel history.

    Launches of kernels already in memory do not count: a steady viewport
    adds nothing.  Reading the history clears it, so only one counter should
    be active at a time.
    """

    def __init__(self):
        import drjit as dr

        self._previous = dr.flag(dr.JitFlag.KernelHistory)
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history()  # drop what happened before
        self.compiled = 0

    def poll(self) -> int:
        """Kernels new since the last call (also added to ``compiled``)."""
        import drjit as dr

        new = sum(1 for entry in dr.kernel_history()
                  if entry["type"] == dr.KernelType.JIT
                  and (not entry.get("cache_hit", 0) or entry.get("cache_disk", 0)))
        self.compiled += new
        return new

    def close(self) -> None:
        import drjit as dr

        dr.kernel_history()
        dr.set_flag(dr.JitFlag.KernelHistory, self._previous)
