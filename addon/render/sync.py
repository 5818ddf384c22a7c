"""Depsgraph updates → session updates: what changed since the viewport last synced, and how little to redo.

:func:`classify` is a pure function of the depsgraph and the :class:`SyncState`
of the last sync (no Mitsuba, no drawing), so tests drive it with real ``bpy``
edits from a ``depsgraph_update_post`` handler, exactly where Blender calls the
engine's ``view_update``.  Each change becomes the cheapest
:class:`~mitsuba_bridge.render.session.Update` that
:class:`~mitsuba_bridge.render.session.Session` can apply (its :class:`~mitsuba_bridge.render.session.Change`):

=====================================  ====================================================
edit                                   update
=====================================  ====================================================
object moved, rotated, scaled           ``transform`` (its shapes' vertices)
scratches painted, generated, cleared,  ``scratches`` (the BSDF's tables; the object's
imported, undone (the stored token)     scratch token changed)
scratch material settings               ``material`` (BSDF parameters)
light moved or edited                   ``light`` (emitter parameters)
world colour / sky / strength           ``world``
material value (colour, roughness ...)  ``material``
anything else (mesh edits, objects      ``build``: the engine gathers the whole scene and the
added, removed or hidden, render        session is rebuilt off the main thread
settings, instancers, ...)
=====================================  ====================================================

The view (camera and region size) is not a depsgraph update: ``view_draw``
compares it each time.
"""
from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass, field

import numpy as np

from ...mitsuba_bridge.render.session import Change, Update
from ...mitsuba_bridge.scratch import ScratchFormatError, ScratchSet
from ..geometry import units
from ..storage import has_scratches, read_scratches, scratch_token
from .gather import GEOMETRY_TYPES, Warnings, gather_settings, renderable_instances, scratched_metal
from .gather.lights import gather_light
from .gather.materials import gather_material
from .gather.world import gather_world, gather_world_volume

__all__ = ["SyncState", "snapshot", "classify", "same", "settings_key"]


@dataclass(frozen=True, eq=False)
class ObjectState:
    matrix: np.ndarray
    token: object  #: the scratch token (None: no scratches)
    materials: tuple  #: material names of the slots
    geometry: object  #: a fingerprint of the evaluated mesh (None: not a mesh)
    shared: bool  #: the mesh data is shown by other objects too (instances)


@dataclass(eq=False)
class SyncState:
    """What the session holds, as far as the classifier needs to know (updated as updates are made)."""

    settings: tuple
    objects: dict  #: object name -> ObjectState
    lights: list
    world: object
    materials: dict  #: material key -> Material of the description
    shape_names: tuple  #: names of the description's shapes, in order
    instanced: bool  #: some geometry comes from instancers (always rebuilt)
    warnings: list = field(default_factory=list)
    world_volume: object = None  #: the world's Volume of the description (a change rebuilds: it is every medium)


def same(a, b) -> bool:
    """Equality of description values (dataclasses holding numpy arrays); scratch sets by identity."""
    if type(a) is not type(b):
        return False
    if isinstance(a, ScratchSet):
        return a is b
    if dataclasses.is_dataclass(a):
        return all(same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool(np.array_equal(a, b))
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return a == b


def settings_key(scene) -> tuple:
    """Everything of the scene's settings that needs a new session when it changes."""
    render = scene.scratch_iridescence
    return (gather_settings(scene), render.film_filter, bool(scene.render.film_transparent),
            units.metres_per_unit(scene), int(render.viewport_samples),
            int(render.viewport_start_divisor), bool(render.viewport_freeze))


def _fingerprint(obj):
    if obj.type != "MESH":
        return None
    mesh = obj.data
    positions = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    return len(mesh.vertices), len(mesh.polygons), zlib.crc32(positions.tobytes())


def _object_state(obj) -> ObjectState:
    original = obj.original
    return ObjectState(
        matrix=np.array(obj.matrix_world, dtype=np.float64),
        token=scratch_token(original) if has_scratches(original) else None,
        materials=tuple(slot.material.name if slot.material else "" for slot in obj.material_slots),
        geometry=_fingerprint(obj),
        shared=obj.type == "MESH" and obj.original.data is not None and obj.original.data.users > 1)


def _renderable(depsgraph):
    """(objects by name, lights in gather order, whether instancers add geometry) of the depsgraph."""
    objects, lights, instanced = {}, [], False
    for obj, matrix, is_instance in renderable_instances(depsgraph):
        if obj.type == "LIGHT":
            lights.append((obj, matrix))
        elif obj.type in GEOMETRY_TYPES:
            if is_instance:
                instanced = True
            else:
                objects[obj.name] = obj
    return objects, lights, instanced


def _gather_lights(lights, warnings) -> list:
    gathered = (gather_light(obj, matrix, warnings) for obj, matrix in lights)
    return [light for light in gathered if light is not None]


def snapshot(depsgraph, description) -> SyncState:
    """The state right after ``description`` was gathered from ``depsgraph`` (a full build)."""
    objects, lights, instanced = _renderable(depsgraph)
    warnings = Warnings()
    return SyncState(settings=settings_key(depsgraph.scene),
                     objects={name: _object_state(obj) for name, obj in objects.items()},
                     lights=_gather_lights(lights, warnings), world=description.world,
                     materials=dict(description.materials),
                     shape_names=tuple(shape.name for shape in description.shapes), instanced=instanced,
                     world_volume=description.world_volume)


def _shapes_of(state: SyncState, name: str) -> list[str]:
    """Shape names of object ``name``: its own, or one per material slot (``name.<slot>``)."""
    return sorted({shape for shape in state.shape_names
                   if shape == name or (shape.startswith(name + ".") and shape[len(name) + 1:].isdigit())})


def classify(depsgraph, state: SyncState) -> list[Update]:
    """The session updates for ``depsgraph.updates`` since ``state`` (which is brought up to date).

    Returns ``[Update(Change.BUILD)]`` when an edit has no cheaper form: the caller
    then gathers the scene and calls :func:`snapshot` afresh.
    """
    build = [Update(Change.BUILD)]
    if settings_key(depsgraph.scene) != state.settings:
        return build
    objects, lights, instanced = _renderable(depsgraph)
    if instanced or state.instanced or objects.keys() != state.objects.keys():
        return build
    updates: list[Update] = []
    lights_changed = world_changed = False
    materials_changed = set()
    import bpy

    for change in depsgraph.updates:
        data = change.id
        if isinstance(data, bpy.types.Object):
            if data.type == "LIGHT":
                lights_changed = True
            elif data.name in objects:
                result = _object_updates(objects[data.name], change.is_updated_geometry, depsgraph.scene, state)
                if result is None:
                    return build
                updates += result
        elif isinstance(data, bpy.types.Light):
            lights_changed = True
        elif isinstance(data, bpy.types.World):
            world_changed = True
        elif isinstance(data, bpy.types.Material):
            materials_changed.add(data.name)
    warnings = Warnings()
    if lights_changed:
        new_lights = _gather_lights(lights, warnings)
        if len(new_lights) != len(state.lights):
            return build
        for index, (old, new) in enumerate(zip(state.lights, new_lights)):
            if not same(old, new):
                updates.append(Update(Change.LIGHT, (index, new)))
        state.lights = new_lights
    if world_changed:
        world = gather_world(depsgraph.scene.world, warnings)
        if (world is None) != (state.world is None):
            return build
        if not same(gather_world_volume(depsgraph.scene.world, warnings), state.world_volume):
            return build
        if not same(world, state.world):
            updates.append(Update(Change.WORLD, (world,)))
            state.world = world
    for name in sorted(materials_changed):
        key = f"material:{name}"
        if key in state.materials:
            material = gather_material(bpy.data.materials[name], warnings)
            if not same(material, state.materials[key]):
                updates.append(Update(Change.MATERIAL, (key, material)))
                state.materials[key] = material
    state.warnings = list(warnings.as_tuple())
    return updates


def _object_updates(obj, geometry_flagged: bool, scene, state: SyncState):
    """Updates of one changed geometry object, or None when it needs a rebuild."""
    old = state.objects[obj.name]
    new = _object_state(obj)
    if new.materials != old.materials or (new.token is None) != (old.token is None):
        return None
    if geometry_flagged and (new.geometry is None or new.geometry != old.geometry):
        return None
    updates = []
    if new.token is not None:
        key = f"scratches:{obj.original.name}"
        if key not in state.materials:
            return None
        metal = state.materials[key]
        if new.token != old.token:
            try:
                metal = dataclasses.replace(metal, scratches=read_scratches(obj.original))
            except ScratchFormatError:
                return None  # the build path reports it
            updates.append(Update(Change.SCRATCHES, (key, metal.scratches)))
        has_uvs = obj.type == "MESH" and len(obj.data.uv_layers) > 0
        settings = scratched_metal(obj.original, scene, has_uvs, Warnings())
        if not same(dataclasses.replace(settings, scratches=metal.scratches), metal):
            metal = dataclasses.replace(settings, scratches=metal.scratches)
            updates.append(Update(Change.MATERIAL, (key, metal)))
        state.materials[key] = metal
    if not np.array_equal(new.matrix, old.matrix):
        shapes = _shapes_of(state, obj.name)
        if not shapes or new.shared:
            return None
        updates += [Update(Change.TRANSFORM, (shape, new.matrix)) for shape in shapes]
    state.objects[obj.name] = new
    return updates
