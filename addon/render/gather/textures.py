"""Image Texture and Environment Texture nodes → :class:`Texture`.

Images with a file on disk are passed by path (Mitsuba reads PNG, JPEG, EXR,
HDR...); packed, generated or edited-in-memory images by their pixels.  A
missing image becomes Blender's own "missing texture" magenta, with a warning.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

from ....mitsuba_bridge.scene import Texture
from .report import Warnings

__all__ = ["gather_image", "image_pixels", "brightest_pixel", "MISSING"]

MISSING = (1.0, 0.0, 1.0)  # what Blender renders for a missing image


def _missing(name: str) -> Texture:
    return Texture(name=f"missing:{name}", pixels=np.array([[MISSING]], dtype=np.float32), srgb=False)


def _is_srgb(image) -> bool:
    return image.colorspace_settings.name.lower().startswith("srgb")


def gather_image(node, warnings: Warnings, *, owner: str) -> Texture:
    """The texture of an image node (``owner`` names the material or world for warnings)."""
    image = node.image
    if image is None:
        warnings.warn(f"{owner}: image node '{node.name}' has no image: rendered magenta")
        return _missing(f"{owner}/{node.name}")
    interpolation = "nearest" if getattr(node, "interpolation", "Linear") == "Closest" else "bilinear"
    if image.source == "TILED":
        warnings.warn(f"{owner}: UDIM image '{image.name}' is not supported: only its first tile is used")
    path = bpy.path.abspath(image.filepath_raw, library=image.library) if image.filepath_raw else ""
    in_memory = image.packed_file is not None or image.source in ("GENERATED", "VIEWER") or image.is_dirty
    if not in_memory and image.source in ("FILE", "TILED", "SEQUENCE") and os.path.isfile(path):
        return Texture(name=image.name, path=os.path.normpath(path), srgb=_is_srgb(image),
                       interpolation=interpolation)
    width, height = image.size
    if width == 0 or height == 0:  # Blender found no file (size is read lazily from it)
        warnings.warn(f"{owner}: image '{image.name}' is missing ({path or 'no file'}): rendered magenta")
        return _missing(image.name)
    channels = image.channels
    pixels = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    # Blender stores rows bottom-up; textures here are top-down.
    pixels = pixels.reshape(height, width, channels)[::-1]
    if channels < 3:
        pixels = np.repeat(pixels[..., :1], 3, axis=2)
    # Float buffers hold linear values; byte buffers the encoded ones.
    return Texture(name=image.name, pixels=np.ascontiguousarray(pixels[..., :3]),
                   srgb=_is_srgb(image) and not image.is_float, interpolation=interpolation)



def image_pixels(node, *, alpha: bool = False) -> np.ndarray:
    """An image node's pixels as linear (H, W, 3) float32, row 0 at the top, for baking node operations.

    ``alpha``: the Alpha output (repeated in three channels; 1 where the image has none).
    Missing images give Blender's magenta (alpha 1).
    """
    image = node.image
    width, height = image.size if image is not None else (0, 0)
    if width == 0 or height == 0:
        return np.full((1, 1, 3), 1.0 if alpha else MISSING, dtype=np.float32)
    channels = image.channels
    pixels = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(height, width, channels)[::-1]
    if alpha:
        level = pixels[..., 3] if channels == 4 else np.ones((height, width), np.float32)
        return np.ascontiguousarray(np.repeat(level[..., None], 3, axis=2))
    colour = np.repeat(pixels[..., :1], 3, axis=2) if channels < 3 else pixels[..., :3]
    if _is_srgb(image) and not image.is_float:
        from ....mitsuba_bridge.scene.colour import srgb_to_linear

        colour = srgb_to_linear(colour)
    return np.ascontiguousarray(colour, dtype=np.float32)


def brightest_pixel(texture: Texture) -> np.ndarray:
    """The brightest linear value per channel of a gathered texture, (3,) (its image's pixels for a file)."""
    from ....mitsuba_bridge.scene.colour import srgb_to_linear

    if texture.pixels is not None:
        pixels = srgb_to_linear(texture.pixels) if texture.srgb else texture.pixels
        return np.asarray(pixels, dtype=np.float64)[..., :3].reshape(-1, 3).max(axis=0)
    image = bpy.data.images.get(texture.name)
    width, height = image.size if image is not None else (0, 0)
    if width == 0 or height == 0:
        return np.ones(3)  # unknown: assume white, as bright as a reflectance gets
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(-1, image.channels)
    colour = np.repeat(pixels[:, :1], 3, axis=1) if image.channels < 3 else pixels[:, :3]
    if _is_srgb(image) and not image.is_float:
        colour = srgb_to_linear(colour)
    return np.asarray(colour, dtype=np.float64).max(axis=0)
