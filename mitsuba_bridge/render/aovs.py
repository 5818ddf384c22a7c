"""Blender's data passes: Depth, Denoising Albedo and Denoising Normal, as Cycles writes them.

The compositor's Denoise node (Intel Open Image Denoise) takes the noisy image with an albedo and a
normal pass; Cycles writes them when *Denoising Data* is on, and the Depth pass when *Z* is. This
module's ``blender_passes`` integrator wraps the scene's integrator (``path`` or ``volpath``) and
adds, per camera ray, the first surface it meets:

* **albedo**: a diffuse surface's reflectance (``eval_diffuse_reflectance``: a diffuse or Principled
  base colour) in linear Rec.709. A spectral render sees four random wavelengths per sample, which
  would make the pass as colour-noisy as the image (and Mitsuba's own ``aov`` integrator also leaves
  the D65 white point out: a (0.8, 0.3, 0.1) base came out (0.93, 0.29, 0.08)); here the reflectance
  is evaluated at 32 fixed wavelengths and integrated against the CIE 1931 curves under D65,
  normalised so that a white reflectance is exactly white: noise-free, and the colour the material
  was given. Surfaces without a diffuse part (metals, glass, the scratch BSDF) give 0: evaluating the
  scratch model eight times more per camera ray would cost more than the render. Where a pixel's
  rays miss, the host puts the world's colour seen there (the image's, clipped to [0, 1]; as noisy
  as the image), as Cycles' background albedo (evaluating a sky at 32 wavelengths for every camera
  ray cost as much again as the render);
* **normal**: the shading normal in Cycles' camera space (x right, y up, z *into* the view: Blender's
  camera frame with z negated), 0 where the ray misses;
* **depth**: the distance along the camera's axis, Blender's Z (not the ray's length), averaged over
  the samples of a pixel that hit something; 10¹⁰ where none did, as Cycles writes.

:func:`blender_passes` turns the rendered channels into Blender's passes. Example::

    {"type": "blender_passes", "integrator": {"type": "path"}, "camera_to_world": <4×4 Blender camera matrix>}
"""
from __future__ import annotations

import numpy as np

__all__ = ["PLUGIN_NAME", "CHANNELS", "BACKGROUND_DEPTH", "PASSES", "register", "blender_passes"]

PLUGIN_NAME = "blender_passes"
#: The AOV channels the integrator adds after the film's RGBA, in order.
CHANNELS = ("albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z", "depth.sum", "depth.hits")
#: Cycles' depth where a pixel sees no surface.
BACKGROUND_DEPTH = 1e10
#: Blender's pass name → (channels, chan_id, type) for ``RenderEngine.register_pass``.
PASSES = {"Depth": (1, "Z", "VALUE"), "Denoising Normal": (3, "XYZ", "VECTOR"),
          "Denoising Albedo": (3, "RGB", "COLOR")}
_CLASSES: dict = {}


_WAVELENGTHS = 32  # 8 evaluations of a 4-wavelength spectrum: well below 1 % error for smooth spectra
# Linear Rec.709 (sRGB primaries, D65 white) from CIE XYZ.
_XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                           [-0.9692660, 1.8760108, 0.0415560],
                           [0.0556434, -0.2040259, 1.0572252]])


def _quadrature():
    """(wavelengths (8, 4) nm, weights (8, 4, 3)): Rec.709 RGB of a reflectance ρ under D65 is
    Σ weights · ρ(wavelengths)."""
    import mitsuba as mi

    lo, hi = float(mi.MI_CIE_MIN), float(mi.MI_CIE_MAX)
    wavelengths = lo + (np.arange(_WAVELENGTHS) + 0.5) * (hi - lo) / _WAVELENGTHS
    curves = mi.cie1931_xyz(mi.Float(wavelengths))
    xyz = np.stack([np.array(curves[i], dtype=np.float64) for i in range(3)], axis=1)  # (N, 3)
    d65 = mi.load_dict({"type": "d65"})
    si = mi.SurfaceInteraction3f()
    illuminant = []
    for start in range(0, _WAVELENGTHS, 4):
        si.wavelengths = mi.Spectrum(*(float(w) for w in wavelengths[start:start + 4]))
        illuminant.append(np.array(d65.eval(si), dtype=np.float64).ravel())
    weights = (xyz * np.concatenate(illuminant)[:, None]) @ _XYZ_TO_REC709.T  # each wavelength's share of RGB
    weights /= weights.sum(axis=0)  # a white reflectance (ρ = 1) is exactly (1, 1, 1)
    return wavelengths.reshape(-1, 4), weights.reshape(-1, 4, 3)


def plugin_class():
    """The ``mi.SamplingIntegrator`` subclass for the active variant (built once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _CLASSES:
        return _CLASSES[variant]
    wavelengths, weights = _quadrature()

    class BlenderPasses(mi.SamplingIntegrator):
        def __init__(self, props):
            super().__init__(props)
            self.inner = props.get("integrator")
            if not isinstance(self.inner, mi.SamplingIntegrator):
                raise ValueError("blender_passes: a nested sampling integrator ('path', 'volpath') is required")
            frame = np.array(props.get("camera_to_world", mi.ScalarTransform4f()).matrix, dtype=np.float64)
            self.origin = mi.ScalarPoint3f(*frame[:3, 3])
            rotation = frame[:3, :3] / np.linalg.norm(frame[:3, :3], axis=0)
            # Cycles' camera space: Blender's camera x and y, and z towards what the camera sees (−z)
            self.axes = [mi.ScalarVector3f(*rotation[:, 0]), mi.ScalarVector3f(*rotation[:, 1]),
                         mi.ScalarVector3f(*-rotation[:, 2])]

        def aov_names(self):
            return list(self.inner.aov_names()) + list(CHANNELS)

        def sample(self, scene, sampler, ray, medium=None, active=True):
            result, valid, aovs = self.inner.sample(scene, sampler, ray, medium, active)
            active = mi.Mask(active)
            si = scene.ray_intersect(ray, active)
            hit = active & si.is_valid()
            bsdf = si.bsdf(ray)
            diffuse = hit & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Diffuse)
            albedo = [mi.Float(0.0), mi.Float(0.0), mi.Float(0.0)]
            fixed = mi.SurfaceInteraction3f(si)
            for group in range(len(wavelengths)):  # the quadrature: 8 lookups of 4 fixed wavelengths
                fixed.wavelengths = mi.Spectrum(*(float(w) for w in wavelengths[group]))
                reflectance = bsdf.eval_diffuse_reflectance(fixed, diffuse)
                for lane in range(4):
                    for channel in range(3):
                        albedo[channel] += float(weights[group, lane, channel]) * reflectance[lane]
            passes = [dr.select(diffuse, albedo[i], 0.0) for i in range(3)]
            passes += [dr.select(hit, dr.dot(si.sh_frame.n, axis), 0.0) for axis in self.axes]
            passes += [dr.select(hit, dr.dot(si.p - self.origin, self.axes[2]), 0.0), dr.select(hit, 1.0, 0.0)]
            return result, valid, list(aovs) + passes

        def traverse(self, callback):
            callback.put("integrator", self.inner, mi.ParamFlags.NonDifferentiable)

        def to_string(self):
            return f"BlenderPasses[integrator={self.inner}]"

    _CLASSES[variant] = BlenderPasses
    return BlenderPasses


def register() -> None:
    """Register ``blender_passes`` for the active variant (call after ``mi.set_variant``)."""
    import mitsuba as mi

    mi.register_integrator(PLUGIN_NAME, lambda props: plugin_class()(props))


def blender_passes(image: np.ndarray) -> dict[str, np.ndarray]:
    """Blender's passes of a render by ``blender_passes``: ``(H, W, 4 + len(CHANNELS))`` → name → (H, W, C).

    ``Combined`` is the RGBA image; ``Depth`` the hit-weighted mean depth (10¹⁰ where nothing was hit); the
    share of a pixel's rays that missed adds the world seen there (the image's colour, clipped to [0, 1])
    to its albedo, as Cycles' background albedo.
    """
    image = np.asarray(image)
    extra = image[..., 4:4 + len(CHANNELS)]
    hits = extra[..., 7:8]
    depth = np.where(hits > 0, extra[..., 6:7] / np.where(hits > 0, hits, 1.0), BACKGROUND_DEPTH)
    albedo = extra[..., 0:3] + (1.0 - hits) * np.clip(image[..., :3], 0.0, 1.0)
    return {"Combined": image[..., :4], "Denoising Albedo": albedo.astype(np.float32),
            "Denoising Normal": extra[..., 3:6], "Depth": depth.astype(np.float32)}
