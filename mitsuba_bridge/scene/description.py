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
* Every number is checked once, here, for every user of the description (the
  add-on's gather, the live session, scripts): a film size is a whole number of
  pixels, matrices are finite 4×4 affine matrices (frames also invertible), a
  field of view lies strictly between 0° and 180°, powers, colours and
  directions are finite.  A violation is a
  :class:`~mitsuba_bridge.errors.ParameterError` (a ``ValueError`` and a user
  error) naming the field, never a silently replaced value.
* Colours are linear Rec.709 RGB triples; radiometric quantities are physical:
  W/sr (point, spot), W/m² (sun), W/(m²·sr) (area lights, emission, world).
* UV coordinates are Blender's (v up, image row 0 at the top of the texture
  maps to v = 1); the builder flips image lookups, never the UVs, because the
  scratch sets live in exactly these UVs.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Optional, Union

import numpy as np

from ..errors import ParameterError
from .materials import RGB, Texture, Volume

__all__ = ["Film", "Camera", "MeshData", "Shape", "PointLight", "SpotLight", "SunLight", "AreaLight", "Light",
           "ConstantWorld", "EnvironmentWorld", "SkyWorld", "World", "RenderSettings", "SceneDescription", "SAMPLERS",
           "FILTERS", "LIGHT_TYPES", "WORLD_TYPES", "orthonormal", "affine"]

#: Reconstruction filters offered to users.  Box is the default: glints are
#: sub-pixel, a Gaussian smears them and filters with negative lobes ring.
FILTERS = ("box", "tent", "gaussian")


def _whole(name: str, value, minimum: int | None = None) -> int:
    """``value`` as an int: an integer (not a bool, not a float such as NaN), at least ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be a whole number, got {value!r}")
    if minimum is not None and value < minimum:
        raise ParameterError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


def _finite(name: str, value, *, low: float | None = None, high: float | None = None,
            open_interval: bool = False) -> float:
    """``value`` as a finite float, within ``[low, high]`` (``(low, high)`` with ``open_interval``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    value = float(value)
    below = low is not None and (value <= low if open_interval else value < low)
    above = high is not None and (value >= high if open_interval else value > high)
    if below or above:
        brackets = "()" if open_interval else "[]"
        raise ParameterError(f"{name} must lie in {brackets[0]}{low if low is not None else '-inf'}, "
                             f"{high if high is not None else 'inf'}{brackets[1]}, got {value!r}")
    return value


def _triple(name: str, value, *, nonzero: bool = False) -> tuple[float, float, float]:
    """Three finite numbers (a colour, a power, a position, a direction: ``nonzero``)."""
    try:
        values = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be three numbers, got {value!r}") from None
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise ParameterError(f"{name} must be three finite numbers, got {value!r}")
    if nonzero and not np.any(values):
        raise ParameterError(f"{name} must not be zero")
    return tuple(float(v) for v in values)


def affine(name: str, matrix) -> np.ndarray:
    """``matrix`` as a finite 4×4 affine float64 matrix (last row 0, 0, 0, 1), else :class:`ParameterError`."""
    try:
        matrix = np.array(matrix, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a 4×4 matrix, got {type(matrix).__name__}") from None
    if matrix.shape != (4, 4):
        raise ParameterError(f"{name} must be a 4×4 matrix, got shape {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise ParameterError(f"{name} holds NaN or infinite values")
    if not np.array_equal(matrix[3], [0.0, 0.0, 0.0, 1.0]):
        raise ParameterError(f"{name} is not an affine transform (its last row is {matrix[3].tolist()}, not "
                             "[0, 0, 0, 1])")
    return matrix


def orthonormal(matrix: np.ndarray, name: str = "matrix") -> np.ndarray:
    """``matrix`` (4×4) with its scale and shear removed, keeping rotation and translation.

    The nearest rotation in the Frobenius norm (from the SVD); a mirroring
    matrix gives the proper rotation that flips the local Z axis back.  A
    matrix with no frame to keep (zero scale along some axis) is refused.
    """
    matrix = affine(name, matrix)
    u, singular, vt = np.linalg.svd(matrix[:3, :3])
    if not singular[-1] > 1e-12 * max(singular[0], 1e-300):
        raise ParameterError(f"{name} has zero scale along an axis (a singular matrix): it has no frame")
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
        object.__setattr__(self, "width", _whole("film width", self.width, 1))
        object.__setattr__(self, "height", _whole("film height", self.height, 1))
        if self.filter not in FILTERS:
            raise ParameterError(f"unknown filter {self.filter!r}; expected one of {FILTERS}")
        if self.crop is not None:
            if not isinstance(self.crop, (tuple, list)) or len(self.crop) != 4:
                raise ParameterError(f"crop window must be (x, y, w, h), got {self.crop!r}")
            x, y, w, h = (_whole("crop window", value) for value in self.crop)
            object.__setattr__(self, "crop", (x, y, w, h))
            if w < 1 or h < 1 or x < 0 or y < 0 or x + w > self.width or y + h > self.height:
                raise ParameterError(f"crop window {self.crop} outside the {self.width} x {self.height} frame")

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
        object.__setattr__(self, "to_world", orthonormal(self.to_world, "camera matrix"))
        if self.projection not in ("perspective", "orthographic"):
            raise ParameterError(f"unknown projection {self.projection!r}")
        _finite("field of view (degrees)", self.fov_x_deg, low=0.0, high=180.0, open_interval=True)
        _finite("orthographic width", self.ortho_width, low=0.0, open_interval=True)
        _finite("lens shift x", self.shift_x)
        _finite("lens shift y", self.shift_y)
        near, far = _finite("near clipping distance", self.near), _finite("far clipping distance", self.far)
        if not 0.0 < near < far:
            raise ParameterError(f"clipping range must satisfy 0 < near < far, got {near}, {far}")


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

    def __post_init__(self):
        # (zero scale is allowed: Blender hides objects so, and their triangles are merely degenerate)
        object.__setattr__(self, "to_world", affine(f"shape {self.name!r}: matrix", self.to_world))


# ---- lights and world ------------------------------------------------------------------------

@dataclass(frozen=True)
class PointLight:
    """Isotropic point (``radius`` 0) or spherical light; ``intensity`` in W/sr."""

    position: tuple[float, float, float]
    intensity: RGB
    radius: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "position", _triple("point light position", self.position))
        object.__setattr__(self, "intensity", _triple("point light intensity", self.intensity))
        _finite("point light radius", self.radius, low=0.0)


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
        object.__setattr__(self, "to_world", orthonormal(self.to_world, "spot light matrix"))
        object.__setattr__(self, "intensity", _triple("spot light intensity", self.intensity))
        _finite("spot light cutoff angle (degrees)", self.cutoff_deg, low=0.0, high=180.0)
        _finite("spot light beam angle (degrees)", self.beam_deg, low=0.0, high=180.0)


@dataclass(frozen=True)
class SunLight:
    """A distant light; ``direction`` points from the light into the scene."""

    direction: tuple[float, float, float]
    irradiance: RGB  #: W/m² on a surface facing the light

    def __post_init__(self):
        object.__setattr__(self, "direction", _triple("sun direction", self.direction, nonzero=True))
        object.__setattr__(self, "irradiance", _triple("sun irradiance", self.irradiance))


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
            raise ParameterError(f"unknown area light shape {self.shape!r}")
        object.__setattr__(self, "to_world", affine("area light matrix", self.to_world))
        _finite("area light size x", self.size_x, low=0.0)
        _finite("area light size y", self.size_y, low=0.0)
        object.__setattr__(self, "radiance", _triple("area light radiance", self.radiance))


Light = Union[PointLight, SpotLight, SunLight, AreaLight]
LIGHT_TYPES = (PointLight, SpotLight, SunLight, AreaLight)


@dataclass(frozen=True)
class ConstantWorld:
    """Uniform background radiance."""

    radiance: RGB

    def __post_init__(self):
        object.__setattr__(self, "radiance", _triple("world colour", self.radiance))


@dataclass(frozen=True)
class EnvironmentWorld:
    """An equirectangular environment map in Blender's orientation.

    ``rotation`` (3×3) maps world directions to the directions at which the
    image is looked up (Blender's Mapping node); ``strength`` scales it.
    """

    texture: Texture
    strength: float = 1.0
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self):
        _finite("world strength", self.strength)
        rotation = np.asarray(self.rotation, dtype=np.float64)
        if rotation.shape != (3, 3) or not np.all(np.isfinite(rotation)):
            raise ParameterError(f"world rotation must be a finite 3×3 matrix, got shape {rotation.shape}")


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

    def __post_init__(self):
        object.__setattr__(self, "sun_direction", _triple("sun direction", self.sun_direction, nonzero=True))
        for name in ("turbidity", "albedo", "sun_scale", "sky_scale", "sun_aperture_deg"):
            _finite(f"sky {name}", getattr(self, name))


World = Union[ConstantWorld, EnvironmentWorld, SkyWorld]
WORLD_TYPES = (ConstantWorld, EnvironmentWorld, SkyWorld)


# ---- the whole scene -------------------------------------------------------------------------

#: Mitsuba's samplers a render may use: ``independent`` (uniform random numbers: the default) and ``multijitter``
#: (correlated multi-jittered: stratified in 2D and in 1D within each chunk of the schedule; less noise on
#: surfaces, but measured 3 % too bright in two of the volume scenes Cycles checks: Mitsuba's multijitter at 4 spp
#: per call, the small films' chunk size; not yet explained).
#: docs/rendering.md, The sampler, says why these two, what the choice costs and why it is not the default.
SAMPLERS = ("multijitter", "independent")


@dataclass(frozen=True)
class RenderSettings:
    """How to render, as opposed to what."""

    spp: int = 64
    max_depth: int = 8
    seed: int = 0
    variant: str = "auto"
    #: average the scratch BSDFs over each sample's share of its pixel (docs/model.md §11). Off by default until far
    #: views are bounded (docs/model.md §11: without aggregates a footprint holding many pieces visits them all)
    footprint_filter: bool = False
    #: also render Blender's data passes (Depth, Denoising Albedo and Normal; F12 when the view layer asks)
    data_passes: bool = False
    #: Mitsuba's sampler, one of :data:`SAMPLERS` (written into scene.xml)
    sampler: str = "independent"

    def __post_init__(self):
        _whole("spp", self.spp, 1)
        if _whole("max_depth", self.max_depth) < 1 and self.max_depth != -1:
            raise ParameterError("max_depth must be >= 1 (or -1 for unlimited)")
        _whole("seed", self.seed)
        if not isinstance(self.variant, str):
            raise ParameterError(f"variant must be a name, got {self.variant!r}")
        if not isinstance(self.data_passes, (bool, np.bool_)):
            raise ParameterError(f"data_passes must be True or False, got {self.data_passes!r}")
        if self.sampler not in SAMPLERS:
            raise ParameterError(f"sampler must be one of {', '.join(SAMPLERS)}, got {self.sampler!r}")


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
        for name, value, kind in (("film", self.film, Film), ("camera", self.camera, Camera)):
            if not isinstance(value, kind):
                raise ParameterError(f"the scene's {name} must be a {kind.__name__}, got {type(value).__name__}")
        for shape in self.shapes:
            if not isinstance(shape, Shape):
                raise ParameterError(f"a shape must be a Shape, got {type(shape).__name__}")
            if shape.material not in self.materials:
                raise ParameterError(f"shape {shape.name!r} uses unknown material {shape.material!r}")
        for light in self.lights:
            if not isinstance(light, LIGHT_TYPES):
                raise ParameterError(f"a light must be one of {', '.join(t.__name__ for t in LIGHT_TYPES)}, got "
                                     f"{type(light).__name__}")
        if self.world is not None and not isinstance(self.world, WORLD_TYPES):
            raise ParameterError(f"the world must be one of {', '.join(t.__name__ for t in WORLD_TYPES)} or None, "
                                 f"got {type(self.world).__name__}")
        if self.world_volume is not None and not isinstance(self.world_volume, Volume):
            raise ParameterError(f"the world's volume must be a Volume or None, got {type(self.world_volume).__name__}")

    @property
    def triangle_count(self) -> int:
        return sum(shape.mesh.triangle_count for shape in self.shapes)
