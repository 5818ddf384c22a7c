"""The neutral scene description: what the Blender side gathers, what the builder turns into Mitsuba.

Plain frozen dataclasses holding numpy arrays and numbers, no Mitsuba and no
Blender types, so that gathering (``addon.render.gather``) and building
(``mitsuba_bridge.builder``) are tested separately and a scene can be made in
code without either program.

Conventions
-----------
* World space is Blender's: right-handed, +Z up, lengths in scene units
  (metres × ``ScratchedMetal.metres_per_unit``).
* Matrices are 4×4 float64, column vectors (``p_world = M @ p_local``).
* ``Camera.to_world`` and the light matrices keep Blender's local frames: a
  camera looks along its local −Z with +Y up, spot and area lights shine along
  their local −Z.  The builder converts to Mitsuba's frames.
* Frames that must not scale are made orthonormal here, once, whoever builds
  the description: ``Camera.to_world`` and ``SpotLight.to_world`` keep rotation
  and translation and lose scale and shear (:func:`orthonormal`), so a scaled
  camera or spot object in Blender renders as an unscaled one.  Area lights
  keep their matrix: its scale is the emitter's size.  Gathering and building
  rely on this and never normalise frames themselves.
* Colours are linear Rec.709 RGB triples; radiometric quantities are physical:
  W/sr (point, spot), W/m² (sun), W/(m²·sr) (area lights, emission, world).
* UV coordinates are Blender's (v up, image row 0 at the top of the texture
  maps to v = 1); the builder flips image lookups, never the UVs, because the
  scratch sets live in exactly these UVs.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional, Union

import numpy as np

from .materials import RGB, Texture, Volume

__all__ = ["Film", "Camera", "MeshData", "Shape", "PointLight", "SpotLight", "SunLight", "AreaLight", "Light",
           "ConstantWorld", "EnvironmentWorld", "SkyWorld", "World", "RenderSettings", "SceneDescription",
           "FILTERS", "orthonormal"]

#: Reconstruction filters offered to users.  Box is the default: glints are
#: sub-pixel, a Gaussian smears them and filters with negative lobes ring.
FILTERS = ("box", "tent", "gaussian")


def orthonormal(matrix: np.ndarray) -> np.ndarray:
    """``matrix`` (4×4) with its scale and shear removed, keeping rotation and translation.

    The nearest rotation in the Frobenius norm (from the SVD); a mirroring
    matrix gives the proper rotation that flips the local Z axis back.
    """
    matrix = np.asarray(matrix, dtype=np.float64)
    if matrix.shape != (4, 4) or not np.all(np.isfinite(matrix)):
        raise ValueError(f"expected a finite 4×4 matrix, got shape {matrix.shape}")
    u, _, vt = np.linalg.svd(matrix[:3, :3])
    rotation = u @ vt
    if np.linalg.det(rotation) < 0:  # a mirroring matrix: keep a proper rotation
        rotation = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    result = np.eye(4)
    result[:3, :3] = rotation
    result[:3, 3] = matrix[:3, 3]
    return result


@dataclass(frozen=True)
class Film:
    """Image size and region.

    ``width``/``height`` are the full frame in pixels (resolution × percentage);
    ``crop`` is ``(x, y, w, h)`` of the rendered window in pixels with the origin
    at the top-left corner (Mitsuba's convention), or None for the full frame.
    """

    width: int
    height: int
    crop: Optional[tuple[int, int, int, int]] = None
    filter: str = "box"
    transparent: bool = False  #: background pixels get alpha 0 and no direct world colour

    def __post_init__(self):
        if self.width < 1 or self.height < 1:
            raise ValueError(f"film size must be positive, got {self.width} x {self.height}")
        if self.filter not in FILTERS:
            raise ValueError(f"unknown filter {self.filter!r}; expected one of {FILTERS}")
        if self.crop is not None:
            x, y, w, h = self.crop
            if w < 1 or h < 1 or x < 0 or y < 0 or x + w > self.width or y + h > self.height:
                raise ValueError(f"crop window {self.crop} outside the {self.width} x {self.height} frame")

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the rendered image: the crop window if any."""
        return (self.crop[2], self.crop[3]) if self.crop else (self.width, self.height)


@dataclass(frozen=True)
class Camera:
    """A pinhole or orthographic camera.

    Attributes
    ----------
    to_world:
        Camera-to-world matrix (Blender's camera frame: looks along −Z, +Y up);
        stored orthonormal (scale and shear removed).
    projection:
        ``"perspective"`` or ``"orthographic"``.
    fov_x_deg:
        Full horizontal field of view of the whole frame (perspective).
    ortho_width:
        Full horizontal extent of the frame in scene units (orthographic).
    shift_x, shift_y:
        Offset of the image window, as fractions of the frame's width and
        height; positive moves the window right and up (Blender's lens shift).
    near, far:
        Clipping distances in scene units.
    """

    to_world: np.ndarray
    projection: str = "perspective"
    fov_x_deg: float = 39.6
    ortho_width: float = 2.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    near: float = 0.1
    far: float = 1000.0

    def __post_init__(self):
        object.__setattr__(self, "to_world", orthonormal(self.to_world))
        if self.projection not in ("perspective", "orthographic"):
            raise ValueError(f"unknown projection {self.projection!r}")
        if not 0.0 < self.near < self.far:
            raise ValueError(f"clipping range must satisfy 0 < near < far, got {self.near}, {self.far}")


# ---- geometry --------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class MeshData:
    """A triangle mesh in object space.

    ``positions`` (N, 3) float32, ``faces`` (M, 3) uint32, optional per-vertex
    ``normals`` (N, 3) float32 (None: flat shading) and ``uvs`` (N, 2) float32.
    ``generated`` (N, 3) float32 are Blender's Generated texture coordinates (the
    mesh's texture space mapped to [0, 1]³), given when a material looks textures
    up there. Several shapes (instances) may share one MeshData.
    """

    name: str
    positions: np.ndarray
    faces: np.ndarray
    normals: Optional[np.ndarray] = None
    uvs: Optional[np.ndarray] = None
    generated: Optional[np.ndarray] = None

    def __post_init__(self):
        n = len(self.positions)
        if self.positions.ndim != 2 or self.positions.shape[1] != 3:
            raise ValueError(f"mesh {self.name!r}: positions must be (N, 3)")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise ValueError(f"mesh {self.name!r}: faces must be (M, 3)")
        if self.normals is not None and self.normals.shape != (n, 3):
            raise ValueError(f"mesh {self.name!r}: normals must be (N, 3)")
        if self.uvs is not None and self.uvs.shape != (n, 2):
            raise ValueError(f"mesh {self.name!r}: uvs must be (N, 2)")
        if self.generated is not None and self.generated.shape != (n, 3):
            raise ValueError(f"mesh {self.name!r}: generated coordinates must be (N, 3)")
        if len(self.faces) and int(self.faces.max()) >= n:
            raise ValueError(f"mesh {self.name!r}: face index out of range")

    @property
    def triangle_count(self) -> int:
        return len(self.faces)


@dataclass(frozen=True, eq=False)
class Shape:
    """One mesh placed in the world with one material (a key of ``SceneDescription.materials``)."""

    name: str
    mesh: MeshData
    to_world: np.ndarray
    material: str


# ---- lights and world ------------------------------------------------------------------------

@dataclass(frozen=True)
class PointLight:
    """Isotropic point (``radius`` 0) or spherical light; ``intensity`` in W/sr."""

    position: tuple[float, float, float]
    intensity: RGB
    radius: float = 0.0


@dataclass(frozen=True)
class SpotLight:
    """A spot shining along its local −Z; ``intensity`` (W/sr) on the axis.

    The intensity falls from 1 at ``beam_deg`` to 0 at ``cutoff_deg`` (angles
    from the axis).  ``to_world`` is stored orthonormal: a spot has a position
    and a direction, no size.
    """

    to_world: np.ndarray
    intensity: RGB
    cutoff_deg: float
    beam_deg: float

    def __post_init__(self):
        object.__setattr__(self, "to_world", orthonormal(self.to_world))


@dataclass(frozen=True)
class SunLight:
    """A distant light; ``direction`` points from the light into the scene."""

    direction: tuple[float, float, float]
    irradiance: RGB  #: W/m² on a surface facing the light


@dataclass(frozen=True)
class AreaLight:
    """A one-sided Lambertian emitter shining along its local −Z.

    ``to_world`` places a ``shape`` (``"rectangle"`` or ``"disk"``) of full size
    ``size_x`` × ``size_y`` (local units, the matrix may scale it further).
    """

    to_world: np.ndarray
    shape: str
    size_x: float
    size_y: float
    radiance: RGB

    def __post_init__(self):
        if self.shape not in ("rectangle", "disk"):
            raise ValueError(f"unknown area light shape {self.shape!r}")


Light = Union[PointLight, SpotLight, SunLight, AreaLight]


@dataclass(frozen=True)
class ConstantWorld:
    """Uniform background radiance."""

    radiance: RGB


@dataclass(frozen=True)
class EnvironmentWorld:
    """An equirectangular environment map in Blender's orientation.

    ``rotation`` (3×3) maps world directions to the directions at which the
    image is looked up (Blender's Mapping node); ``strength`` scales it.
    """

    texture: Texture
    strength: float = 1.0
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))


@dataclass(frozen=True)
class SkyWorld:
    """Physically based sun and sky (Mitsuba's ``sunsky``, Hosek–Wilkie).

    ``sun_direction`` points from the scene towards the sun; the scales
    multiply the model's radiance (0 switches a part off).
    """

    sun_direction: tuple[float, float, float]
    turbidity: float = 3.0
    albedo: float = 0.3
    sun_scale: float = 1.0
    sky_scale: float = 1.0
    sun_aperture_deg: float = 0.5338


World = Union[ConstantWorld, EnvironmentWorld, SkyWorld]


# ---- the whole scene -------------------------------------------------------------------------

@dataclass(frozen=True)
class RenderSettings:
    """How to render, as opposed to what."""

    spp: int = 64
    max_depth: int = 8
    seed: int = 0
    variant: str = "auto"
    #: average the scratch BSDFs over each sample's share of its pixel (docs/model.md §11); off for validation
    footprint_filter: bool = True
    #: also render Blender's data passes (Depth, Denoising Albedo and Normal; F12 when the view layer asks)
    data_passes: bool = False

    def __post_init__(self):
        if self.spp < 1:
            raise ValueError("spp must be at least 1")
        if self.max_depth < 1 and self.max_depth != -1:
            raise ValueError("max_depth must be >= 1 (or -1 for unlimited)")


@dataclass(frozen=True, eq=False)
class SceneDescription:
    """Everything the builder needs, plus the warnings met while gathering it.

    ``world_volume`` fills all space outside the closed meshes that carry a volume of their own (Blender's
    world Volume output): the camera, the lights and every surface sit in it.
    """

    film: Film
    camera: Camera
    shapes: tuple[Shape, ...] = ()
    materials: dict = field(default_factory=dict)  # key -> Material
    lights: tuple = ()
    world: Optional[World] = None
    warnings: tuple[str, ...] = ()
    world_volume: Optional[Volume] = None

    def __post_init__(self):
        for shape in self.shapes:
            if shape.material not in self.materials:
                raise ValueError(f"shape {shape.name!r} uses unknown material {shape.material!r}")

    @property
    def triangle_count(self) -> int:
        return sum(shape.mesh.triangle_count for shape in self.shapes)
