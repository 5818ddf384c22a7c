"""The footprint filter's size for a render: each sample's share of its pixel (docs/model.md §11.2).

A render of ``spp`` samples per pixel divides every pixel among its samples: a sample stands for a
patch about ``pixel/√spp`` wide, so each scratched BSDF averages itself over a Gaussian of standard
deviation ``FOOTPRINT_SCALE × pixel/√spp`` around the sample's hit point (docs/model.md §11.2).
As the samples grow, the footprint shrinks and the image converges to the point-sampled one; the
size depends only on the render's camera, film and **total** samples per pixel, never on a chunk's,
so a render split into chunks or parts averages exactly as one render does.

``spp_total`` sets the scratch BSDFs' ``footprint_angle`` (perspective cameras: radians per sample at
unit distance, the BSDF multiplies by the hit distance) and ``footprint_width`` (orthographic:
scene units per sample) through ``mi.traverse``: opaque values, no kernel compiled again.
"""
from __future__ import annotations

import math

from ..bsdf.parameters import FOOTPRINT_SCALE, sample_footprint

__all__ = ["pixel_size", "set_footprint", "footprint_keys", "footprint_values", "FOOTPRINT_SCALE"]

_ANGLE, _WIDTH = "footprint_angle", "footprint_width"


def pixel_size(scene) -> tuple[float, float]:
    """``(radians, scene units)`` one pixel of the scene's sensor spans (one of them 0): its field of
    view over the film's width for a perspective camera, its width over the film's for an orthographic one."""
    import mitsuba as mi
    import numpy as np

    sensor = scene.sensors()[0]
    width = max(int(sensor.film().size()[0]), 1)
    params = mi.traverse(sensor)
    if "x_fov" in params:
        return 2.0 * math.tan(math.radians(float(np.asarray(params["x_fov"]).ravel()[0])) / 2.0) / width, 0.0
    matrix = np.asarray(params["to_world"].matrix if "to_world" in params else sensor.world_transform().matrix)
    matrix = matrix.reshape(4, 4) if matrix.size == 16 else matrix[..., 0].reshape(4, 4)
    half_width = float(np.linalg.norm(matrix[:3, 0]))  # the orthographic sensor sees [-1, 1] of its frame
    return 0.0, 2.0 * half_width / width


def footprint_keys(params) -> list[str]:
    """The ``footprint_angle`` keys of a scene's parameters (one per scratch BSDF)."""
    return [key for key in params.keys() if key.endswith("." + _ANGLE) or key == _ANGLE]


def footprint_values(keys, pixel: tuple[float, float], spp_total: float, *, scale: float = 1.0) -> dict:
    """The parameters that size the footprints of ``keys``' BSDFs for a render of ``spp_total`` samples per pixel
    of ``pixel`` (:func:`pixel_size`); ``scale``: pixels that many times larger (a preview's)."""
    import mitsuba as mi

    angle, width = sample_footprint(pixel[0] * scale, pixel[1] * scale, spp_total)
    values = {}
    for key in keys:
        values[key] = mi.Float(angle)
        values[key[:-len(_ANGLE)] + _WIDTH] = mi.Float(width)
    return values


def set_footprint(scene, spp_total: float, *, scale: float = 1.0) -> int:
    """Size every scratch BSDF's footprint for a render of ``spp_total`` samples per pixel (``scale``: a pixel
    ``scale`` times larger, a preview's); returns how many BSDFs were set."""
    import drjit as dr
    import mitsuba as mi

    params = mi.traverse(scene)
    keys = footprint_keys(params)
    if keys:
        for key, value in footprint_values(keys, pixel_size(scene), spp_total, scale=scale).items():
            dr.make_opaque(value)
            params[key] = value
        params.update()
    return len(keys)
