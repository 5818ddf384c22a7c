"""The neutral scene description: what the Blender side gathers and the builder turns into Mitsuba.

Frozen dataclasses and numpy arrays, no Mitsuba, no Blender: the contract between the two halves of
the project (docs/architecture.md); its invariants live here, not on either side.  Import the names
from this package: :mod:`.description` holds the scene (film, camera, meshes, lights, world, render
settings), :mod:`.materials` the materials and textures; :mod:`.finite` drops non-finite mesh values
and :mod:`.colour` converts colour spaces.
"""
from __future__ import annotations

from .description import (FILTERS, LIGHT_TYPES, SAMPLERS, WORLD_TYPES, AreaLight, Camera, ConstantWorld,
                          EnvironmentWorld, Film, Light, MeshData, PointLight, RenderSettings, SceneDescription, Shape,
                          SkyWorld, SpotLight, SunLight, World, affine, orthonormal)
from .materials import (RGB, TEXTURE_COORDINATES, Add, Bump, Checker, Dielectric, Diffuse, Emission, Glossy,
                        Interface, Mask, Material, Mix, NormalMap, Principled, ScratchedMetal, Texture, Translucent,
                        Transparent, Value, Volume, Volumetric, walk_materials)

__all__ = ["FILTERS", "LIGHT_TYPES", "SAMPLERS", "WORLD_TYPES", "affine", "AreaLight", "Camera", "ConstantWorld",
           "EnvironmentWorld", "Film", "Light", "MeshData", "PointLight", "RenderSettings", "SceneDescription",
           "Shape", "SkyWorld", "SpotLight", "SunLight", "World",
           "orthonormal", "RGB", "Add", "Bump", "Checker", "Dielectric", "Diffuse", "Emission", "Glossy", "Mask",
           "Material", "Mix", "NormalMap", "Principled", "ScratchedMetal", "Texture", "Translucent", "Transparent",
           "Value", "walk_materials", "Interface", "Volume", "Volumetric", "TEXTURE_COORDINATES"]
