"""Pure Dr.Jit functions of the scratch model (docs/model.md §2, §3): complex arithmetic on pairs of
arrays, the Faddeeva function, the Gaussian window's integrals, the cross-section transforms, one
segment's amplitude, and the windowed transform of a convex polygon.  No plugin state, no tables.
"""
