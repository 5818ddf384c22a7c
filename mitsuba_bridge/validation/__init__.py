"""Numerical validation: the brute-force wave-field reference (numpy), shading points on a flat
test surface, and the supplement's Fig. 15 comparison (``validate`` on the command line, ``make paper``).

Not shipped in the extension (its figure needs matplotlib and its reference scipy); the tests and
the paper harness use it.
"""
