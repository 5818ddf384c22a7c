"""Shader input sockets → neutral values (a number, an RGB triple or a texture).

What feeds an input is evaluated the way Cycles would, then handed over in a
form Mitsuba can take:

* constants (RGB, Value, and Math, Mix, Invert, Color Ramp nodes on constants) are
  folded into one number or colour;
* Image Texture outputs pass through as textures (the file itself when possible);
* Math, Mix, Invert and Color Ramp nodes applied to image textures are *baked*:
  evaluated per pixel with numpy into a new linear texture of the image's size;
* Checker Texture becomes Mitsuba's ``checkerboard`` in UV space, or Cycles' 3D checker in Generated
  coordinates (its default: nothing on the Vector input).

Textures keep the coordinates Cycles would use: the UV map, or the object's Generated texture space
(a checker with nothing on its Vector, any texture fed by Texture Coordinate › Generated).

Anything else (Noise, Voronoi, vector nodes...) keeps the input's own value,
with one warning naming the node.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ....mitsuba_bridge.scene import Checker, Texture
from .report import Warnings
from .textures import gather_image, image_pixels

__all__ = ["ValueReader", "linked_output", "LUMINANCE"]

#: Rec.709 luminance: how Cycles turns a colour into a number (Color → Float sockets).
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
_RAMP_SAMPLES = 1024  # Color Ramp lookup table size for baking (Blender's own table is 256 entries)


def linked_output(socket):
    """``(node, output socket)`` feeding ``socket`` through reroutes, or None (unlinked or muted)."""
    for _ in range(64):  # reroute chains are short; a cycle must not hang the render
        links = [link for link in socket.links if link.is_valid and not link.is_muted]
        if not links:
            return None
        node = links[0].from_node
        if node.bl_idname != "NodeReroute":
            return None if node.mute else (node, links[0].from_socket)
        socket = node.inputs[0]
    return None


class _Image:
    """An Image Texture's Color output: kept as the file until an operation needs its pixels."""

    def __init__(self, node, texture: Texture):
        self.node, self.texture = node, texture


class _Baked:
    """Pixels computed here: (H, W, 3) float32, linear, row 0 at the top, looked up at ``coordinates``."""

    def __init__(self, pixels: np.ndarray, interpolation: str, coordinates: str = "uv"):
        self.pixels, self.interpolation, self.coordinates = pixels, interpolation, coordinates


def _is_array(value) -> bool:
    return isinstance(value, (_Image, _Baked))


# ---- arithmetic on numbers, colours and pixel arrays alike -------------------------------------------

def _safe_divide(a, b):
    b = np.asarray(b, dtype=np.float64)
    return np.divide(a, b, out=np.zeros(np.broadcast(a, b).shape), where=b != 0)


def _safe_power(a, b):
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    valid = (a >= 0) | (b == np.round(b))  # Cycles' safe_powf: 0 for a negative base with a fraction
    with np.errstate(all="ignore"):
        return np.where(valid, np.power(a, b), 0.0)


MATH = {
    "ADD": lambda a, b, c: a + b,
    "SUBTRACT": lambda a, b, c: a - b,
    "MULTIPLY": lambda a, b, c: a * b,
    "DIVIDE": lambda a, b, c: _safe_divide(a, b),
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": lambda a, b, c: _safe_power(a, b),
    "SQRT": lambda a, b, c: np.sqrt(np.maximum(a, 0.0)),
    "ABSOLUTE": lambda a, b, c: np.abs(a),
    "EXPONENT": lambda a, b, c: np.exp(a),
    "MINIMUM": lambda a, b, c: np.minimum(a, b),
    "MAXIMUM": lambda a, b, c: np.maximum(a, b),
    "LESS_THAN": lambda a, b, c: (np.asarray(a) < b).astype(float),
    "GREATER_THAN": lambda a, b, c: (np.asarray(a) > b).astype(float),
    "SIGN": lambda a, b, c: np.sign(a),
    "ROUND": lambda a, b, c: np.floor(np.asarray(a) + 0.5),
    "FLOOR": lambda a, b, c: np.floor(a),
    "CEIL": lambda a, b, c: np.ceil(a),
    "FRACT": lambda a, b, c: np.asarray(a) - np.floor(a),
    "MODULO": lambda a, b, c: np.where(np.asarray(b) != 0, np.fmod(a, np.where(np.asarray(b) != 0, b, 1.0)), 0.0),
    "SINE": lambda a, b, c: np.sin(a),
    "COSINE": lambda a, b, c: np.cos(a),
}


def _lerp(a, b, t):
    return a + (b - a) * t


MIX_BLENDS = {
    "MIX": lambda a, b, t: _lerp(a, b, t),
    "MULTIPLY": lambda a, b, t: _lerp(a, a * b, t),
    "ADD": lambda a, b, t: a + b * t,
    "SUBTRACT": lambda a, b, t: a - b * t,
    "SCREEN": lambda a, b, t: 1.0 - (1.0 - t + t * (1.0 - b)) * (1.0 - a),
    "DIVIDE": lambda a, b, t: _lerp(a, np.where(np.asarray(b) != 0, _safe_divide(a, b), a), t),
    "DIFFERENCE": lambda a, b, t: _lerp(a, np.abs(a - b), t),
    "DARKEN": lambda a, b, t: _lerp(a, np.minimum(a, b), t),
    "LIGHTEN": lambda a, b, t: _lerp(a, np.maximum(a, b), t),
}


class ValueReader:
    """Evaluates the inputs of one material's nodes (``owner`` names it in warnings and texture names)."""

    def __init__(self, warnings: Warnings, owner: str):
        self.warnings, self.owner = warnings, owner

    # ---- public -------------------------------------------------------------------------------------

    def read(self, node, name: str, *, colour: bool):
        """The neutral value of input ``name`` of ``node``: a float, an RGB tuple, a Texture or a Checker."""
        return self.finish(self.evaluate(node.inputs[name], owner_node=node), colour=colour,
                           name=f"{self.owner}/{node.name}/{name}")

    def finish(self, value, *, colour: bool, name: str):
        """``value`` as something the neutral description holds."""
        if isinstance(value, _Image):
            return value.texture
        if isinstance(value, _Baked):
            return Texture(name=name, pixels=value.pixels, srgb=False, interpolation=value.interpolation,
                           coordinates=value.coordinates)
        if isinstance(value, Checker):
            return value if colour else _grey_checker(value)
        array = np.asarray(value, dtype=np.float64)
        if colour:
            return tuple(float(c) for c in np.broadcast_to(array, (3,)))
        return float(array @ LUMINANCE) if array.ndim else float(array)

    def evaluate(self, socket, owner_node=None):
        """The value reaching ``socket``: a number, an RGB array, an image, baked pixels or a Checker."""
        source = linked_output(socket)
        if source is None:
            return _socket_default(socket)
        node, output = source
        kind = node.bl_idname
        handler = _HANDLERS.get(kind)
        if handler is not None:
            result = handler(self, node, output)
            if result is not None:
                return result
        else:
            where = f"input '{socket.name}' of '{owner_node.name}'" if owner_node is not None else f"'{socket.name}'"
            self.warnings.warn(f"{self.owner}: {where} is driven by '{node.name}' ({node.bl_label}), which is "
                               "not supported: its own value is used",
                               key=(self.owner, getattr(owner_node, "name", ""), socket.identifier))
        return _socket_default(socket)

    def number(self, node, name: str):
        """Input ``name`` as a number or a single-channel pixel array (colours become luminance)."""
        return _as_float(self.evaluate(node.inputs[name], owner_node=node), self)

    def mean(self, node, name: str, *, colour: bool):
        """``(value, source)``: input ``name`` of ``node`` averaged over space, and the node that made it vary.

        A constant comes back as it is with ``source`` None. An image (or what is baked from one) gives the
        mean of its pixels, a checker the mean of its two colours, and Noise and Wave textures their mean
        level, 0.5; ``source`` is then that texture node, for a warning naming it. Where a uniform value is
        all a renderer takes (a homogeneous volume), this is the value that keeps the mean extinction.
        """
        socket = node.inputs[name]
        source = linked_output(socket)
        if source is not None and source[0].bl_idname in _HALF_MEAN:
            value = 0.5
        else:
            value = self.evaluate(socket, owner_node=node)
            if isinstance(value, Checker):
                value = (np.asarray(value.color1, dtype=np.float64) + np.asarray(value.color2, dtype=np.float64)) / 2
            elif _is_array(value):
                value = self._pixels(value).reshape(-1, 3).mean(axis=0)
            else:
                source = None  # a constant (folded): nothing varies
        return self.finish(value, colour=colour, name=""), (None if source is None else source[0])

    # ---- nodes --------------------------------------------------------------------------------------

    def coordinates(self, node, default: str) -> str:
        """``"uv"`` or ``"generated"``: where the texture ``node`` is looked up (``default`` with nothing on its
        Vector: UV for images, Generated for procedural textures, as in Cycles)."""
        vector = linked_output(node.inputs["Vector"])
        if vector is None:
            return default
        source, socket = vector
        if source.bl_idname == "ShaderNodeUVMap" or (source.bl_idname == "ShaderNodeTexCoord"
                                                     and socket.identifier == "UV"):
            return "uv"
        if source.bl_idname == "ShaderNodeTexCoord" and socket.identifier == "Generated":
            return "generated"
        what = f"'{socket.name}' of '{source.name}'" if source.bl_idname == "ShaderNodeTexCoord" else \
            f"'{source.name}' ({source.bl_label})"
        instead = {"uv": "the active UV map is used", "generated": "Generated coordinates are used"}[default]
        self.warnings.warn(f"{self.owner}: the texture coordinates of '{node.name}' come from {what}, which is not "
                           f"supported: {instead}")
        return default

    def _image(self, node, output):
        coordinates = self.coordinates(node, "uv")
        if output.identifier == "Alpha":
            return _Baked(image_pixels(node, alpha=True), _interpolation(node), coordinates)
        texture = gather_image(node, self.warnings, owner=self.owner)
        if getattr(node, "projection", "FLAT") != "FLAT" and coordinates == "generated":
            self.warnings.warn(f"{self.owner}: the {node.projection.lower()} projection of '{node.name}' is not "
                               "supported: Flat is used")
        return _Image(node, dataclasses.replace(texture, coordinates=coordinates))

    def _checker(self, node, output):
        coordinates = self.coordinates(node, "generated")
        colours = []
        for name in ("Color1", "Color2"):
            value = self.evaluate(node.inputs[name], owner_node=node)
            if _is_array(value) or isinstance(value, Checker):
                self.warnings.warn(f"{self.owner}: a textured '{name}' of Checker Texture '{node.name}' is not "
                                   "supported: its own value is used")
                value = _socket_default(node.inputs[name])
            colours.append(tuple(float(c) for c in np.broadcast_to(np.asarray(value, dtype=float), (3,))))
        scale = _as_float(self.evaluate(node.inputs["Scale"], owner_node=node), self)
        if _is_array(scale):
            self.warnings.warn(f"{self.owner}: a textured scale of '{node.name}' is not supported: 5 is used")
            scale = 5.0
        if output.identifier == "Fac":
            colours = [(1.0,) * 3, (0.0,) * 3]
        return Checker(colours[0], colours[1], float(scale), coordinates)

    def _ramp(self, node, output):
        factor = self.number(node, "Fac")
        ramp = node.color_ramp
        if isinstance(factor, Checker):
            return self._unbakeable(node)
        channel = 3 if output.identifier == "Alpha" else slice(0, 3)
        if not _is_array(factor):
            value = np.asarray(ramp.evaluate(float(factor)), dtype=np.float64)[channel]
            return value
        positions = np.linspace(0.0, 1.0, _RAMP_SAMPLES)
        table = np.array([ramp.evaluate(float(p)) for p in positions])[:, channel]
        levels = np.clip(factor.pixels[..., 0], 0.0, 1.0)
        if table.ndim == 1:
            pixels = np.repeat(np.interp(levels, positions, table)[..., None], 3, axis=2)
        else:
            pixels = np.stack([np.interp(levels, positions, table[:, c]) for c in range(3)], axis=-1)
        return _Baked(pixels.astype(np.float32), factor.interpolation)

    def _invert(self, node, output):
        factor = self.number(node, "Fac")
        colour = self.evaluate(node.inputs["Color"], owner_node=node)
        return self._combine(node, lambda t, c: _lerp(c, 1.0 - c, t), factor, colour)

    def _math(self, node, output):
        operation = MATH.get(node.operation)
        if operation is None:
            self.warnings.warn(f"{self.owner}: Math operation {node.operation} of '{node.name}' is not supported: "
                               "its first input is passed on")
            return self.number(node, 0)
        inputs = [_as_float(self.evaluate(socket, owner_node=node), self) for socket in list(node.inputs)[:3]]
        clamp = node.use_clamp
        return self._combine(node, lambda a, b, c: _clip(operation(a, b, c), clamp), *inputs)

    def _mix(self, node, output):
        if node.bl_idname == "ShaderNodeMixRGB":
            blend, clamp_factor, clamp_result = node.blend_type, True, node.use_clamp
            a_id, b_id, factor_id = "Color1", "Color2", "Fac"
        elif node.data_type in ("RGBA", "FLOAT"):
            blend = node.blend_type if node.data_type == "RGBA" else "MIX"
            clamp_factor, clamp_result = node.clamp_factor, node.clamp_result and node.data_type == "RGBA"
            suffix = "Color" if node.data_type == "RGBA" else "Float"
            a_id, b_id, factor_id = f"A_{suffix}", f"B_{suffix}", "Factor_Float"
        else:
            return self._unbakeable(node)
        operation = MIX_BLENDS.get(blend)
        if operation is None:
            self.warnings.warn(f"{self.owner}: blend mode {blend} of '{node.name}' is not supported: mixed instead")
            operation = MIX_BLENDS["MIX"]
        sockets = {socket.identifier: socket for socket in node.inputs}
        factor = _as_float(self.evaluate(sockets[factor_id], owner_node=node), self)
        a = self.evaluate(sockets[a_id], owner_node=node)
        b = self.evaluate(sockets[b_id], owner_node=node)
        if node.bl_idname != "ShaderNodeMixRGB" and node.data_type == "FLOAT":
            a, b = _as_float(a, self), _as_float(b, self)
        return self._combine(node, lambda t, x, y: _clip(operation(x, y, _clip(t, clamp_factor)), clamp_result),
                             factor, a, b)

    def _constant(self, node, output):
        value = output.default_value
        return np.asarray(value[:3], dtype=np.float64) if hasattr(value, "__len__") else float(value)

    # ---- helpers ------------------------------------------------------------------------------------

    def _combine(self, node, operation, *values):
        """``operation`` applied to numbers, colours or pixel arrays (baked when any is an array)."""
        if any(isinstance(v, Checker) for v in values):
            return self._unbakeable(node)
        arrays = [v for v in values if _is_array(v)]
        if not arrays:
            return operation(*(np.asarray(v, dtype=np.float64) for v in values))
        pixels = [self._pixels(v) if _is_array(v) else np.asarray(v, dtype=np.float64) for v in values]
        shape = max((p.shape for p in pixels if p.ndim == 3), key=lambda s: s[0] * s[1])
        pixels = [_resized(p, shape) if p.ndim == 3 else p for p in pixels]
        interpolation = arrays[0].interpolation if isinstance(arrays[0], _Baked) else arrays[0].texture.interpolation
        coordinates = {_coordinates_of(array) for array in arrays}
        if len(coordinates) > 1:
            self.warnings.warn(f"{self.owner}: '{node.name}' combines textures laid out in UV and in Generated "
                               "coordinates: baked in the first one's")
        result = np.broadcast_to(operation(*pixels), shape)
        return _Baked(np.ascontiguousarray(result, dtype=np.float32), interpolation, _coordinates_of(arrays[0]))

    def _pixels(self, value) -> np.ndarray:
        if isinstance(value, _Baked):
            return value.pixels.astype(np.float64)
        return image_pixels(value.node).astype(np.float64)

    def _unbakeable(self, node):
        self.warnings.warn(f"{self.owner}: '{node.name}' ({node.bl_label}) cannot be applied to a procedural "
                           "texture here: its first input is passed on")
        return None


def _coordinates_of(array) -> str:
    return array.coordinates if isinstance(array, _Baked) else array.texture.coordinates


def _grey_checker(checker: Checker) -> Checker:
    return dataclasses.replace(checker, color1=_grey(checker.color1), color2=_grey(checker.color2))


def _grey(colour) -> tuple:
    level = float(np.asarray(colour) @ LUMINANCE)
    return (level,) * 3


def _clip(value, clamp: bool):
    return np.clip(value, 0.0, 1.0) if clamp else value


def _as_float(value, reader: ValueReader):
    """A number (or a single-level pixel array, repeated in 3 channels) from any value."""
    if isinstance(value, Checker):
        return _grey_checker(value)
    if _is_array(value):
        pixels = reader._pixels(value)
        level = pixels @ LUMINANCE
        interpolation = value.interpolation if isinstance(value, _Baked) else value.texture.interpolation
        return _Baked(np.repeat(level[..., None], 3, axis=2).astype(np.float32), interpolation,
                      _coordinates_of(value))
    array = np.asarray(value, dtype=np.float64)
    return float(array @ LUMINANCE) if array.ndim else float(array)


def _resized(pixels: np.ndarray, shape) -> np.ndarray:
    """Nearest-neighbour resampling to ``shape`` (images of different sizes combined per UV)."""
    if pixels.shape[:2] == tuple(shape[:2]):
        return pixels
    rows = (np.arange(shape[0]) + 0.5) * pixels.shape[0] // shape[0]
    cols = (np.arange(shape[1]) + 0.5) * pixels.shape[1] // shape[1]
    return pixels[rows.astype(int)][:, cols.astype(int)]


def _interpolation(node) -> str:
    return "nearest" if getattr(node, "interpolation", "Linear") == "Closest" else "bilinear"


def _socket_default(socket):
    if not hasattr(socket, "default_value"):
        return 0.0
    value = socket.default_value
    if hasattr(value, "__len__"):
        return np.asarray(value[:3], dtype=np.float64)
    return float(value)


#: Procedural textures whose outputs average 0.5 over space (Perlin noise and the wave's sine around 0.5).
_HALF_MEAN = ("ShaderNodeTexNoise", "ShaderNodeTexWave")

_HANDLERS = {
    "ShaderNodeTexImage": ValueReader._image,
    "ShaderNodeTexChecker": ValueReader._checker,
    "ShaderNodeValToRGB": ValueReader._ramp,
    "ShaderNodeInvert": ValueReader._invert,
    "ShaderNodeMath": ValueReader._math,
    "ShaderNodeMix": ValueReader._mix,
    "ShaderNodeMixRGB": ValueReader._mix,
    "ShaderNodeRGB": ValueReader._constant,
    "ShaderNodeValue": ValueReader._constant,
}
