"""The export folder's resources: meshes, textures and scratch sets written beside ``scene.xml``.

:class:`ToFolder` is the builder's resources object for an export (:mod:`...builder.resources` says
what a resources object does): meshes are written once per mesh as PLY files in object space and
placed with ``to_world``, textures are copied or written as EXR, scratch sets as format-v1 files;
the scene dict references them by paths relative to the folder.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from .. import scratch as scratch_io
from ..bsdf import plugin_dict
from ..builder.resources import bitmap_options, safe_name, scratch_plugin_settings
from ..builder.transform import to_mitsuba
from ..files.exr import write_exr
from ..scene import MeshData, ScratchedMetal, Shape, Texture
from ..scene.colour import srgb_to_linear
from .ply import write_ply

__all__ = ["ToFolder"]


class ToFolder:
    """Resources for a self-contained export folder (paths in the dict are relative to it)."""

    shares_materials = True  #: materials are top-level entries of the XML that shapes reference
    #: ``plugin_dict`` keywords of the render's footprint filter (:func:`...builder.camera.footprint_settings`)
    footprint: dict = {}

    def __init__(self, folder):
        self.folder = Path(folder)
        self._meshes: dict[int, str] = {}
        self._textures: dict[str, str] = {}
        self._names: set[str] = set()

    def _unique(self, subfolder: str, name: str, suffix: str) -> str:
        base = f"{subfolder}/{safe_name(name)}"
        candidate, index = base + suffix, 1
        while candidate in self._names:
            candidate, index = f"{base}_{index:03d}{suffix}", index + 1
        self._names.add(candidate)
        (self.folder / subfolder).mkdir(parents=True, exist_ok=True)
        return candidate

    def _texture_file(self, texture: Texture) -> str:
        if texture.name not in self._textures:
            if texture.path is not None:
                suffix = Path(texture.path).suffix.lower() or ".png"
                relative = self._unique("textures", Path(texture.name).stem, suffix)
                shutil.copyfile(texture.path, self.folder / relative)
            else:
                relative = self._unique("textures", Path(texture.name).stem, ".exr")
                pixels = srgb_to_linear(texture.pixels) if texture.srgb else texture.pixels
                write_exr(self.folder / relative, pixels[..., :3])
            self._textures[texture.name] = relative
        return self._textures[texture.name]

    def texture(self, texture: Texture, *, colour: bool) -> dict:
        return {"type": "bitmap", "filename": self._texture_file(texture), **bitmap_options(texture, colour)}

    def environment(self, texture: Texture) -> dict:
        return {"filename": self._texture_file(texture)}

    def scratch_bsdf(self, material: ScratchedMetal, *, key: str) -> dict:
        if not material.scratches.count:
            return plugin_dict(**scratch_plugin_settings(material), **self.footprint)
        relative = self._unique("scratches", key, ".npz")
        scratch_io.save(material.scratches, self.folder / relative)
        return plugin_dict(filename=relative, **scratch_plugin_settings(material), **self.footprint)

    def medium(self, key: str, medium: dict) -> dict:
        """The medium, written where it is used (the XML repeats it; every copy is the same medium)."""
        return medium

    def shape(self, shape: Shape, bsdf: dict, emitter: dict | None, *, material_key: str,
              media: dict | None = None) -> dict:
        """A ``ply`` shape: the mesh file is written once and shared by its instances."""
        result = {"type": "ply", "filename": self._ply(shape.mesh), "to_world": to_mitsuba(shape.to_world),
                  "bsdf": bsdf, **(media or {})}
        if emitter is not None:
            result["emitter"] = emitter
        return result

    def instanced_shape(self, mesh: MeshData, bsdf: dict, *, material_key: str, media: dict | None = None) -> dict:
        """A ``ply`` shape in object space for a ``shapegroup``."""
        return {"type": "ply", "filename": self._ply(mesh), "bsdf": bsdf, **(media or {})}

    def _ply(self, mesh: MeshData) -> str:
        if id(mesh) not in self._meshes:
            relative = self._unique("meshes", mesh.name, ".ply")
            write_ply(self.folder / relative, mesh.positions, mesh.faces, mesh.normals, mesh.uvs, mesh.generated)
            self._meshes[id(mesh)] = relative
        return self._meshes[id(mesh)]
