"""The machine Mitsuba runs on: which variant (CUDA, Metal or LLVM), the libLLVM the CPU backend loads,
the CPU kernels' machine code, counting the kernels Dr.Jit compiles, and the memory this process
may still take (:mod:`.memory`: free memory, ``ulimit``, cgroups).

The lowest room of the bridge: it imports nothing of the project but :mod:`..errors`.
"""
