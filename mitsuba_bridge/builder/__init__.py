"""Neutral scene description → Mitsuba scene dict (and, in memory, a loaded ``mi.Scene``).

One small function per output type (``sensor_dict``, ``bsdf_dict``,
``light_dict``, ``world_dict``), assembled here; a *resources* object decides
whether heavy data stays in memory (rendering) or goes to files (export).
A Mitsuba variant must be active before calling anything here.
"""
from __future__ import annotations

import contextlib
from collections import Counter

from ..scene import Interface, Mask, RenderSettings, SceneDescription, Transparent, walk_materials
from .camera import film_dict, footprint_settings, integrator_dict, sensor_dict, window_camera, with_data_passes
from .lights import light_dict, world_dict
from .materials import add_weights, bsdf_dict, emitter_dict
from .resources import InMemory, load_dict, safe_name
from .transform import to_mitsuba
from .volumes import WORLD_MEDIUM, has_media, material_volume, medium_dict

__all__ = ["scene_dict", "load_scene", "check_tables_memory", "load_dict", "InMemory", "sensor_dict", "film_dict",
           "integrator_dict", "window_camera", "bsdf_dict", "emitter_dict", "add_weights", "light_dict", "world_dict",
           "material_id", "MIN_INSTANCES"]

#: Shapes showing one mesh with one material at least this often share it through a ``shapegroup``.
MIN_INSTANCES = 2


def material_id(key: str) -> str:
    """The id of a material's top-level BSDF entry."""
    return "mat-" + safe_name(key)


def scene_dict(description: SceneDescription, settings: RenderSettings, resources=None, *,
               instancing: bool = True) -> dict:
    """The ``mi.load_dict`` dict of ``description``.

    With :class:`...folder.resources.ToFolder` resources materials are top-level entries that shapes
    reference (written once in the XML); in memory the resources share one
    loaded BSDF per material instead.

    Shapes that share one :class:`MeshData` and one material (instances, linked
    duplicates) become one ``shapegroup`` holding the mesh in object space and
    one ``instance`` per shape, so memory grows with the unique meshes, not the
    instances. Emissive ones stay separate meshes (Mitsuba's shape groups carry
    no emitters); ``instancing=False`` turns sharing off (comparisons, benchmarks).

    Volumes become media (:mod:`.volumes`): a material's inside its shapes, the world's around
    everything else, the camera included.
    """
    resources = InMemory() if resources is None else resources
    resources.footprint = footprint_settings(description.camera, description.film, settings)
    shared = resources.shares_materials
    world_medium = None
    if description.world_volume is not None and not description.world_volume.empty:
        world_medium = resources.medium(WORLD_MEDIUM, medium_dict(description.world_volume))
    result: dict = {
        "type": "scene",
        "integrator": integrator_dict(settings, description.film, see_through_surfaces=(
            _has_see_through_surfaces(description) or has_media(description))),
        "sensor": sensor_dict(description.camera, description.film, settings, medium=world_medium),
    }
    if settings.data_passes:
        result["integrator"] = with_data_passes(result["integrator"], description.camera)
    bsdfs = {key: bsdf_dict(material, resources, key=key) for key, material in description.materials.items()
             if any(shape.material == key for shape in description.shapes)}
    if shared:
        for key, bsdf in bsdfs.items():
            result[material_id(key)] = bsdf
    names = set(result)
    uses = Counter((id(shape.mesh), shape.material) for shape in description.shapes)
    groups: dict = {}
    for shape in description.shapes:
        material = description.materials[shape.material]
        bsdf = {"type": "ref", "id": material_id(shape.material)} if shared else bsdfs[shape.material]
        emitter = emitter_dict(material)
        media = _media(resources, shape.material, material, world_medium)
        key = (id(shape.mesh), shape.material)
        name = _unique(names, "shape-" + safe_name(shape.name))
        if not instancing or emitter is not None or uses[key] < MIN_INSTANCES:
            result[name] = resources.shape(shape, bsdf, emitter, material_key=shape.material, media=media)
            continue
        if key not in groups:
            groups[key] = _unique(names, "group-" + safe_name(shape.mesh.name))
            result[groups[key]] = {"type": "shapegroup", "mesh": resources.instanced_shape(
                shape.mesh, bsdf, material_key=shape.material, media=media)}
        result[name] = {"type": "instance", "shapegroup": {"type": "ref", "id": groups[key]},
                        "to_world": to_mitsuba(shape.to_world)}
    for index, light in enumerate(description.lights):
        light_entry = light_dict(light)
        if world_medium is not None and "emitter" in light_entry:  # a light's shape sits in the world's volume
            light_entry.update(interior=world_medium, exterior=world_medium)
        result[_unique(names, f"light-{index}")] = light_entry
    if description.world is not None:
        result["world"] = world_dict(description.world, resources)
    return result


def _has_see_through_surfaces(description: SceneDescription) -> bool:
    return any(isinstance(part, (Mask, Transparent, Interface)) for material in description.materials.values()
               for part in walk_materials(material))


def _media(resources, material_key: str, material, world_medium) -> dict | None:
    """The ``interior``/``exterior`` media of the shapes of a material (None: no media in the scene).

    In a world volume a surface has the world on both sides unless its material fills it with a
    volume of its own: rays learn their medium only from the surfaces they cross.
    """
    volume = material_volume(material)
    interior = world_medium if volume is None else resources.medium(material_key, medium_dict(volume))
    if interior is None and world_medium is None:
        return None
    media = {"interior": interior}
    if world_medium is not None:
        media["exterior"] = world_medium
    return media


def load_scene(description: SceneDescription, settings: RenderSettings, *, instancing: bool = True,
               keep_tables: bool | None = None):
    """The scene loaded in memory (no files written).

    ``keep_tables`` (a final render's *Persistent Data*): True reuses the scratch tables kept from the
    previous final render where the scratch set is unchanged and keeps this scene's; False forgets any
    kept tables; None (the viewport, exports, tests) leaves them alone (:mod:`..bsdf.persistent`).
    """
    from ..bsdf.persistent import kept_between_renders

    check_tables_memory(description)
    kept = contextlib.nullcontext() if keep_tables is None else kept_between_renders(keep_tables)
    with kept:
        return load_dict(scene_dict(description, settings, InMemory(), instancing=instancing))


def check_tables_memory(description: SceneDescription) -> None:
    """Refuse, before loading, a scene whose scratch tables cannot fit the memory this process is allowed
    (:func:`...bsdf.tables.grid.check_piece_memory`: raised inside Mitsuba's loader it would reach the caller as a
    plugin's traceback)."""
    from ..bsdf.tables.grid import check_piece_memory
    from ..scene import ScratchedMetal

    for key, material in description.materials.items():
        if isinstance(material, ScratchedMetal) and any(shape.material == key for shape in description.shapes):
            check_piece_memory(material.scratches)


def _unique(names: set, name: str) -> str:
    candidate, index = name, 1
    while candidate in names:
        candidate, index = f"{name}_{index:03d}", index + 1
    names.add(candidate)
    return candidate
