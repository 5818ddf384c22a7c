"""Far-field amplitude of one straight scratch segment inside the window (docs/model.md §3).

In the segment's frame (direction d, normal n = (-d_y, d_x)) the Gaussian window
is a product of a factor along and a factor across the segment, so

    S_k(ξ) = [Φ(c + L; ν∥) - Φ(c; ν∥)] · A(ν⊥)

with ``c`` the start of the segment measured from the foot point of the shading
point x0, ``ν∥ = ξ·d``, ``ν⊥ = ξ·n`` and ``A`` the windowed cross-section transform
of :mod:`.profiles`.  x0 is the phase reference: every length here is a few σ
at most, which is what keeps float32 accurate.  Units: µm and 1/µm.
"""
from __future__ import annotations

from typing import NamedTuple

import drjit as dr

from . import profiles
from .complexmath import Cx
from .window import piece_and_run_integrals, window_integral

__all__ = ["SegmentGeometry", "amplitude", "flat_bottomed", "frequencies", "incoherent_intensity"]


class SegmentGeometry(NamedTuple):
    """One segment seen from the shading point, in the local shading frame (µm)."""

    c: object  #: Float: start of the segment along d, from the foot point of x0
    length: object  #: Float: L
    a_perp: object  #: Float: signed distance of the centre line from x0 (a·n)
    dx: object  #: Float: unit direction d
    dy: object
    width: object  #: Float: W (µm)
    depth: object  #: Float: D (µm)
    #: Bool: V-groove (else flat bottom); a Python bool where the whole set has one profile (lookup.Grid)
    triangular: object


def flat_bottomed(triangular):
    """``~triangular`` for a mask or a Python bool (:attr:`SegmentGeometry.triangular`)."""
    return (not triangular) if isinstance(triangular, bool) else ~triangular


def frequencies(segment: SegmentGeometry, xi_x, xi_y):
    """``(ν∥, ν⊥) = (ξ·d, ξ·n)`` for every wavelength."""
    nu_par = xi_x * segment.dx + xi_y * segment.dy
    nu_perp = xi_y * segment.dx - xi_x * segment.dy
    return nu_par, nu_perp


def cross_section(segment: SegmentGeometry, nu_perp, kappa, sigma, coherent: bool) -> Cx:
    """``A(ν⊥)`` of the segment's profile; V-grooves cost extra only in SIMD packets that hold one."""
    a_perp, width = segment.a_perp, segment.width

    def triangular(nu, kappa):
        a = profiles.triangular(a_perp, width, nu, kappa, sigma, coherent)
        return a.re, a.im

    def rectangular(nu, kappa):
        a = profiles.rectangular(a_perp, width, nu, kappa, sigma, coherent)
        return a.re, a.im

    re, im = dr.if_stmt((nu_perp, kappa), segment.triangular, triangular, rectangular,
                        label="scratch_profile")
    return Cx(re, im)


def amplitude(segment: SegmentGeometry, xi_x, xi_y, k_z, sigma) -> Cx:
    """``S_k(ξ)`` (the incoherent mode sums :func:`incoherent_intensity` instead).

    Parameters
    ----------
    segment:
        Geometry relative to the shading point (µm).
    xi_x, xi_y:
        Spatial frequency ξ in the local frame (1/µm), one value per wavelength.
    k_z:
        Phase per unit depth ``2π(γ_i + γ_o)/λ`` (1/µm), per wavelength.
    sigma:
        Window standard deviation σ (µm).
    """
    nu_par, nu_perp = frequencies(segment, xi_x, xi_y)
    along = window_integral(segment.c, segment.c + segment.length, nu_par, sigma)
    return along * cross_section(segment, nu_perp, k_z * segment.depth, sigma, True)


def incoherent_intensity(segment: SegmentGeometry, xi_x, xi_y, k_z, sigma, before, after):
    """The piece's share ``Re(S'_k S'_run*)`` of ``|S'_run|²`` (docs/model.md §4.2), per wavelength.

    The incoherent mode adds the intensities of straight segments; a segment that the tables cut into
    pieces, or a polyline running straight on, is one run that goes on ``before`` the piece's start and
    ``after`` its end (µm, 0 where it ends).  Its pieces' shares add up to the run's ``|S'|²`` wherever
    the window sees them, so where a long groove is cut no seam shows (``|S'_k|²`` per piece halved
    the intensity over a window at every cut)."""
    nu_par, nu_perp = frequencies(segment, xi_x, xi_y)
    piece, run = piece_and_run_integrals(segment.c, segment.c + segment.length, before, after, nu_par, sigma)
    across = cross_section(segment, nu_perp, k_z * segment.depth, sigma, False).abs2()
    return dr.fma(piece.re, run.re, piece.im * run.im) * across
