"""The machine Mitsuba runs on: which variant (CUDA, Metal or LLVM), the libLLVM the CPU backend loads,
the CPU kernels' machine code, and counting the kernels Dr.Jit compiles.

The lowest room of the bridge: it imports nothing of the project but :mod:`..errors`.
"""
