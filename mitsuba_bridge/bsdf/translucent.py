"""``translucent``: Lambertian transmission, the counterpart of Blender's Translucent BSDF.

Mitsuba 3 has no diffuse transmitter among its plugins, so this small Python
BSDF provides one.

.. list-table::
   :header-rows: 1

   * - parameter
     - type
     - meaning
   * - ``transmittance``
     - spectrum or texture
     - fraction of the light sent to the other side (default 0.5)

Light arriving on either side leaves on the *other* side with a cosine
distribution, ``f(ωi, ωo) = T / π`` when ``cos θi · cos θo < 0``, else 0: the
albedo is ``T`` and nothing is reflected. Example::

    {"type": "translucent", "transmittance": {"type": "rgb", "value": [0.8, 0.8, 0.8]}}
"""
from __future__ import annotations

__all__ = ["PLUGIN_NAME", "register", "plugin_class"]

PLUGIN_NAME = "translucent"
_CLASSES: dict = {}


def plugin_class():
    """The ``mi.BSDF`` subclass for the active variant (built once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _CLASSES:
        return _CLASSES[variant]

    class Translucent(mi.BSDF):
        def __init__(self, props):
            super().__init__(props)
            if "transmittance" in props:
                self.m_transmittance = props.get_texture("transmittance")  # numbers, colours and textures
            else:
                # (serial: this runs on a worker of the parallel scene loader, as fresnel.material_textures)
                self.m_transmittance = mi.load_dict({"type": "uniform", "value": 0.5}, parallel=False)
            flags = mi.BSDFFlags.DiffuseTransmission | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
            self.m_components = [flags]
            self.m_flags = flags

        def _opposite(self, si, wo):
            return mi.Frame3f.cos_theta(si.wi) * mi.Frame3f.cos_theta(wo) < 0

        def sample(self, ctx, si, sample1, sample2, active=True):
            cos_i = mi.Frame3f.cos_theta(si.wi)
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            wo = mi.Vector3f(wo.x, wo.y, dr.select(cos_i > 0, -wo.z, wo.z))  # leave through the other side
            active = (mi.Mask(active) & (cos_i != 0)
                      & ctx.is_enabled(mi.BSDFFlags.DiffuseTransmission, 0))
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = dr.select(active, dr.abs(wo.z) * dr.inv_pi, 0.0)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseTransmission)
            bs.sampled_component = mi.UInt32(0)
            weight = self.m_transmittance.eval(si, active)  # f · |cos θo| / pdf = T
            return bs, dr.select(active & (bs.pdf > 0), weight, 0.0)

        def eval(self, ctx, si, wo, active=True):
            active = (mi.Mask(active) & self._opposite(si, wo)
                      & ctx.is_enabled(mi.BSDFFlags.DiffuseTransmission, 0))
            value = self.m_transmittance.eval(si, active) * (dr.inv_pi * dr.abs(mi.Frame3f.cos_theta(wo)))
            return dr.select(active, value, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            active = (mi.Mask(active) & self._opposite(si, wo)
                      & ctx.is_enabled(mi.BSDFFlags.DiffuseTransmission, 0))
            return dr.select(active, dr.abs(mi.Frame3f.cos_theta(wo)) * dr.inv_pi, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def traverse(self, callback):
            callback.put("transmittance", self.m_transmittance, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys=()):
            pass

        def to_string(self):
            return f"Translucent[transmittance={self.m_transmittance}]"

    _CLASSES[variant] = Translucent
    return Translucent


def register() -> None:
    """Register ``translucent`` for the active Mitsuba variant (idempotent)."""
    import mitsuba as mi

    cls = plugin_class()
    mi.register_bsdf(PLUGIN_NAME, lambda props: cls(props))
