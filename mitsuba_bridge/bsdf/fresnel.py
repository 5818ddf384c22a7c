"""Base reflectance: conductor Fresnel for all wavelengths at once, and Mitsuba's material spectra.

Mitsuba's ``mi.fresnel_conductor`` takes one ``Float`` (a single wavelength);
the scratch BSDF needs the four wavelengths of a spectral ray together, so the
unpolarised conductor Fresnel equations are written out here on complex pairs
of ``mi.Spectrum`` (tested against Mitsuba's function channel by channel).

A named material's η and k are read through :class:`ConductorSpectra`, one
table of both: the Fresnel factor is evaluated at least twice per path vertex
(towards the light and in the direction sampled), and two ``regular`` textures
cost eight gathers per wavelength there, the table one (docs/bsdf.md, Performance).
"""
from __future__ import annotations

from dataclasses import dataclass

import drjit as dr

__all__ = ["fresnel_conductor", "material_textures", "ConductorSpectra"]


def fresnel_conductor(cos_theta, eta, k):
    """Unpolarised reflectance of a conductor with complex index ``eta + i k``.

    ``cos_theta`` (> 0) is the cosine of incidence (one per lane), ``eta`` and
    ``k`` one value per wavelength.  The Fresnel equations in their real form
    (Born & Wolf): with ``a² + b² = |η̃² - sin²θ|`` and ``a = Re sqrt(η̃² - sin²θ)``::

        R_s = (a² + b² - 2a cos θ + cos²θ) / (a² + b² + 2a cos θ + cos²θ)
        R_p = R_s (cos²θ (a² + b²) - 2a cos θ sin²θ + sin⁴θ) / (cos²θ (a² + b²) + 2a cos θ sin²θ + sin⁴θ)
    """
    cos_theta = dr.clip(cos_theta, 1e-6, 1.0)
    cos2 = cos_theta * cos_theta
    sin2 = 1.0 - cos2
    t0 = eta * eta - k * k - sin2
    a2b2 = dr.sqrt(dr.fma(t0, t0, 4.0 * dr.square(eta * k)))
    a = dr.sqrt(dr.maximum(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + cos2
    t2 = 2.0 * a * cos_theta
    t3 = dr.fma(cos2, a2b2, sin2 * sin2)
    t4 = t2 * sin2
    # ½ (R_s + R_p) = ½ R_s (1 + (t3 - t4)/(t3 + t4)) = R_s t3 / (t3 + t4): one division for both
    return (t1 - t2) * t3 / ((t1 + t2) * (t3 + t4))


@dataclass
class ConductorSpectra:
    """η and k of two ``regular`` spectra on one wavelength grid, as one table: per grid interval the four
    values ``(η_i, k_i, η_i+1, k_i+1)`` that a linear interpolation reads, fetched by one 4-wide gather per
    wavelength.  Returns what ``texture.eval`` returns (0 outside the grid, as Mitsuba's ``regular``).

    The table is made of the textures' own arrays by Dr.Jit gathers (:meth:`of`), so gradients with respect
    to their values still reach them; :meth:`matches` says whether two textures can be read this way.  (A
    dataclass: Dr.Jit finds the table in it when it records a frozen render.)"""

    table: object  #: mi.Float, 4 per grid interval
    lo_nm: float  #: the grid's first wavelength
    per_nm: float  #: grid intervals per nanometre
    nodes: int  #: grid wavelengths

    @classmethod
    def of(cls, eta, k) -> "ConductorSpectra":
        """The table of two ``regular`` textures for which :meth:`matches` holds."""
        import mitsuba as mi

        eta_values, k_values = (mi.traverse(t)["values"] for t in (eta, k))
        lo_nm, hi_nm = _grid_range(eta)
        nodes = dr.width(eta_values)
        # entry i: interval i // 4, its left (η, k) then its right one; (Dr.Jit indices, not numpy's memory:
        # a mapped buffer's alignment would change the kernel, fresnel._regular)
        entry = dr.arange(mi.UInt32, 4 * (nodes - 1))
        node = (entry >> 2) + ((entry >> 1) & 1)
        is_eta = (entry & 1) == 0
        table = dr.select(is_eta, dr.gather(mi.Float, eta_values, node), dr.gather(mi.Float, k_values, node))
        dr.make_opaque(table)
        return cls(table, lo_nm, (nodes - 1) / (hi_nm - lo_nm), nodes)

    @staticmethod
    def matches(eta, k) -> bool:
        """Whether ``eta`` and ``k`` are ``regular`` spectra on the same grid (a named material's are)."""
        import mitsuba as mi

        try:
            a, b = mi.traverse(eta), mi.traverse(k)
            return ("values" in a and "values" in b and "range" in a.keys() and dr.width(a["values"]) >= 2
                    and dr.width(a["values"]) == dr.width(b["values"]) and _grid_range(eta) == _grid_range(k))
        except Exception:  # not a texture Mitsuba can traverse this way
            return False

    def eval(self, wavelengths, active=True):
        """``(η, k)`` per wavelength (nm) as ``mi.Spectrum`` pairs."""
        import mitsuba as mi

        etas, ks = [], []
        for channel in range(dr.size_v(mi.Spectrum)):
            x = (wavelengths[channel] - self.lo_nm) * self.per_nm
            inside = mi.Bool(active) & (x >= 0.0) & (x <= self.nodes - 1)
            node = dr.clip(mi.UInt32(x), 0, self.nodes - 2)
            w = x - mi.Float(node)
            v = dr.gather(mi.Vector4f, self.table, node, inside)  # (a packet gather: 6 % faster than four)
            etas.append(dr.fma(w, v.z - v.x, v.x))
            ks.append(dr.fma(w, v.w - v.y, v.y))
        return mi.Spectrum(*etas), mi.Spectrum(*ks)


def _grid_range(texture) -> tuple:
    import numpy as np
    import mitsuba as mi

    lo, hi = (float(x) for x in np.asarray(mi.traverse(texture)["range"]).ravel()[:2])
    return lo, hi


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
    # (parallel=False: the plugin's constructor runs on a worker of Mitsuba's own parallel scene loader,
    # whose pool a nested parallel load would schedule on again; one node needs no parallelism)
    return tuple(_regular(mi.load_dict({"type": "spectrum", "filename": p}, parallel=False)) for p in paths)


def _wavelength_grid_nm(texture):
    """Every whole nanometre (float32) within the wavelengths ``texture`` tabulates."""
    import mitsuba as mi
    import numpy as np

    nodes = np.asarray(mi.traverse(texture)["wavelengths"], dtype=np.float64)
    return np.arange(np.ceil(nodes.min()), np.floor(nodes.max()) + 0.5, 1.0).astype(np.float32)


def _regular(texture):
    """The irregular spectrum ``texture`` resampled every nanometre over its own range."""
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    from .tables.references import aligned_array

    grid = _wavelength_grid_nm(texture)
    si = dr.zeros(mi.SurfaceInteraction3f, len(grid))
    # aligned: Dr.Jit maps numpy's memory, and its alignment would pick another
    # kernel (a kernel-cache miss) wherever malloc happened to put the grid
    si.wavelengths = mi.Spectrum(aligned_array(mi.Float, grid))
    values = np.asarray(texture.eval(si))[0]
    return mi.load_dict({"type": "regular", "wavelength_min": float(grid[0]), "wavelength_max": float(grid[-1]),
                         "values": ", ".join(f"{v:.9g}" for v in values)}, parallel=False)
