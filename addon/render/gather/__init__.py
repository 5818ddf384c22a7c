"""Evaluated depsgraph → :class:`~mitsuba_bridge.scene.SceneDescription`.

The one entry point is :func:`gather_scene`; everything Blender-specific
(power conventions, sensor fit, node trees, instancing) is resolved here, so
the builder on the other side sees only physical quantities and numpy arrays.
"""
from __future__ import annotations

import numpy as np

from ....mitsuba_bridge.scene import (Checker, Emission, MeshData, RenderSettings, SceneDescription, ScratchedMetal,
                                      Shape, Texture, Volumetric, walk_materials)
from ....mitsuba_bridge.scene.finite import with_finite_meshes
from ....mitsuba_bridge.scene.glints import check_glints, surface_samples
from ....mitsuba_bridge.scratch import ScratchFormatError, ScratchSet
from ...geometry import units
from ...storage import has_scratches, read_scratches
from .camera import gather_camera, gather_film
from .lights import gather_light
from .materials import gather_material
from .meshes import mesh_parts
from .report import GatherError, Warnings
from .world import gather_world, gather_world_volume

__all__ = ["gather_scene", "gather_settings", "renderable_instances", "GatherError", "Warnings", "GEOMETRY_TYPES",
           "scratched_metal"]

#: Object types that evaluate to a mesh.
GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}


def renderable_instances(depsgraph):
    """``(object, world matrix, is_instance)`` of every object instance that renders, in the depsgraph's order
    (gather and the viewport's sync walk the scene the same way)."""
    for instance in depsgraph.object_instances:
        obj = instance.object
        if obj.original.hide_render:
            continue  # a viewport depsgraph (export) also holds objects that do not render
        yield obj, np.array(instance.matrix_world), instance.is_instance


def gather_settings(scene) -> RenderSettings:
    settings = scene.scratch_iridescence
    return RenderSettings(spp=settings.samples, max_depth=settings.max_depth, seed=settings.seed,
                          variant=settings.variant, footprint_filter=settings.footprint_filter,
                          sampler=settings.sampler)


def gather_scene(depsgraph, *, camera=None, view=None) -> SceneDescription:
    """Gather what ``depsgraph`` (render or viewport) shows through ``camera`` (default: the scene's).

    ``view``, a ``(Camera, Film)`` pair, replaces the scene's camera and film
    (the 3D view's, for the Rendered viewport).  Raises :class:`GatherError`
    when nothing sensible can be rendered (no camera); everything else that is
    not supported becomes a warning in the result.
    """
    scene = depsgraph.scene
    warnings = Warnings()
    if view is not None:
        camera_description, film = view
    else:
        film = gather_film(scene, scene.scratch_iridescence.film_filter)
        camera_description = gather_camera(scene, camera if camera is not None else scene.camera, warnings)
    materials, shapes, lights, meshes = {}, [], [], {}
    for obj, matrix, _ in renderable_instances(depsgraph):
        if obj.type == "LIGHT":
            light = gather_light(obj, matrix, warnings)
            if light is not None:
                lights.append(light)
        elif obj.type in GEOMETRY_TYPES:
            shapes += _gather_object(obj, matrix, scene, materials, meshes, warnings)
        elif obj.type in ("CURVES", "POINTCLOUD", "VOLUME", "GREASEPENCIL"):
            warnings.warn(f"{obj.type.lower()} objects are not supported and are not rendered ('{obj.name}')",
                          key=("type", obj.type))
    world = gather_world(scene.world, warnings)
    world_volume = gather_world_volume(scene.world, warnings)
    if not shapes and not lights and world is None:
        warnings.warn("the scene has no visible objects, lights or world: the image is black")
    elif not lights and world is None and not any(_emits(m) for m in materials.values()):
        warnings.warn("the scene has no lights, no emissive material and a black world: the image is black; "
                      "add a light or a world colour")
    else:
        _warn_unlit_glints(shapes, materials, camera_description, lights, world, warnings)
    # NaN/inf vertices (a broken modifier or driver) would blacken the image silently: drop them, with a warning.
    return with_finite_meshes(SceneDescription(film=film, camera=camera_description, shapes=tuple(shapes),
                                               materials=materials, lights=tuple(lights), world=world,
                                               warnings=warnings.as_tuple(), world_volume=world_volume))


def _warn_unlit_glints(shapes, materials: dict, camera, lights, world, warnings: Warnings) -> None:
    """A warning per scratched object whose glints no light of the scene can show (:mod:`scene.glints`)."""
    emissive = any(_emits(m) for m in materials.values())
    for key, material in materials.items():
        metal = next((part for part in walk_materials(material) if isinstance(part, ScratchedMetal)), None)
        if metal is None or metal.scratches.count == 0:
            continue
        samples = [surface_samples(shape.mesh, shape.to_world) for shape in shapes if shape.material == key]
        if not samples:
            continue
        surfaces = tuple(np.concatenate([sample[i] for sample in samples]) for i in (0, 1))
        check = check_glints(surfaces, metal.scratches, camera, lights, world, emissive=emissive)
        if not check.shows:
            name = key.split(":", 1)[1]
            warnings.warn(f"object '{name}': no light can show its scratches' glints ({check.describe()}): it "
                          "renders as a dark mirror; Object Properties › Scratches › Add Glint Lighting places a "
                          "sun that shows them", key=("glints", name))


def _emits(material) -> bool:
    return isinstance(material.surface if isinstance(material, Volumetric) else material, Emission)


def _gather_object(obj, matrix, scene, materials: dict, meshes: dict, warnings: Warnings) -> list[Shape]:
    original = obj.original
    scratched = has_scratches(original)
    # Objects (and instances) showing the same evaluated mesh share its data; other
    # types are converted per object.
    key = (obj.data.as_pointer() if obj.type == "MESH" else obj.name, scratched, False)
    if key not in meshes:
        meshes[key] = _object_parts(obj, scratched)
    parts = meshes[key]
    keys = []
    for slot, mesh in parts:
        material = obj.material_slots[slot].material if slot < len(obj.material_slots) else None
        if scratched:
            material_key = f"scratches:{original.name}"
            if material_key not in materials:
                metal = scratched_metal(original, scene, mesh.uvs is not None, warnings)
                materials[material_key] = gather_material(material, warnings, scratch=metal)
        else:
            material_key = "default" if material is None else f"material:{material.name}"
            if material_key not in materials:
                materials[material_key] = gather_material(material, warnings)
            if mesh.uvs is None and _uses_texture(materials[material_key], "uv"):
                warnings.warn(f"object '{obj.name}' has no UV map but its material uses an image texture: "
                              "the texture is read at UV (0, 0)", key=("no-uv", obj.name))
        keys.append(material_key)
    if any(_uses_texture(materials[material_key], "generated") for material_key in keys):
        generated_key = key[:2] + (True,)  # the same parts with Generated coordinates
        if generated_key not in meshes:
            meshes[generated_key] = _object_parts(obj, scratched, generated=True)
        parts = meshes[generated_key]
    return [Shape(name=mesh.name, mesh=mesh, to_world=matrix, material=material_key)
            for (_, mesh), material_key in zip(parts, keys)]


def _object_parts(obj, scratched: bool, *, generated: bool = False):
    """Mesh parts of an evaluated object (scratched objects stay whole: one BSDF covers them)."""
    if obj.type == "MESH":
        parts = mesh_parts(obj.data, obj.name, generated=generated)
    else:
        mesh = obj.to_mesh()
        try:
            parts = mesh_parts(mesh, obj.name, generated=generated) if mesh is not None else []
        finally:
            obj.to_mesh_clear()
    if scratched and len(parts) > 1:
        parts = [(0, _join([mesh for _, mesh in parts], obj.name))]
    return parts


def _join(meshes, name) -> MeshData:
    offsets = np.cumsum([0] + [len(m.positions) for m in meshes[:-1]])
    has = lambda attribute: all(getattr(m, attribute) is not None for m in meshes)  # noqa: E731
    return MeshData(
        name, np.concatenate([m.positions for m in meshes]),
        np.concatenate([m.faces + np.uint32(o) for m, o in zip(meshes, offsets)]),
        np.concatenate([m.normals for m in meshes]) if has("normals") else None,
        np.concatenate([m.uvs for m in meshes]) if has("uvs") else None,
        np.concatenate([m.generated for m in meshes]) if has("generated") else None)


def _uses_texture(material, coordinates: str) -> bool:
    """Whether a texture of ``material`` is looked up in ``coordinates`` (``"uv"`` or ``"generated"``)."""
    return any(isinstance(value, (Texture, Checker)) and value.coordinates == coordinates
               for part in walk_materials(material)
               for value in (getattr(part, name, None) for name in ("reflectance", "base_color", "metallic",
                                                                   "roughness", "color", "factor", "opacity",
                                                                   "texture", "height")))


def scratched_metal(obj, scene, has_uvs: bool, warnings: Warnings) -> ScratchedMetal:
    """The scratch BSDF settings of ``obj`` (its scratches, base metal, coherence)."""
    settings = obj.scratch_iridescence
    metres_per_unit = units.metres_per_unit(scene)
    try:
        scratches = read_scratches(obj)
    except ScratchFormatError as error:
        # Like every reader of a stored set (overlay, eraser, export): one clear error, no silent substitute.
        raise GatherError(str(error)) from None
    if not has_uvs and scratches.count:
        warnings.warn(f"object '{obj.name}' carries scratches but has no UV map: rendered without scratches; "
                      "add a UV map (the scratches live in UV space)")
        scratches = ScratchSet.empty()
    diffuse = tuple(float(c) for c in settings.diffuse_reflectance)
    return ScratchedMetal(scratches=scratches, coherence_diameter_m=float(settings.coherence_diameter_um) * 1e-6,
                          metres_per_unit=metres_per_unit, material=settings.base_material, coherent=bool(settings.coherent),
                          diffuse_reflectance=diffuse if any(diffuse) else None, crossings=settings.crossings,
                          depth_phase=settings.depth_phase)
