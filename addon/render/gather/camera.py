"""The active camera and the render resolution, border and film settings."""
from __future__ import annotations

import math

import numpy as np

from ....mitsuba_bridge.scene import Camera, Film
from .report import GatherError, Warnings

__all__ = ["gather_film", "gather_camera", "frame_size", "border_window"]


def frame_size(render) -> tuple[int, int]:
    """Full frame size in pixels: resolution × percentage, truncated as Blender does."""
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    return max(width, 1), max(height, 1)


def border_window(render, width: int, height: int):
    """The border region ``(x, y, w, h)`` in pixels from the *top-left*, or None.

    Blender truncates ``border_min/max × size`` to integers (its ``disprect``,
    origin bottom-left); the render result it hands to engines has exactly
    that size, with or without "Crop to Render Region".
    """
    if not render.use_border:
        return None
    x0, x1 = int(render.border_min_x * width), int(render.border_max_x * width)
    y0, y1 = int(render.border_min_y * height), int(render.border_max_y * height)
    if x1 - x0 < 1 or y1 - y0 < 1:
        raise GatherError("the render region (border) is empty: draw a larger region (Ctrl+B) or clear it "
                          "(Ctrl+Alt+B)")
    if (x0, y0, x1, y1) == (0, 0, width, height):
        return None
    return x0, height - y1, x1 - x0, y1 - y0


def gather_film(scene, filter_name: str) -> Film:
    render = scene.render
    width, height = frame_size(render)
    return Film(width=width, height=height, crop=border_window(render, width, height), filter=filter_name,
                transparent=bool(render.film_transparent))


def gather_camera(scene, camera_object, warnings: Warnings) -> Camera:
    """The camera of ``camera_object`` for the scene's frame.

    Blender fits the sensor to one image dimension (``sensor_fit``; AUTO takes
    the larger one with the sensor *width*) and expresses lens shift in units
    of that dimension; the description wants the horizontal field of view and
    shifts as fractions of the frame's own width and height.
    """
    if camera_object is None:
        raise GatherError(f"scene '{scene.name}' has no active camera: add one (Add > Camera) and make it "
                          "active (View > Cameras > Set Active Object as Camera)")
    if camera_object.type != "CAMERA":
        raise GatherError(f"the active camera '{camera_object.name}' is a {camera_object.type.lower()} object, "
                          "not a camera")
    data = camera_object.data
    render = scene.render
    width, height = frame_size(render)
    aspect_x, aspect_y = render.pixel_aspect_x, render.pixel_aspect_y
    if abs(aspect_x - aspect_y) > 1e-6:
        warnings.warn("pixel aspect ratios other than 1:1 are not supported: rendered with square pixels")
    frame_w, frame_h = float(width), float(height)
    fit = data.sensor_fit
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and frame_w >= frame_h)
    fitted = frame_w if horizontal else frame_h  # the dimension the sensor (and the shift) refers to
    sensor = data.sensor_height if fit == "VERTICAL" else data.sensor_width
    if data.dof.use_dof:
        warnings.warn(f"camera '{camera_object.name}': depth of field is not supported and is ignored")
    if render.use_motion_blur:
        warnings.warn("motion blur is not supported and is ignored")

    common = dict(
        to_world=np.array(camera_object.matrix_world),  # made orthonormal by Camera itself
        shift_x=data.shift_x * fitted / frame_w,
        shift_y=data.shift_y * fitted / frame_h,
        near=max(float(data.clip_start), 1e-6),
        far=max(float(data.clip_end), float(data.clip_start) * (1 + 1e-6) + 1e-6),
    )
    if data.type == "PERSP":
        tan_half = sensor / (2.0 * data.lens) * frame_w / fitted
        return Camera(projection="perspective", fov_x_deg=math.degrees(2.0 * math.atan(tan_half)), **common)
    if data.type == "ORTHO":
        return Camera(projection="orthographic", ortho_width=data.ortho_scale * frame_w / fitted, **common)
    raise GatherError(f"camera '{camera_object.name}': panoramic cameras are not supported; use a perspective "
                      "or orthographic camera")
