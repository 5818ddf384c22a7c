"""Volume shaders (a material's or the world's Volume output) → a homogeneous :class:`Volume`.

Coefficients as Cycles computes them (``svm_node_closure_volume`` and ``svm_node_principled_volume``),
per scene unit:

* Volume Scatter: σ_s = colour × density (it absorbs nothing);
* Volume Absorption: σ_a = (1 − colour) × density;
* Principled Volume: σ_s = colour × density, σ_a = max(1 − colour, 0) × max(1 − √absorption colour, 0)
  × density, anisotropy g;
* Volume Coefficients (Blender 5): σ_a and σ_s as given;
* Add Shader sums coefficients, Mix Shader weighs them by its factor. Two scattering volumes with
  different anisotropies become one Henyey–Greenstein lobe of their scattering-weighted mean g
  (Cycles keeps both lobes), with a warning.

Mitsuba's ``homogeneous`` medium is uniform and does not emit: an input that varies in space (an image,
a checker, noise) is rendered at its mean, with a warning naming the node; a mesh's geometry attribute
(Attribute node) is 0 inside its volume, as Cycles reads it there; emission and blackbody are left
out, with a warning.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ....mitsuba_bridge.scene import Volume
from .report import Warnings
from .values import LUMINANCE, ValueReader, linked_output

__all__ = ["gather_volume", "VOLUME_SHADERS"]

VOLUME_SHADERS = {
    "ShaderNodeVolumePrincipled": "Principled Volume",
    "ShaderNodeVolumeScatter": "Volume Scatter",
    "ShaderNodeVolumeAbsorption": "Volume Absorption",
    "ShaderNodeVolumeCoefficients": "Volume Coefficients",
    "ShaderNodeAddShader": "Add Shader",
    "ShaderNodeMixShader": "Mix Shader",
}
_NESTING = 16  # deeper Add/Mix trees than this are a cycle or a mistake


class _Coefficients:
    """σ_s, σ_a (RGB, 1/scene unit) and the scattering-weighted sum of g of a volume being summed."""

    def __init__(self, scattering=(0.0, 0.0, 0.0), absorption=(0.0, 0.0, 0.0), anisotropy: float = 0.0):
        self.scattering = np.maximum(np.asarray(scattering, dtype=np.float64), 0.0)
        self.absorption = np.maximum(np.asarray(absorption, dtype=np.float64), 0.0)
        self.weighted_g = float(self.scattering @ LUMINANCE) * anisotropy
        self.anisotropies = {round(anisotropy, 6)} if self.scattering.any() else set()

    def scaled(self, factor: float) -> "_Coefficients":
        result = _Coefficients()
        result.scattering, result.absorption = self.scattering * factor, self.absorption * factor
        result.weighted_g, result.anisotropies = self.weighted_g * factor, set(self.anisotropies)
        return result

    def plus(self, other: "_Coefficients") -> "_Coefficients":
        result = _Coefficients()
        result.scattering, result.absorption = self.scattering + other.scattering, self.absorption + other.absorption
        result.weighted_g = self.weighted_g + other.weighted_g
        result.anisotropies = self.anisotropies | other.anisotropies
        return result

    def volume(self) -> Volume:
        scattering = float(self.scattering @ LUMINANCE)
        g = self.weighted_g / scattering if scattering > 0 else 0.0
        return Volume(scattering=tuple(float(c) for c in self.scattering),
                      absorption=tuple(float(c) for c in self.absorption),
                      anisotropy=float(np.clip(g, -0.999, 0.999)))


class _VolumeReader:
    def __init__(self, warnings: Warnings, owner: str):
        self.warnings, self.owner = warnings, owner
        self.values = ValueReader(warnings, owner)

    def input(self, node, name: str, *, colour: bool):
        """Input ``name`` of ``node`` as a number or an RGB array; one that varies in space at its mean."""
        linked = linked_output(node.inputs[name])
        if linked is not None and linked[0].bl_idname == "ShaderNodeAttribute" and \
                linked[0].attribute_type == "GEOMETRY":
            # A mesh's attributes live on its surface: inside its volume Cycles reads them as 0 (measured).
            self.warnings.warn(f"{self.owner}: the volume's '{name}' of '{node.name}' reads the geometry attribute "
                               f"'{linked[0].attribute_name}' ('{linked[0].name}'), which a mesh has only on its "
                               "surface: 0 inside the volume, as in Cycles", key=(self.owner, node.name, name, "attr"))
            return np.zeros(3) if colour else 0.0
        value, source = self.values.mean(node, name, colour=colour)
        if source is not None:
            shown = f"{value:.3g}" if not colour else "(" + ", ".join(f"{c:.3g}" for c in value) + ")"
            self.warnings.warn(f"{self.owner}: the volume's '{name}' of '{node.name}' varies in space "
                               f"('{source.name}', {source.bl_label}): rendered uniform at its mean {shown} "
                               "(a homogeneous volume)", key=(self.owner, node.name, name, "mean"))
        return np.asarray(value, dtype=np.float64) if colour else float(value)

    def no_emission(self, node, names) -> None:
        if any(name in node.inputs and (linked_output(node.inputs[name]) is not None
                                        or float(node.inputs[name].default_value) > 0) for name in names):
            self.warnings.warn(f"{self.owner}: volume emission ('{node.name}') is not supported (Mitsuba's "
                               "homogeneous medium does not emit): left out", key=(self.owner, node.name, "emit"))

    def coefficients(self, socket, depth: int = 0) -> Optional[_Coefficients]:
        source = linked_output(socket)
        if source is None or depth > _NESTING:
            return None
        node = source[0]
        kind = node.bl_idname
        if kind == "ShaderNodeAddShader":
            parts = [self.coefficients(node.inputs[i], depth + 1) for i in (0, 1)]
            parts = [part for part in parts if part is not None]
            return None if not parts else parts[0] if len(parts) == 1 else parts[0].plus(parts[1])
        if kind == "ShaderNodeMixShader":
            factor = float(np.clip(self.input(node, "Fac", colour=False), 0.0, 1.0))
            first, second = (self.coefficients(node.inputs[i], depth + 1) for i in (1, 2))
            parts = [part.scaled(weight) for part, weight in ((first, 1 - factor), (second, factor))
                     if part is not None]
            return None if not parts else parts[0] if len(parts) == 1 else parts[0].plus(parts[1])
        if kind == "ShaderNodeVolumePrincipled":
            colour = self.input(node, "Color", colour=True)
            density = max(self.input(node, "Density", colour=False), 0.0)
            absorption_colour = np.maximum(self.input(node, "Absorption Color", colour=True), 0.0)
            absorption = np.maximum(1 - colour, 0.0) * np.maximum(1 - np.sqrt(absorption_colour), 0.0)
            self.no_emission(node, ("Emission Strength", "Blackbody Intensity"))
            return _Coefficients(colour * density, absorption * density, self.anisotropy(node))
        if kind == "ShaderNodeVolumeScatter":
            colour = self.input(node, "Color", colour=True)
            density = max(self.input(node, "Density", colour=False), 0.0)
            return _Coefficients(colour * density, anisotropy=self.anisotropy(node))
        if kind == "ShaderNodeVolumeAbsorption":
            colour = self.input(node, "Color", colour=True)
            density = max(self.input(node, "Density", colour=False), 0.0)
            return _Coefficients(absorption=(1 - colour) * density)
        if kind == "ShaderNodeVolumeCoefficients":
            self.no_emission_coefficients(node)
            return _Coefficients(self.input(node, "Scatter Coefficients", colour=True),
                                 self.input(node, "Absorption Coefficients", colour=True), self.anisotropy(node))
        self.warnings.warn(f"{self.owner}: '{node.name}' ({node.bl_label}) on the Volume output is not supported: "
                           f"no volume (supported: {', '.join(VOLUME_SHADERS.values())})",
                           key=(self.owner, node.name, "volume"))
        return None

    def no_emission_coefficients(self, node) -> None:
        socket = node.inputs.get("Emission Coefficients")
        if socket is not None and (linked_output(socket) is not None or any(socket.default_value)):
            self.warnings.warn(f"{self.owner}: volume emission ('{node.name}') is not supported (Mitsuba's "
                               "homogeneous medium does not emit): left out", key=(self.owner, node.name, "emit"))

    def anisotropy(self, node) -> float:
        phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
        if phase != "HENYEY_GREENSTEIN":
            self.warnings.warn(f"{self.owner}: the {phase.replace('_', '-').title()} phase function of "
                               f"'{node.name}' is rendered as Henyey-Greenstein with its Anisotropy",
                               key=(self.owner, node.name, "phase"))
        return float(np.clip(self.input(node, "Anisotropy", colour=False), -0.999, 0.999))


def gather_volume(socket, warnings: Warnings, owner: str) -> Optional[Volume]:
    """The homogeneous volume of the shader tree on ``socket`` (a Volume output), or None.

    ``owner`` names the material or the world in warnings. A volume that neither scatters nor absorbs
    is returned as it is (its surface still counts); the builder gives it no medium.
    """
    reader = _VolumeReader(warnings, owner)
    coefficients = reader.coefficients(socket)
    if coefficients is None:
        return None
    if len(coefficients.anisotropies) > 1:
        warnings.warn(f"{owner}: volumes of different anisotropy are rendered as one Henyey-Greenstein lobe of "
                      "their mean anisotropy (Cycles keeps each)", key=(owner, "anisotropies"))
    return coefficients.volume()
