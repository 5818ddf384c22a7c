"""Blender materials (shader node trees) → neutral materials.

Principled BSDF, Diffuse BSDF, Glossy BSDF and Emission map to their Mitsuba
counterparts, with Image Texture nodes on their colour and scalar inputs.
Anything else renders as diffuse grey with one warning per material; an input
driven by an unsupported node keeps its own value, with a warning.
"""
from __future__ import annotations

from ....mitsuba_bridge.scene import Diffuse, Emission, Glossy, Principled, Texture
from .report import Warnings
from .textures import gather_image

__all__ = ["gather_material", "DEFAULT_MATERIAL", "FALLBACK_MATERIAL", "SUPPORTED_SHADERS"]

#: What objects without a material render as (Blender's default surface).
DEFAULT_MATERIAL = Diffuse((0.8, 0.8, 0.8))
#: What unsupported shaders render as.
FALLBACK_MATERIAL = Diffuse((0.5, 0.5, 0.5))
SUPPORTED_SHADERS = {
    "ShaderNodeBsdfPrincipled": "Principled BSDF",
    "ShaderNodeBsdfDiffuse": "Diffuse BSDF",
    "ShaderNodeBsdfAnisotropic": "Glossy BSDF",
    "ShaderNodeEmission": "Emission",
}


def linked_node(socket):
    """The node feeding ``socket`` (through reroutes), or None if unlinked or muted."""
    for _ in range(64):  # reroute chains are short; a cycle must not hang the render
        links = [link for link in socket.links if link.is_valid and not link.is_muted]
        if not links:
            return None
        node = links[0].from_node
        if node.bl_idname != "NodeReroute":
            return None if node.mute else node
        socket = node.inputs[0]
    return None


def _default(socket, colour: bool):
    value = socket.default_value
    return tuple(float(c) for c in value[:3]) if colour else float(value)


def input_value(node, name: str, warnings: Warnings, owner: str, *, colour: bool):
    """The value of input ``name``: its own value, or an image texture plugged into it."""
    socket = node.inputs[name]
    source = linked_node(socket)
    if source is None:
        return _default(socket, colour)
    if source.bl_idname == "ShaderNodeTexImage":
        vector = linked_node(source.inputs["Vector"])
        if vector is not None and not (vector.bl_idname in ("ShaderNodeUVMap", "ShaderNodeTexCoord")):
            warnings.warn(f"{owner}: the texture coordinates of '{source.name}' come from '{vector.name}', "
                          "which is not supported: the active UV map is used")
        return gather_image(source, warnings, owner=owner)
    warnings.warn(f"{owner}: input '{name}' of '{node.name}' is driven by '{source.name}' ({source.bl_label}), "
                  "which is not supported: its own value is used", key=(owner, node.name, name))
    return _default(socket, colour)


def _scalar(node, name: str) -> float:
    return float(node.inputs[name].default_value)


def _warn_if_linked(node, names, warnings: Warnings, owner: str, what: str) -> None:
    for name in names:
        if name in node.inputs and linked_node(node.inputs[name]) is not None:
            warnings.warn(f"{owner}: {what} ('{name}' of '{node.name}') is not supported and is ignored")


def _principled(node, warnings: Warnings, owner: str):
    value = lambda name, colour=False: input_value(node, name, warnings, owner, colour=colour)  # noqa: E731
    _warn_if_linked(node, ("Normal", "Coat Normal", "Tangent"), warnings, owner, "normal and tangent mapping")
    if _scalar(node, "Alpha") < 1.0 or linked_node(node.inputs["Alpha"]) is not None:
        warnings.warn(f"{owner}: alpha (transparency) is not supported: rendered opaque")
    if _scalar(node, "Subsurface Weight") > 0:
        warnings.warn(f"{owner}: subsurface scattering is not supported and is ignored")
    bsdf = Principled(
        base_color=value("Base Color", True),
        metallic=value("Metallic"),
        roughness=value("Roughness"),
        ior=_scalar(node, "IOR"),
        anisotropic=_scalar(node, "Anisotropic"),
        transmission=_scalar(node, "Transmission Weight"),
        coat=_scalar(node, "Coat Weight"),
        coat_roughness=_scalar(node, "Coat Roughness"),
        sheen=_scalar(node, "Sheen Weight"),
    )
    emission = value("Emission Color", True)
    strength = _scalar(node, "Emission Strength")
    if isinstance(emission, Texture):
        warnings.warn(f"{owner}: textured emission is not supported: emission ignored")
    elif strength > 0 and any(c > 0 for c in emission):
        return Emission(radiance=tuple(c * strength for c in emission), bsdf=bsdf)
    return bsdf


def _glossy(node, warnings: Warnings, owner: str) -> Glossy:
    _warn_if_linked(node, ("Normal", "Tangent"), warnings, owner, "normal and tangent mapping")
    if _scalar(node, "Anisotropy") != 0:
        warnings.warn(f"{owner}: anisotropic glossy reflection is rendered isotropic")
    roughness = _scalar(node, "Roughness")
    if linked_node(node.inputs["Roughness"]) is not None:
        warnings.warn(f"{owner}: a textured glossy roughness is not supported: its own value is used")
    return Glossy(color=input_value(node, "Color", warnings, owner, colour=True), alpha=roughness * roughness)


def gather_material(material, warnings: Warnings):
    """The neutral material of a Blender material (``None``: the default surface)."""
    if material is None:
        return DEFAULT_MATERIAL
    owner = f"material '{material.name}'"
    tree = material.node_tree
    if tree is None:
        return Diffuse(tuple(float(c) for c in material.diffuse_color[:3]))
    output = tree.get_output_node("CYCLES")
    if output is None:
        warnings.warn(f"{owner} has no Material Output node: rendered as diffuse grey")
        return FALLBACK_MATERIAL
    shader = linked_node(output.inputs["Surface"])
    if shader is None:
        warnings.warn(f"{owner}: nothing is connected to the output's Surface: rendered black, as in Cycles")
        return Diffuse((0.0, 0.0, 0.0))
    kind = shader.bl_idname
    if kind == "ShaderNodeBsdfPrincipled":
        return _principled(shader, warnings, owner)
    if kind == "ShaderNodeBsdfDiffuse":
        _warn_if_linked(shader, ("Normal",), warnings, owner, "normal mapping")
        return Diffuse(input_value(shader, "Color", warnings, owner, colour=True))
    if kind == "ShaderNodeBsdfAnisotropic":
        return _glossy(shader, warnings, owner)
    if kind == "ShaderNodeEmission":
        colour = input_value(shader, "Color", warnings, owner, colour=True)
        if isinstance(colour, Texture):
            warnings.warn(f"{owner}: textured emission is not supported: rendered white")
            colour = (1.0, 1.0, 1.0)
        strength = _scalar(shader, "Strength")
        return Emission(radiance=tuple(c * strength for c in colour))
    warnings.warn(f"{owner}: shader '{shader.name}' ({shader.bl_label}) is not supported: rendered as diffuse "
                  f"grey (supported: {', '.join(SUPPORTED_SHADERS.values())})", key=("material", material.name))
    return FALLBACK_MATERIAL
