"""Periodic families: runs of identical, parallel, equally spaced scratches summed in closed form.

A CD's tracks and a ruled grating are, inside a coherence window, one
infinite periodic set of straight grooves.  Their sum over the tracks is a
Fourier series (Poisson summation, docs/model.md §3.5): with the window's
along factor ``σ√(2π) e^{-2π²σ²ν∥²}`` common to all of them,

    Σ_n S_n(ξ) = σ√(2π) e^{-2π²σ²ν∥²} · (1/P) Σ_m ŵ(ν⊥ + m/P) G(m/P) e^{2πi m a0/P}

(``P`` the pitch, ``a0`` the offset of a track from the shading point, ``ŵ``
the window's transform across, ``G`` the transform of one groove's
``e^{iκp(u)} - 1``), and only the three orders ``m`` nearest to ``-ν⊥P``
matter where σ ≥ P.  A query that qualifies costs one closed form instead of
a scan of the ~20 tracks in its window and their transforms.

**Tables** (:func:`.tables.periodic.periodic_families`, numpy, built when dense tables are
uploaded): per grid cell up to two *families*, each a maximal set of the
cell's references that are parallel (|sin| < ``PARALLEL_SIN``), of one width
and depth, whose lines are equally spaced (``PITCH_TOLERANCE``) and whose
pieces tile each track without gap or overlap, together with the rectangle
(in the family's own frame, cell units) where every track runs through and
no other piece of the cell lies.  A cell with pieces of a third direction, a
missing or an extra track, or pieces that end irregularly gets no family
there, and its queries scan as before.

**Kernel** (:func:`find_family`, :func:`family_field`): a query uses a family
when its window's box (4σ, the scan's window radius, through the UV
Jacobian) reaches no lattice position beyond the first or last track of the
family in any cell it touches — at most 2 × 2 cells, each holding the same
run (direction, pitch, groove, offsets a whole number of pitches apart) —
when no track ends within 7.2σ of x0 (so every end lies beyond the 6σ
where the scan skips its term), and when σ ≥ P.  Otherwise the
lane scans (:func:`.lookup.for_each_segment`) and gets the scan's values bit
for bit.  The closed form is the exact sum over the infinite run; the scan
drops tracks beyond 4σ (e^-8 of the window), so the two differ by that
truncation, ~1e-4 (tests/bridge/bsdf/test_periodic.py).

**Kinks** (:func:`_end_lines`, and the same functions): where two families meet on a line on which
every track of one ends and every track of the other begins (a CD's polygonal tracks turn there), a
window across the line (its box in up to 2 × 2 cells) sums each run cut by its side's half-plane (one
Faddeeva evaluation per order, docs/model.md §3.5), and ``sample`` draws either run's line in
proportion to its cut weight; a window near the line but wholly on one side sums that run cut alone.
Sets without kinks compile none of this.

**Incoherent mode** (:func:`family_intensity`): the tracks' intensities sum by the same Poisson formula
to the order 0 alone, the squared along factor times (σ/P) the squared groove transform averaged over
the squared window's transform (4-point Gauss–Hermite; docs/model.md §3.5); at a kink each run's cut
along factor is averaged over the tracks' offsets the same way.
Units as everywhere in the kernels: µm, 1/µm.
"""
from __future__ import annotations

from __future__ import annotations

from .field import (MAX_INCOHERENT_WIDTH_SIGMAS, NARROW_GROOVE_SIGMAS, family_field, family_intensity,
                    groove_transform, run_energies)
from .find import ACROSS_SIGMAS, ALONG_SIGMAS, Family, find_family

__all__ = ["Family", "find_family", "family_field", "family_intensity", "groove_transform", "run_energies",
           "ACROSS_SIGMAS", "ALONG_SIGMAS", "MAX_INCOHERENT_WIDTH_SIGMAS", "NARROW_GROOVE_SIGMAS"]
