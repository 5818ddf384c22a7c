"""Where the heavy parts of a scene go: meshes, textures and scratch sets.

The builder produces the same dict either way and asks a *resources* object
for the heavy parts:

* :class:`InMemory` (rendering): meshes become ``mi.Mesh`` objects filled from
  numpy, textures ``mi.Bitmap`` objects or the user's own files, scratch sets
  are handed to the BSDF as arrays — no temporary files.
* :class:`...folder.resources.ToFolder` (export): meshes are written once per mesh
  as PLY files in object space and placed with ``to_world``, textures are copied
  or written as EXR, scratch sets as format-v1 files; the dict references them by
  paths relative to the folder.

Both have the same methods (``texture``, ``environment``, ``scratch_bsdf``, ``medium``, ``shape``,
``instanced_shape``) and say with ``shares_materials`` whether materials are top-level
entries that shapes reference (a folder's XML) or objects loaded once per material (memory).
"""
from __future__ import annotations

import re

import numpy as np

from ..bsdf.generated import ATTRIBUTE as GENERATED_ATTRIBUTE
from ..errors import plugin_user_errors
from ..bsdf.tables.references import aligned_array
from ..scene.colour import srgb_to_linear
from ..scene import MeshData, ScratchedMetal, Shape, Texture
from .transform import to_mitsuba

__all__ = ["InMemory", "world_geometry", "safe_name", "mesh_buffer", "bitmap_options", "scratch_plugin_settings",
           "load_dict", "GENERATED_ATTRIBUTE"]


# Image rows run top-down, Blender's v runs bottom-up: look textures up at (u, 1 - v).
_FLIP_V = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 1.0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]])


def safe_name(name: str) -> str:
    """``name`` reduced to characters that are safe in file names and XML ids."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", name) or "unnamed"


def world_geometry(shape: Shape) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(positions, faces, normals) of ``shape`` in world space.

    Normals transform with the inverse transpose; a mirroring matrix reverses the
    winding so that geometric and shading normals keep agreeing.
    """
    mesh = shape.mesh
    matrix = np.asarray(shape.to_world, dtype=np.float64)
    linear = matrix[:3, :3]
    positions = mesh.positions @ linear.T.astype(np.float32)
    positions += matrix[:3, 3].astype(np.float32)
    faces = mesh.faces
    mirrored = np.linalg.det(linear) < 0
    if mirrored:
        faces = faces[:, ::-1]
    normals = None
    if mesh.normals is not None:
        normal_matrix = np.linalg.inv(linear).T.astype(np.float32)
        normals = mesh.normals @ normal_matrix.T
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        np.divide(normals, length, out=normals, where=length > 0)
    return positions, np.ascontiguousarray(faces, dtype=np.uint32), normals


def bitmap_options(texture: Texture, colour: bool) -> dict:
    """The ``bitmap`` plugin's options for ``texture`` besides its pixels (UV flip, filter, raw)."""
    return {
        "to_uv": to_mitsuba(_FLIP_V),
        "filter_type": "nearest" if texture.interpolation == "nearest" else "bilinear",
        # Non-colour data must not be upsampled to spectra nor linearised.
        "raw": not colour,
    }


def load_dict(description: dict):
    """``mi.load_dict(description)``, serially: every scene, BSDF, light and world the bridge loads goes here.

    Mitsuba's parallel loader instantiates siblings in whatever order its threads run, and numbers them so:
    the area lights (rectangles, discs, spheres: loaded with the scene) and the world took emitter IDs 1
    and 2 either way round, a literal in the render kernel, whose hash then changed and whose 1-25 s compile
    Dr.Jit's disk cache no longer saved (2 of 23 engine renders of the Fig. 9 grating under load, 0 of 16
    serially). It also kept the Python scratch BSDF on its worker threads beside other plugins, which
    Mitsuba does not promise to support (mitsuba3 #457; a rare "failed to instantiate ...
    basic_string::_M_create" was seen that way). See docs/rendering.md, What a chunk's size costs. The
    shapes and BSDFs of a scene are objects already: little is left to parallelise.

    A user error raised by the scratch BSDF while it loads comes out as itself (:func:`..errors.plugin_user_errors`),
    not as Mitsuba's ``RuntimeError`` quoting its traceback.
    """
    import mitsuba as mi

    with plugin_user_errors():
        return mi.load_dict(description, parallel=False)


class InMemory:
    """Resources for rendering straight from memory."""

    shares_materials = False  #: each material's BSDF is loaded once and handed to its shapes
    #: ``plugin_dict`` keywords of the render's footprint filter (:func:`.camera.footprint_settings`)
    footprint: dict = {}

    def __init__(self):
        self._bsdfs: dict[str, object] = {}
        self._textures: dict[tuple[str, bool], dict] = {}
        self._media: dict[str, object] = {}

    def texture(self, texture: Texture, *, colour: bool) -> dict:
        import mitsuba as mi

        key = (texture.name, colour)
        if key not in self._textures:
            result = {"type": "bitmap", **bitmap_options(texture, colour)}
            if texture.path is not None:
                result["filename"] = str(texture.path)
            else:
                pixels = srgb_to_linear(texture.pixels) if texture.srgb and colour else texture.pixels
                result["bitmap"] = mi.Bitmap(np.ascontiguousarray(pixels[..., :3], dtype=np.float32))
            self._textures[key] = result
        return self._textures[key]

    def environment(self, texture: Texture) -> dict:
        """``filename`` or ``bitmap`` entries of an ``envmap`` (linear RGB)."""
        import mitsuba as mi

        if texture.path is not None:
            return {"filename": str(texture.path)}
        pixels = srgb_to_linear(texture.pixels) if texture.srgb else texture.pixels
        return {"bitmap": mi.Bitmap(np.ascontiguousarray(pixels[..., :3], dtype=np.float32))}

    def scratch_bsdf(self, material: ScratchedMetal, *, key: str) -> dict:
        from ..bsdf import plugin_dict

        scratches = material.scratches if material.scratches.count else None  # None: unscratched metal
        return plugin_dict(scratches, **scratch_plugin_settings(material), **self.footprint)

    def medium(self, key: str, medium: dict):
        """The medium ``medium`` loaded once per ``key`` (the camera and every shape in it share the object)."""
        if key not in self._media:
            self._media[key] = load_dict(medium)
        return self._media[key]

    def shape(self, shape: Shape, bsdf: dict, emitter: dict | None, *, material_key: str, media: dict | None = None):
        """An ``mi.Mesh`` in world space, filled from numpy, with its BSDF (shared per material) and the
        ``interior``/``exterior`` media of ``media`` (objects from :meth:`medium`)."""
        positions, faces, normals = world_geometry(shape)
        return self._mesh(shape.name, positions, faces, normals, shape.mesh, bsdf, emitter, material_key, media)

    def instanced_shape(self, mesh: MeshData, bsdf: dict, *, material_key: str, media: dict | None = None):
        """An ``mi.Mesh`` in object space for a ``shapegroup`` (its instances place it)."""
        return self._mesh(mesh.name, mesh.positions, mesh.faces, mesh.normals, mesh, bsdf, None, material_key, media)

    def _mesh(self, name, positions, faces, normals, mesh: MeshData, bsdf, emitter, material_key, media):
        import mitsuba as mi

        if material_key not in self._bsdfs:
            self._bsdfs[material_key] = load_dict(bsdf)
        props = mi.Properties()
        props["bsdf"] = self._bsdfs[material_key]
        if emitter is not None:
            props["emitter"] = load_dict(emitter)
        for side, medium in (media or {}).items():
            props[side] = medium
        uvs = mesh.uvs
        result = mi.Mesh(name, len(positions), len(faces), props=props,
                         has_vertex_normals=normals is not None, has_vertex_texcoords=uvs is not None)
        if mesh.generated is not None:  # Blender's Generated coordinates, read by the ``generated`` texture
            result.add_attribute(GENERATED_ATTRIBUTE, 3, mesh_buffer(mi.Float, mesh.generated))
        params = mi.traverse(result)
        params["vertex_positions"] = mesh_buffer(mi.Float, positions)
        params["faces"] = mesh_buffer(mi.UInt32, faces, np.uint32)
        if normals is not None:
            params["vertex_normals"] = mesh_buffer(mi.Float, normals)
        if uvs is not None:
            params["vertex_texcoords"] = mesh_buffer(mi.Float, uvs)
        params.update()
        return result


def mesh_buffer(kind, values, dtype=np.float32):
    """A flat Dr.Jit array ``kind`` (``mi.Float``; ``mi.UInt32`` with ``dtype=np.uint32``) of a mesh
    attribute, on a 64-byte boundary.

    Dr.Jit's CPU backend maps numpy's memory without copying and gathers from it
    in packets or element by element depending on its alignment: a buffer that
    lands wherever ``malloc`` puts it gives every process other kernels, which
    then miss Dr.Jit's kernel cache and compile again (the height field's for
    ~45 s on a 2-core machine; docs/bsdf.md, Performance).
    """
    return aligned_array(kind, np.ascontiguousarray(values, dtype=dtype).ravel())


def scratch_plugin_settings(material: ScratchedMetal) -> dict:
    """The ``scratch_diffraction`` plugin's settings for ``material``, all but its scratches: the one
    mapping of :class:`...scene.ScratchedMetal` to the plugin (rendering, export and the session's updates)."""
    settings = dict(coherence_diameter=material.coherence_diameter_m, unit_scale=material.metres_per_unit,
                    material=material.material, coherent=material.coherent, crossings=material.crossings,
                    depth_phase=material.depth_phase)
    if material.diffuse_reflectance is not None and any(c > 0 for c in material.diffuse_reflectance):
        settings["diffuse_reflectance"] = {"type": "rgb", "value": [float(c) for c in material.diffuse_reflectance]}
    return settings
