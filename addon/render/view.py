"""The 3D view's camera as a neutral :class:`~mitsuba_bridge.scene.Camera` (numpy only, no bpy).

The viewport's matrices say everything, in perspective, orthographic and
camera view alike (camera view with its zoom and offset is just another
off-centre window): ``view_matrix`` maps world to view space (looking along
−Z, +Y up, Blender's camera frame) and ``window_matrix`` is an OpenGL
projection.  For a frustum with window [l, r] × [b, t] on the near plane n:

* perspective: ``P[0,0] = 2n/(r-l)``, ``P[0,2] = (r+l)/(r-l)``, ``P[2,2] = -(f+n)/(f-n)``, ``P[2,3] = -2fn/(f-n)``;
* orthographic: ``P[0,0] = 2/(r-l)``, ``P[0,3] = -(r+l)/(r-l)``, ``P[2,2] = -2/(f-n)``, ``P[2,3] = -(f+n)/(f-n)``.

The description's shifts are fractions of the frame's width and height, so the
window's centre ``(r+l)/2`` over its width ``r-l`` is the horizontal shift.
"""
from __future__ import annotations

import math

import numpy as np

from ...mitsuba_bridge.scene import Camera

__all__ = ["view_camera", "border_crop"]


def view_camera(view_matrix, window_matrix, is_perspective: bool) -> Camera:
    """The camera of a 3D view region (``region_data.view_matrix``, ``window_matrix``, ``is_perspective``)."""
    view = np.asarray(view_matrix, dtype=np.float64)
    projection = np.asarray(window_matrix, dtype=np.float64)
    to_world = np.linalg.inv(view)
    if is_perspective:
        p22, p23 = projection[2, 2], projection[2, 3]
        near, far = p23 / (p22 - 1.0), p23 / (p22 + 1.0)
        return Camera(to_world=to_world, projection="perspective",
                      fov_x_deg=math.degrees(2.0 * math.atan(1.0 / projection[0, 0])),
                      shift_x=0.5 * projection[0, 2], shift_y=0.5 * projection[1, 2],
                      near=max(near, 1e-6), far=max(far, near * (1 + 1e-6)))
    p22, p23 = projection[2, 2], projection[2, 3]
    near, far = (p23 + 1.0) / p22, (p23 - 1.0) / p22
    if near <= 0.0:
        # Blender's orthographic view clips from behind its origin; Mitsuba's starts at
        # a positive distance: move the camera back along its axis (+Z, it looks along −Z).
        back = -near + 1e-6 * (far - near)
        to_world = to_world @ _translate_z(back)
        near, far = near + back, far + back
    return Camera(to_world=to_world, projection="orthographic", ortho_width=2.0 / projection[0, 0],
                  shift_x=-0.5 * projection[0, 3], shift_y=-0.5 * projection[1, 3], near=near, far=far)


def border_crop(frame_corners, view_matrix, window_matrix, border, region_size) -> tuple[int, int, int, int]:
    """The render border of a camera view as a film crop ``(x, y, w, h)`` (pixels, origin top-left).

    Parameters
    ----------
    frame_corners : (4, 3)
        World-space corners of the camera's frame (``camera.data.view_frame`` through its matrix).
    view_matrix, window_matrix : 4 × 4
        The region's matrices (the frame lands where the region shows it, zoom and offset included).
    border : (min_x, min_y, max_x, max_y)
        Blender's ``render.border_*``: fractions of the camera frame, origin at its bottom-left.
    region_size : (width, height)

    The window is clipped to the region and is at least one pixel (a border outside the region).
    """
    width, height = region_size
    corners = np.c_[np.asarray(frame_corners, dtype=np.float64), np.ones(len(frame_corners))]
    clip = corners @ (np.asarray(window_matrix, dtype=np.float64) @ np.asarray(view_matrix, dtype=np.float64)).T
    pixels = (clip[:, :2] / clip[:, 3:] + 1.0) * 0.5 * np.array([width, height])  # y up, as Blender's regions
    low, high = pixels.min(axis=0), pixels.max(axis=0)
    border_low = low + np.array(border[:2], dtype=np.float64) * (high - low)
    border_high = low + np.array(border[2:], dtype=np.float64) * (high - low)
    x0, y0 = np.clip(np.round(border_low), 0, [width - 1, height - 1]).astype(int)
    x1, y1 = np.clip(np.round(border_high), [x0 + 1, y0 + 1], [width, height]).astype(int)
    return int(x0), int(height - y1), int(x1 - x0), int(y1 - y0)


def _translate_z(distance: float) -> np.ndarray:
    matrix = np.eye(4)
    matrix[2, 3] = distance
    return matrix
