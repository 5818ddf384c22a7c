"""Camera, film, sampler and integrator dicts."""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..bsdf.parameters import sample_footprint
from ..scene import Camera, Film, RenderSettings
from .transform import FLIP_XZ, scale, to_mitsuba, translate

__all__ = ["sensor_dict", "integrator_dict", "film_dict", "window_camera", "with_data_passes", "footprint_settings"]


def film_dict(film: Film) -> dict:
    """An RGBA ``hdrfilm`` with the crop window and reconstruction filter of ``film``."""
    result = {
        "type": "hdrfilm",
        "width": film.width,
        "height": film.height,
        "pixel_format": "rgba",
        "component_format": "float32",
        "rfilter": {"type": film.filter},
    }
    if film.crop is not None:
        x, y, w, h = film.crop
        result.update(crop_offset_x=x, crop_offset_y=y, crop_width=w, crop_height=h)
    return result


def sensor_dict(camera: Camera, film: Film, settings: RenderSettings, *, medium=None) -> dict:
    """A ``perspective`` or ``orthographic`` sensor matching ``camera`` on ``film``.

    Mitsuba's camera frame looks along +Z with +X to the *left*; Blender's along
    −Z with +X to the right: a rotation by 180° about Y maps one onto the other.
    ``medium``: the world's volume, in which the camera's rays start (a medium dict or object).
    """
    aspect_hw = film.height / film.width
    if camera.projection == "perspective":
        sensor = {
            "type": "perspective",
            "fov": float(camera.fov_x_deg),
            "fov_axis": "x",
            # Mitsuba's offsets are fractions of the film size, positive moves the
            # image content left / up; a window shifted right / up moves it left / down.
            "principal_point_offset_x": float(camera.shift_x),
            "principal_point_offset_y": -float(camera.shift_y),
            "to_world": to_mitsuba(np.asarray(camera.to_world) @ FLIP_XZ),
        }
    else:
        # Mitsuba's orthographic sensor sees [-1, 1] horizontally (and ±height/width
        # vertically) of its local frame: scale by the half width; a lens shift
        # moves the camera within its own plane.
        half_width = 0.5 * camera.ortho_width
        shift = translate(camera.shift_x * camera.ortho_width,
                          camera.shift_y * camera.ortho_width * aspect_hw, 0.0)
        sensor = {
            "type": "orthographic",
            "to_world": to_mitsuba(np.asarray(camera.to_world) @ shift @ FLIP_XZ
                                   @ scale(half_width, half_width, 1.0)),
        }
    sensor.update(
        near_clip=float(camera.near),
        far_clip=float(camera.far),
        film=film_dict(film),
        sampler={"type": settings.sampler, "sample_count": int(settings.spp), "seed": int(settings.seed)},
    )
    if medium is not None:
        sensor["medium"] = medium
    return sensor


def footprint_settings(camera: Camera, film: Film, settings: RenderSettings) -> dict:
    """The scratch BSDFs' footprint filter for a render of ``settings.spp`` through ``camera`` onto ``film``
    (docs/model.md §11.2): ``plugin_dict`` keywords, empty when the filter is off.  The renderer sets the
    footprint again for the samples it actually renders (:func:`...render.filtering.set_footprint`); these
    values make an exported scene.xml render alike in plain Mitsuba."""
    if not settings.footprint_filter:
        return {}
    if camera.projection == "perspective":
        pixel = (2.0 * math.tan(math.radians(camera.fov_x_deg) / 2.0) / film.width, 0.0)
    else:
        pixel = (0.0, camera.ortho_width / film.width)
    angle, width = sample_footprint(*pixel, settings.spp)
    return {"footprint_filter": True, "footprint_angle": angle, "footprint_width": width}


def window_camera(camera: Camera, film: Film, window: tuple[int, int, int, int]) -> tuple[Camera, Film]:
    """The camera and film that see exactly the pixels ``window`` = (x, y, w, h) of ``film``'s frame.

    The window is in pixels of the whole frame (``film.width`` × ``film.height``, origin at the
    top-left corner, like a crop window) and may reach past its edges. The returned film is
    ``w`` × ``h`` without a crop window: its pixel (i, j) sees what pixel (x + i, y + j) of the
    frame sees, for either projection (the window's share of the field of view or of the
    orthographic width, and a lens shift that centres it). The interactive session renders a
    frame in strips this way: every strip is the same small film, hence the same kernel.
    """
    x, y, w, h = window
    if w < 1 or h < 1:
        raise ValueError(f"window size must be positive, got {w} x {h}")
    width, height = film.width, film.height
    # The window's centre, in pixels right of / above the frame's centre.
    right = x + 0.5 * w - 0.5 * width
    up = 0.5 * height - (y + 0.5 * h)
    shift_x = (camera.shift_x * width + right) / w
    shift_y = (camera.shift_y * height + up) / h
    if camera.projection == "perspective":
        half_tan = math.tan(math.radians(camera.fov_x_deg) / 2.0) * w / width
        window = dataclasses.replace(camera, fov_x_deg=math.degrees(2.0 * math.atan(half_tan)),
                                     shift_x=shift_x, shift_y=shift_y)
    else:
        window = dataclasses.replace(camera, ortho_width=camera.ortho_width * w / width,
                                     shift_x=shift_x, shift_y=shift_y)
    return window, Film(w, h, filter=film.filter, transparent=film.transparent)


def integrator_dict(settings: RenderSettings, film: Film, *, see_through_surfaces: bool = False) -> dict:
    """A path tracer; a transparent film hides directly seen emitters, as Blender's does.

    With ``see_through_surfaces`` (alpha, Transparent BSDF) it is ``volpath``, whose shadow
    rays pass through ``mask`` surfaces as Cycles' do; ``path`` would make them cast full shadows.
    """
    return {"type": "volpath" if see_through_surfaces else "path", "max_depth": int(settings.max_depth),
            "hide_emitters": bool(film.transparent)}


def with_data_passes(integrator: dict, camera: Camera) -> dict:
    """``integrator`` wrapped so that it also renders Blender's data passes (``render.aovs``: Depth along
    ``camera``'s axis, Denoising Albedo and Normal in Cycles' conventions)."""
    return {"type": "blender_passes", "integrator": integrator, "camera_to_world": to_mitsuba(camera.to_world)}
