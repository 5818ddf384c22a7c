"""Blender materials (shader node trees) → neutral materials.

Shaders: Principled, Diffuse, Glossy, Glass, Refraction, Translucent,
Transparent and Emission BSDFs, combined by Mix and Add Shader nodes; Normal Map
and Bump nodes on a shader's Normal input; the Principled BSDF's alpha. Inputs
are read by :class:`~.values.ValueReader` (textures, constant folding, baking).
An unsupported shader renders as diffuse grey with one warning per material;
an input driven by an unsupported node keeps its own value, with a warning.

On a scratched object a node group named "Scratch BSDF" stands for the
``scratch_diffraction`` BSDF (docs/rendering.md, "Scratches in a material").
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ....mitsuba_bridge.scene import (Add, Bump, Checker, Dielectric, Diffuse, Emission, Glossy, Interface, Mask, Mix,
                                      NormalMap, Principled, Texture, Translucent, Transparent, Volumetric,
                                      walk_materials)
from ....mitsuba_bridge.scene.albedo import add_sum
from .report import Warnings
from .textures import brightest_pixel
from .values import ValueReader, linked_output
from .volumes import gather_volume

__all__ = ["gather_material", "linked_node", "DEFAULT_MATERIAL", "FALLBACK_MATERIAL", "SUPPORTED_SHADERS",
           "SCRATCH_GROUP"]

#: What objects without a material render as (Blender's default surface).
DEFAULT_MATERIAL = Diffuse((0.8, 0.8, 0.8))
#: What unsupported shaders render as.
FALLBACK_MATERIAL = Diffuse((0.5, 0.5, 0.5))
#: An unconnected shader socket: Cycles' empty closure, black.
BLACK = Diffuse((0.0, 0.0, 0.0))
#: Node groups whose name starts with this stand for the scratch BSDF on scratched objects.
SCRATCH_GROUP = "Scratch BSDF"
SUPPORTED_SHADERS = {
    "ShaderNodeBsdfPrincipled": "Principled BSDF",
    "ShaderNodeBsdfDiffuse": "Diffuse BSDF",
    "ShaderNodeBsdfAnisotropic": "Glossy BSDF",
    "ShaderNodeBsdfGlass": "Glass BSDF",
    "ShaderNodeBsdfRefraction": "Refraction BSDF",
    "ShaderNodeBsdfTranslucent": "Translucent BSDF",
    "ShaderNodeBsdfTransparent": "Transparent BSDF",
    "ShaderNodeEmission": "Emission",
    "ShaderNodeMixShader": "Mix Shader",
    "ShaderNodeAddShader": "Add Shader",
}


def linked_node(socket):
    """The node feeding ``socket`` (through reroutes), or None if unlinked or muted."""
    source = linked_output(socket)
    return None if source is None else source[0]


class _Shaders:
    """Gathers one material's shader tree."""

    def __init__(self, warnings: Warnings, owner: str, scratch, material_name: str):
        self.warnings, self.owner, self.scratch = warnings, owner, scratch
        self.values = ValueReader(warnings, owner)
        self.material_name = material_name
        self.used_scratch_group = False

    def value(self, node, name, colour=False):
        return self.values.read(node, name, colour=colour)

    def scalar(self, node, name: str, what: str) -> float:
        """A number input; a texture there is not supported by the plugin (its own value is used)."""
        value = self.value(node, name)
        if not isinstance(value, float):
            self.warnings.warn(f"{self.owner}: a textured {what} ('{name}' of '{node.name}') is not supported: "
                               "its own value is used")
            value = float(node.inputs[name].default_value)
        return value

    def warn_if_linked(self, node, names, what: str) -> None:
        for name in names:
            if name in node.inputs and linked_node(node.inputs[name]) is not None:
                self.warnings.warn(f"{self.owner}: {what} ('{name}' of '{node.name}') is not supported and is ignored")

    # ---- the tree -----------------------------------------------------------------------------------

    def shader(self, socket):
        """The material reaching a shader socket (an unconnected one is black, as in Cycles)."""
        node = linked_node(socket)
        if node is None:
            return BLACK
        kind = node.bl_idname
        if kind == "ShaderNodeMixShader":
            factor = self.value(node, "Fac")
            first, second = self.shader(node.inputs[1]), self.shader(node.inputs[2])
            if isinstance(factor, float):
                factor = min(max(factor, 0.0), 1.0)  # Cycles clamps the factor
                if factor == 0.0:
                    return first
                if factor == 1.0:
                    return second
            return Mix(factor, first, second)
        if kind == "ShaderNodeAddShader":
            added = Add(self.shader(node.inputs[0]), self.shader(node.inputs[1]))
            total = add_sum(added, brightest_pixel)
            if total > 1.0 + 1e-6:
                self.warnings.warn(f"{self.owner}: Add Shader '{node.name}' scatters up to {total:.2f}× the light "
                                   f"that arrives: both halves are rendered at {1 / total:.2f}× so that the surface "
                                   "creates no energy (Cycles renders the sum, brighter)",
                                   key=("add", self.material_name, node.name))
            return added
        if kind == "ShaderNodeEmission":
            colour = self.value(node, "Color", True)
            if not isinstance(colour, tuple):
                self.warnings.warn(f"{self.owner}: textured emission is not supported: rendered white")
                colour = (1.0, 1.0, 1.0)
            strength = self.scalar(node, "Strength", "emission strength")
            return Emission(radiance=tuple(c * strength for c in colour))
        if kind == "ShaderNodeGroup" and node.node_tree is not None and node.node_tree.name.startswith(SCRATCH_GROUP):
            if self.scratch is not None:
                self.used_scratch_group = True
                return self.scratch
            self.warnings.warn(f"{self.owner}: '{node.name}' stands for the scratch BSDF but the object carries no "
                               "scratches: rendered as a plain mirror-like metal", key=("scratch-group", self.owner))
            return Glossy((0.9, 0.9, 0.9), alpha=0.0)
        bsdf = self.bsdf(node)
        if bsdf is None:
            self.warnings.warn(f"{self.owner}: shader '{node.name}' ({node.bl_label}) is not supported: rendered as "
                               f"diffuse grey (supported: {', '.join(SUPPORTED_SHADERS.values())})",
                               key=("material", self.material_name, node.name))
            return FALLBACK_MATERIAL
        return bsdf

    def bsdf(self, node):
        kind = node.bl_idname
        if kind == "ShaderNodeBsdfPrincipled":
            return self.principled(node)
        if kind == "ShaderNodeBsdfDiffuse":
            return self.with_normal(node, Diffuse(self.value(node, "Color", True)))
        if kind == "ShaderNodeBsdfAnisotropic":
            self.warn_if_linked(node, ("Tangent",), "tangent mapping")
            if float(node.inputs["Anisotropy"].default_value) != 0:
                self.warnings.warn(f"{self.owner}: anisotropic glossy reflection is rendered isotropic")
            roughness = self.scalar(node, "Roughness", "glossy roughness")
            return self.with_normal(node, Glossy(color=self.value(node, "Color", True), alpha=roughness ** 2))
        if kind in ("ShaderNodeBsdfGlass", "ShaderNodeBsdfRefraction"):
            roughness = self.scalar(node, "Roughness", "glass roughness")
            return self.with_normal(node, Dielectric(
                color=self.value(node, "Color", True), ior=self.scalar(node, "IOR", "index of refraction"),
                alpha=0.0 if node.distribution == "SHARP" else roughness ** 2,
                reflect=kind == "ShaderNodeBsdfGlass"))
        if kind == "ShaderNodeBsdfTranslucent":
            return self.with_normal(node, Translucent(self.value(node, "Color", True)))
        if kind == "ShaderNodeBsdfTransparent":
            colour = self.value(node, "Color", True)
            if not isinstance(colour, tuple):
                self.warnings.warn(f"{self.owner}: a textured Transparent BSDF colour is not supported: its own "
                                   "value is used")
                colour = tuple(float(c) for c in node.inputs["Color"].default_value[:3])
            if max(colour) - min(colour) > 1e-3:
                self.warnings.warn(f"{self.owner}: a tinted Transparent BSDF passes its grey level (Mitsuba's "
                                   "opacity is a number)")
            return Transparent(colour)
        return None

    def principled(self, node):
        value = lambda name, colour=False: self.value(node, name, colour)  # noqa: E731
        self.warn_if_linked(node, ("Coat Normal", "Tangent"), "coat normal and tangent mapping")
        if float(node.inputs["Subsurface Weight"].default_value) > 0:
            self.warnings.warn(f"{self.owner}: subsurface scattering is not supported and is ignored")
        bsdf = Principled(
            base_color=value("Base Color", True),
            metallic=value("Metallic"),
            roughness=value("Roughness"),
            ior=self.scalar(node, "IOR", "index of refraction"),
            anisotropic=self.scalar(node, "Anisotropic", "anisotropy"),
            transmission=self.scalar(node, "Transmission Weight", "transmission"),
            coat=self.scalar(node, "Coat Weight", "coat"),
            coat_roughness=self.scalar(node, "Coat Roughness", "coat roughness"),
            sheen=self.scalar(node, "Sheen Weight", "sheen"),
        )
        surface = self.with_normal(node, bsdf)
        alpha = value("Alpha")
        if not isinstance(alpha, float) or alpha < 1.0:
            surface = Mask(alpha, surface)
        emission = value("Emission Color", True)
        strength = self.scalar(node, "Emission Strength", "emission strength")
        if not isinstance(emission, tuple):
            self.warnings.warn(f"{self.owner}: textured emission is not supported: emission ignored")
        elif strength > 0 and any(c > 0 for c in emission):
            return Emission(radiance=tuple(c * strength for c in emission), bsdf=surface)
        return surface

    def in_uv(self, texture: Texture, node) -> Texture:
        """``texture`` looked up in UV (normal and bump maps are: Mitsuba's take their tangents from the UVs)."""
        if texture.coordinates == "uv":
            return texture
        self.warnings.warn(f"{self.owner}: the texture of '{node.name}' is laid out in Generated coordinates; "
                           "normal and bump maps read it in UV here")
        return dataclasses.replace(texture, coordinates="uv")

    def with_normal(self, node, bsdf):
        """``bsdf`` under the Normal Map or Bump node plugged into ``node``'s Normal input, if any."""
        if "Normal" not in node.inputs:
            return bsdf
        return self._perturbed(node.inputs["Normal"], bsdf, depth=0)

    def _perturbed(self, socket, bsdf, depth: int):
        source = linked_node(socket)
        if source is None or depth > 4:
            return bsdf
        if source.bl_idname == "ShaderNodeNormalMap":
            if source.space != "TANGENT":
                self.warnings.warn(f"{self.owner}: normal map '{source.name}' in {source.space.lower()} space is "
                                   "not supported (tangent space only): ignored")
                return bsdf
            if abs(float(source.inputs["Strength"].default_value) - 1.0) > 1e-6:
                self.warnings.warn(f"{self.owner}: the strength of normal map '{source.name}' is rendered as 1")
            texture = self.value(source, "Color", colour=False)
            if not isinstance(texture, Texture):
                self.warnings.warn(f"{self.owner}: normal map '{source.name}' needs an image texture: ignored")
                return bsdf
            return NormalMap(self.in_uv(texture, source), bsdf)
        if source.bl_idname == "ShaderNodeBump":
            height = self.value(source, "Height")
            # Mitsuba's bumpmap displaces by height × scale along the normal, as Blender's by height × distance;
            # Blender's strength blends towards the unbumped normal, here it scales the displacement.
            scale = float(source.inputs["Distance"].default_value) * float(source.inputs["Strength"].default_value)
            inner = self._perturbed(source.inputs["Normal"], bsdf, depth + 1)
            if isinstance(height, Checker) or not isinstance(height, Texture):
                if isinstance(height, Checker):
                    self.warnings.warn(f"{self.owner}: bump '{source.name}' needs an image texture as height: ignored")
                return inner
            height = self.in_uv(height, source)
            if inner is not bsdf:  # Blender applies the Bump's own Normal input first: the outer perturbation
                return NormalMap(inner.texture, Bump(height, -scale if source.invert else scale, inner.bsdf)) \
                    if isinstance(inner, NormalMap) else Bump(height, -scale if source.invert else scale, inner)
            return Bump(height, -scale if source.invert else scale, bsdf)
        self.warnings.warn(f"{self.owner}: the normal of '{socket.node.name}' comes from '{source.name}' "
                           f"({source.bl_label}), which is not supported: ignored")
        return bsdf


def _lift_emission(material):
    """(radiance or None, BSDF or None) of a shader tree: emission becomes the surface's area emitter.

    Cycles adds emission closures wherever they sit in the tree; Mitsuba's emitter
    belongs to the shape, so the tree's emission is summed (with constant Mix
    factors) and replaced by black in the BSDF.
    """
    if isinstance(material, Emission):
        return np.asarray(material.radiance, dtype=float), material.bsdf
    if isinstance(material, Mix):
        first_radiance, first = _lift_emission(material.first)
        second_radiance, second = _lift_emission(material.second)
        if first_radiance is None and second_radiance is None:
            return None, material
        factor = material.factor if isinstance(material.factor, float) else 0.5  # see gather_material's warning
        radiance = (1 - factor) * _zero(first_radiance) + factor * _zero(second_radiance)
        if first is None and second is None:
            return radiance, None
        return radiance, Mix(material.factor, first or BLACK, second or BLACK)
    if isinstance(material, Add):
        first_radiance, first = _lift_emission(material.first)
        second_radiance, second = _lift_emission(material.second)
        if first_radiance is None and second_radiance is None:
            return None, material
        radiance = _zero(first_radiance) + _zero(second_radiance)
        parts = [part for part in (first, second) if part is not None]
        return radiance, (None if not parts else parts[0] if len(parts) == 1 else Add(*parts))
    return None, material


def _has_textured_mix(material) -> bool:
    return any(isinstance(part, Mix) and not isinstance(part.factor, float) and
               (_lift_emission(part.first)[0] is not None or _lift_emission(part.second)[0] is not None)
               for part in walk_materials(material))


def _zero(radiance):
    return np.zeros(3) if radiance is None else radiance


def gather_material(material, warnings: Warnings, *, scratch=None):
    """The neutral material of a Blender material (``None``: the default surface).

    ``scratch``: the object's :class:`ScratchedMetal` when it carries scratches. It replaces
    a "Scratch BSDF" node group in the tree, or else the whole material (as before such groups).
    A shader on the output's Volume makes a :class:`Volumetric` material (docs/rendering.md, Volumes).
    """
    if material is None:
        return DEFAULT_MATERIAL if scratch is None else scratch
    owner = f"material '{material.name}'"
    tree = material.node_tree
    if tree is None:
        return scratch or Diffuse(tuple(float(c) for c in material.diffuse_color[:3]))
    output = tree.get_output_node("CYCLES")
    if output is None:
        if scratch is not None:
            return scratch
        warnings.warn(f"{owner} has no Material Output node: rendered as diffuse grey")
        return FALLBACK_MATERIAL
    has_volume = "Volume" in output.inputs and linked_node(output.inputs["Volume"]) is not None
    if scratch is not None and has_volume:
        warnings.warn(f"{owner}: the volume inside the scratched object is not rendered (the scratch BSDF is "
                      "opaque metal)", key=("scratched-volume", material.name))
        has_volume = False
    volume = gather_volume(output.inputs["Volume"], warnings, owner) if has_volume else None
    surface = _surface(output, material, owner, scratch, warnings, has_volume=has_volume)
    return surface if volume is None else Volumetric(surface, volume)


def _surface(output, material, owner: str, scratch, warnings: Warnings, *, has_volume: bool):
    """The material of the output's Surface (an :class:`Interface` when only a volume is connected)."""
    if linked_node(output.inputs["Surface"]) is None:
        if scratch is not None:
            return scratch
        if has_volume:  # Cycles renders the volume with no surface: the mesh only bounds it (even one
            return Interface()  # not supported here, which gather_volume reported)
        warnings.warn(f"{owner}: nothing is connected to the output's Surface or Volume: rendered black, "
                      "as in Cycles")
        return BLACK
    shaders = _Shaders(warnings, owner, scratch, material.name)
    surface = shaders.shader(output.inputs["Surface"])
    if scratch is not None and not shaders.used_scratch_group:
        return scratch  # no Scratch BSDF group: the scratch BSDF covers the whole object, as documented
    radiance, bsdf = _lift_emission(surface)
    if radiance is not None and _has_textured_mix(surface):
        warnings.warn(f"{owner}: emission inside a Mix Shader with a textured factor is weighted by one half "
                      "(an emitter's radiance is one colour here)")
    if radiance is not None and np.any(radiance > 0):
        return Emission(radiance=tuple(float(c) for c in radiance), bsdf=bsdf)
    return bsdf if bsdf is not None else BLACK
