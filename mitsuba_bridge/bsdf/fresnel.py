"""Base reflectance: conductor Fresnel for all wavelengths at once, and Mitsuba's material spectra.

Mitsuba's ``mi.fresnel_conductor`` takes one ``Float`` (a single wavelength);
the scratch BSDF needs the four wavelengths of a spectral ray together, so the
unpolarised conductor Fresnel equations are written out here on complex pairs
of ``mi.Spectrum`` (tested against Mitsuba's function channel by channel).
"""
from __future__ import annotations

import drjit as dr

from .complexmath import Cx

__all__ = ["fresnel_conductor", "material_textures"]


def _sqrt(z: Cx) -> Cx:
    """Principal square root."""
    magnitude = dr.sqrt(z.abs2())
    re = dr.sqrt(dr.maximum(0.5 * (magnitude + z.re), 0.0))
    im = dr.sqrt(dr.maximum(0.5 * (magnitude - z.re), 0.0))
    return Cx(re, dr.select(z.im < 0.0, -im, im))


def fresnel_conductor(cos_theta, eta, k):
    """Unpolarised reflectance of a conductor with complex index ``eta + i k``.

    ``cos_theta`` (> 0) is the cosine of incidence (one per lane), ``eta`` and
    ``k`` one value per wavelength.  Standard Fresnel equations with the complex
    cosine of refraction ``a = sqrt(η² - sin²θ)``::

        r_s = (cos θ - a) / (cos θ + a),   r_p = (η² cos θ - a) / (η² cos θ + a)
    """
    cos_theta = dr.clip(cos_theta, 1e-6, 1.0)
    sin2 = 1.0 - cos_theta * cos_theta
    n = Cx(eta, k)
    n2 = n * n
    a = _sqrt(n2 - sin2)
    # Only |r|² is needed, so the sign convention of r_s does not matter.
    r_s = (a - cos_theta) / (a + cos_theta)
    n2_cos = n2 * cos_theta
    r_p = (n2_cos - a) / (n2_cos + a)
    return 0.5 * (r_s.abs2() + r_p.abs2())


def material_textures(name: str):
    """``(eta, k)`` textures of one of Mitsuba's tabulated conductors.

    Raises ``ValueError`` for a name without ``data/ior/<name>.eta.spd`` in
    Mitsuba's data folder.
    """
    import os

    import mitsuba as mi

    paths = [str(mi.file_resolver().resolve(f"data/ior/{name}.{part}.spd")) for part in ("eta", "k")]
    if not all(os.path.isfile(p) for p in paths):
        folder = os.path.dirname(str(mi.file_resolver().resolve("data/ior/Al.eta.spd")))
        known = sorted({f.split(".")[0] for f in os.listdir(folder) if f.endswith(".k.spd")}) \
            if os.path.isdir(folder) else []
        raise ValueError(
            f"unknown material {name!r}: use a conductor name of Mitsuba's 'conductor' plugin "
            f"({', '.join(known[:12])}{', ...' if len(known) > 12 else ''}), 'none' for a perfect "
            "mirror, or give 'eta' and 'k'")
    return tuple(mi.load_dict({"type": "spectrum", "filename": p}) for p in paths)
