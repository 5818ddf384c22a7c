"""A Mitsuba scene dict written as Mitsuba 3 scene XML (for export folders).

Only what the builder emits with file-backed resources is supported: plugin
dicts, ``rgb`` spectra, references, transforms, points/vectors and scalars.
In-memory objects (``mi.Mesh``, ``mi.Bitmap``, Dr.Jit arrays) cannot be written
and raise ``TypeError``.
"""
from __future__ import annotations

import numbers
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

__all__ = ["dict_to_xml", "write_xml", "PLUGIN_TAGS"]

#: Plugin type → XML element.
PLUGIN_TAGS = {
    "scene": "scene",
    **dict.fromkeys(("path", "direct", "volpath", "aov", "blender_passes"), "integrator"),
    **dict.fromkeys(("perspective", "orthographic", "thinlens"), "sensor"),
    "hdrfilm": "film", "specfilm": "film",
    **dict.fromkeys(("box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos"), "rfilter"),
    **dict.fromkeys(("independent", "stratified", "multijitter", "ldsampler"), "sampler"),
    **dict.fromkeys(("ply", "obj", "serialized", "rectangle", "disk", "sphere", "cube", "cylinder", "shapegroup",
                     "instance"), "shape"),
    **dict.fromkeys(("diffuse", "principled", "principledthin", "conductor", "roughconductor", "plastic",
                     "roughplastic", "dielectric", "roughdielectric", "thindielectric", "twosided", "blendbsdf", "mask",
                     "null", "normalmap", "bumpmap", "translucent",
                     "scratch_diffraction"), "bsdf"),
    **dict.fromkeys(("area", "point", "spot", "directional", "constant", "envmap", "sunsky"), "emitter"),
    **dict.fromkeys(("bitmap", "checkerboard", "generated"), "texture"),
    "homogeneous": "medium",
    **dict.fromkeys(("hg", "isotropic"), "phase"),
}

_POINTS = {"position", "center", "origin", "target"}
_VECTORS = {"direction", "sun_direction", "up"}


def _number(value) -> str:
    return repr(float(value))


def _element(tag: str, attributes: dict, children: list[str], indent: str) -> list[str]:
    attrs = "".join(f" {key}={quoteattr(str(value))}" for key, value in attributes.items())
    if not children:
        return [f"{indent}<{tag}{attrs}/>"]
    return [f"{indent}<{tag}{attrs}>", *children, f"{indent}</{tag}>"]


def _property(name: str, value, indent: str) -> list[str]:
    if isinstance(value, dict):
        kind = value.get("type")
        if kind == "rgb":
            rgb = np.broadcast_to(np.asarray(value["value"], dtype=float), (3,))
            return [f"{indent}<rgb name={quoteattr(name)} value=\"{', '.join(_number(c) for c in rgb)}\"/>"]
        if kind == "spectrum" and isinstance(value.get("value"), (int, float)):
            return [f"{indent}<spectrum name={quoteattr(name)} value=\"{_number(value['value'])}\"/>"]
        if kind == "ref":
            return [f"{indent}<ref id={quoteattr(value['id'])} name={quoteattr(name)}/>"]
        return _plugin(value, indent, name=name)
    if isinstance(value, bool) or isinstance(value, np.bool_):
        return [f"{indent}<boolean name={quoteattr(name)} value=\"{'true' if value else 'false'}\"/>"]
    if isinstance(value, numbers.Integral):
        return [f"{indent}<integer name={quoteattr(name)} value=\"{int(value)}\"/>"]
    if isinstance(value, numbers.Real):
        return [f"{indent}<float name={quoteattr(name)} value=\"{_number(value)}\"/>"]
    if isinstance(value, (str, Path)):
        return [f"{indent}<string name={quoteattr(name)} value={quoteattr(str(value))}/>"]
    if hasattr(value, "matrix") and "Transform" in type(value).__name__:
        matrix = np.asarray(value.matrix, dtype=float).ravel()
        return [f"{indent}<transform name={quoteattr(name)}>",
                f"{indent}    <matrix value=\"{' '.join(_number(c) for c in matrix)}\"/>",
                f"{indent}</transform>"]
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 3 and (name in _POINTS or name in _VECTORS):
        tag = "point" if name in _POINTS else "vector"
        x, y, z = (_number(c) for c in value)
        return [f"{indent}<{tag} name={quoteattr(name)} x=\"{x}\" y=\"{y}\" z=\"{z}\"/>"]
    raise TypeError(f"cannot write property {name!r} of type {type(value).__name__} to XML")


def _plugin(plugin: dict, indent: str, *, name: str | None = None, id: str | None = None) -> list[str]:
    kind = plugin["type"]
    tag = PLUGIN_TAGS.get(kind)
    if tag is None:
        raise TypeError(f"plugin type {kind!r} has no known XML element")
    attributes = {"type": kind}
    if id is not None:
        attributes["id"] = id
    if name is not None:
        attributes["name"] = name
    children = []
    for key, value in plugin.items():
        if key == "type":
            continue
        children += _property(key, value, indent + "    ")
    return _element(tag, attributes, children, indent)


def dict_to_xml(scene: dict) -> str:
    """The XML text of a scene dict (top-level entries keep their keys as ids)."""
    if scene.get("type") != "scene":
        raise ValueError("expected a dict of type 'scene'")
    lines = ['<?xml version="1.0" encoding="utf-8"?>', '<scene version="3.0.0">']
    for key, value in scene.items():
        if key == "type":
            continue
        if not isinstance(value, dict):
            lines += _property(key, value, "    ")
        else:
            lines += _plugin(value, "    ", id=key)
    lines.append("</scene>")
    return "\n".join(lines) + "\n"


def write_xml(scene: dict, path) -> Path:
    path = Path(path)
    path.write_text(dict_to_xml(scene), encoding="utf-8")
    return path
