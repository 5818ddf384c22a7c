"""Interactive rendering: one loaded scene, updated in place and refined pass after pass.

This is the bpy-free core of the viewport's Rendered shading (the engine's
``view_update``/``view_draw`` are a thin adapter over it); tests, benchmarks
and scripts use it directly.

.. code-block:: python

    session = Session(description, settings, samples=1024)   # sets up settings.variant itself
    progress = session.step(0.1)          # passes for up to 0.1 s: Progress(image, spp_done, ...)
    session.set_camera(camera)            # the sensor's parameters only, no kernel compiled
    session.set_scratches("scratches:Plate", scratch_set)   # the BSDF's tables only
    session.set_transform("Plate", matrix)                   # that shape's vertices only
    session.set_light(0, light); session.set_world(world); session.set_material(key, material)
    session.set_film(film)                # a new viewport size: rebuilds (new kernels)
    session.apply(Update(Change.CAMERA, (camera,)))          # the same, as a record (the viewport's queue)
    session.stats                         # kernels_compiled, passes, last_update, rebuilds, ...
    session.close()

Progressive schedule (fixed, so that every pass size compiles once and a
session is reproducible): after each change the first pass renders one sample
at ``1/start_divisor`` of the resolution (shown enlarged), then full-resolution
passes of one sample follow, up to ``samples``.  On the CPU a full-resolution
pass is rendered in horizontal strips of at most ``CPU_STRIP_PIXELS`` pixels
(the rows above the strip in flight already show the new sample): a kernel
cannot be interrupted, so a change waits for the strip in flight, not for a
whole pass.  Every strip is the same small film seen through a camera aimed at
its rows (:func:`.builder.window_camera`), one kernel for all strips.  On a GPU
a pass is one launch, and from the fifth pass on it renders ``BATCH_SPP``
samples (fewer per-call overheads once the picture has settled).  Render *i*
after a change (preview, strip or pass) uses the sampler seed
``pass_seed(settings.seed, i)``, so the image after *n* renders is exactly the
one a freshly built session gives after the same *n* renders.

Every update either changes parameters in place through ``mi.traverse`` (kept
opaque, so the kernels stay valid; :mod:`..builder.updates` says which parameters
an edit of the description changes) or, where that cannot express the change
(another camera projection, another light type, a different material kind),
rebuilds the scene from the updated description; either way the accumulation
restarts.  Passes are frozen (``dr.freeze``, :mod:`.freezing`): a camera move
replays the recorded pass without tracing the integrator and the BSDF again;
other updates record it again (about one traced pass).  Methods are not
thread-safe: one thread owns a session.

Inputs are checked as the command line checks its arguments, before anything
changes: the description's own invariants (:mod:`..scene.description`: film
sizes, matrices, fields of view, powers) and the session's (the right kind of
object for each update, light indices and names that exist, a finite
``step``), each a :class:`~mitsuba_bridge.errors.ParameterError` (a
``ValueError``) with a clear message.  A film too large for the memory this
process is allowed is refused before anything is allocated
(:func:`.memory.check_session_memory`), and a closed session refuses every call
with :class:`SessionClosed`.
"""
from __future__ import annotations

import dataclasses
import enum
import math
import numbers
from dataclasses import dataclass
import time

import numpy as np

from .. import builder
from ..builder import updates
from ..device.kernels import KernelCounter
from ..device.variants import on_gpu
from ..errors import ParameterError
from ..scene import (LIGHT_TYPES, WORLD_TYPES, Camera, Film, RenderSettings, SceneDescription, ScratchedMetal,
                     affine)
from ..scene.materials import Material
from ..scratch import ScratchSet
from .activation import activate
from .filtering import footprint_keys, footprint_values, pixel_size
from .freezing import FrozenRender
from .memory import check_session_memory
from .passes import Progress, pass_seed

__all__ = ["Session", "SessionClosed", "Change", "Update", "plan_pass", "strip_windows", "BATCH_SPP",
           "SINGLE_SAMPLE_PASSES", "CPU_STRIP_PIXELS"]

#: Full-resolution passes of one sample after each change (a quick, steady refinement) ...
SINGLE_SAMPLE_PASSES = 4
#: ... then passes of this many samples where a pass is one launch (each size/spp pair is one kernel).
BATCH_SPP = 4
#: On the CPU, full-resolution passes are rendered in strips of at most this many pixels (2¹⁷: about
#: 40 ms of the demo plate on 2 cores), so that a change waits for one strip, not a whole pass.
CPU_STRIP_PIXELS = 1 << 17


class Change(enum.Enum):
    """What an :class:`Update` changes: the session method it calls (``BUILD``: a new session, the caller's)."""

    BUILD = "build"
    CAMERA = "camera"  #: (camera,)
    FILM = "film"  #: (film,)
    TRANSFORM = "transform"  #: (shape name, 4×4 matrix)
    SCRATCHES = "scratches"  #: (material key, scratch set)
    MATERIAL = "material"  #: (material key, material)
    LIGHT = "light"  #: (light index, light)
    WORLD = "world"  #: (world,)


class SessionClosed(RuntimeError):
    """A call on a session after :meth:`Session.close`."""


def _expect(value, kind, what: str):
    """``value`` when it is a ``kind``, else :class:`ParameterError` naming ``what`` was given instead."""
    if not isinstance(value, kind):
        names = " or ".join(k.__name__ for k in (kind if isinstance(kind, tuple) else (kind,)))
        raise ParameterError(f"{what} must be a {names}, got {type(value).__name__}")
    return value


@dataclass(frozen=True)
class Update:
    """One edit of a session's description: ``Session.apply(update)`` calls the method ``change`` names
    with ``args``."""

    change: Change
    args: tuple = ()


def _whole(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ParameterError(f"{name} must be a whole number >= {minimum}, got {value!r}")
    return int(value)


def plan_pass(index: int, spp_done: int, spp_total: int, start_divisor: int,
              batch_spp: int = BATCH_SPP) -> tuple[bool, int]:
    """``(preview, spp)`` of pass ``index`` after a change.

    ``preview`` passes render at ``1/start_divisor`` resolution and do not count
    towards ``spp_done``.  The answer depends on the pass index and sample
    counts only, never on time.  ``batch_spp`` is the sample count of the passes
    after the first ``SINGLE_SAMPLE_PASSES`` (1: every pass renders one sample).
    """
    if index == 0 and start_divisor > 1:
        return True, 1
    remaining = spp_total - spp_done
    full_index = index - (1 if start_divisor > 1 else 0)
    if full_index >= SINGLE_SAMPLE_PASSES and remaining >= batch_spp:
        return False, batch_spp
    return False, 1


def strip_windows(film: Film, max_pixels: int) -> list[tuple[int, int, int, int]]:
    """The strips ``(x, y, w, h)`` (frame pixels) that cover ``film``'s crop window, or the frame.

    As few strips as keep each at most ``max_pixels`` (0: no limit), all of the
    same height (the last may reach past the window's bottom edge: its extra
    rows are not used).  One strip is the whole window.
    """
    x, y, width, height = film.crop or (0, 0, film.width, film.height)
    count = 1 if max_pixels <= 0 else min(height, max(1, -(-width * height // max_pixels)))
    rows = -(-height // count)
    count = -(-height // rows)
    return [(x, y + index * rows, width, rows) for index in range(count)]


def _preview_film(film: Film, divisor: int) -> Film:
    width, height = film.size
    return Film(max(1, -(-width // divisor)), max(1, -(-height // divisor)), filter=film.filter,
                transparent=film.transparent)


def _enlarge(image: np.ndarray, height: int, width: int) -> np.ndarray:
    """Nearest-neighbour enlargement of a preview to the full size (as Cycles shows its start resolution)."""
    rows = np.arange(height) * image.shape[0] // height
    columns = np.arange(width) * image.shape[1] // width
    return image[rows][:, columns]


class Session:
    """A loaded scene that accepts updates and renders progressively (see the module docstring).

    Parameters
    ----------
    description : SceneDescription
        The scene; the film's size (crop window, if any) is the viewport's.
    settings : RenderSettings
        Variant, max depth and seed are used; ``spp`` is replaced by ``samples``.  The session
        activates ``settings.variant`` itself (:func:`.activation.activate`).
    samples : int, optional
        Samples per pixel after which the session stops rendering (default ``settings.spp``).
    start_divisor : int
        The first pass after each change renders at 1/start_divisor resolution (1: no preview).
    freeze : bool
        Replay recorded passes (``dr.freeze``, see :mod:`.freezing`) instead of tracing each one again.
    strip_pixels : int, optional
        Render full-resolution passes in strips of at most this many pixels (0: whole passes).
        Default ``CPU_STRIP_PIXELS`` on the CPU, 0 on a GPU.
    """

    def __init__(self, description: SceneDescription, settings: RenderSettings, *, samples: int | None = None,
                 start_divisor: int = 4, freeze: bool = True, strip_pixels: int | None = None):
        _expect(description, SceneDescription, "the session's description")
        self.settings = _expect(settings, RenderSettings, "the session's settings")
        self.samples = _whole("samples", settings.spp if samples is None else samples, 1)
        self.start_divisor = _whole("start_divisor", start_divisor, 1)
        self._strip_pixels = None if strip_pixels is None else _whole("strip_pixels", strip_pixels, 0)
        self._closed = False
        activate(settings.variant)
        self._counter = KernelCounter()
        self._render = FrozenRender(freeze)
        self._stats = {"passes": 0, "rebuilds": 0, "updates": 0, "last_update": "build",
                       "last_pass_seconds": 0.0, "last_update_seconds": 0.0}
        self._latest: Progress | None = None
        self._load(description)

    # ------------------------------------------------------------------ building
    def _load(self, description: SceneDescription) -> None:
        import mitsuba as mi

        strip_pixels = self._strip_pixels
        if strip_pixels is None:
            strip_pixels = 0 if on_gpu() else CPU_STRIP_PIXELS
        width, height = description.film.size
        check_session_memory(width, height, self.start_divisor, strip_pixels)  # before any film exists
        builder.check_tables_memory(description)
        self.description = description
        # One Mitsuba shape per described shape (no shapegroups): transforms are updated per shape name.
        scene_dict = builder.scene_dict(description, self.settings, instancing=False)
        medium = scene_dict[updates.SENSOR].get("medium")  # the world's volume: every sensor starts in it
        if self.start_divisor > 1:
            preview = _preview_film(description.film, self.start_divisor)
            scene_dict[updates.PREVIEW_SENSOR] = builder.sensor_dict(description.camera, preview, self.settings,
                                                                     medium=medium)
        self._windows = strip_windows(description.film, strip_pixels)
        if len(self._windows) > 1:
            camera, film = builder.window_camera(description.camera, description.film, self._windows[0])
            scene_dict[updates.STRIP_SENSOR] = builder.sensor_dict(camera, film, self.settings, medium=medium)
        self._keys = updates.SceneKeys.of(scene_dict)
        self._scene = builder.load_dict(scene_dict)
        self._params = mi.traverse(self._scene)
        self._footprint_keys = footprint_keys(self._params)
        self._render.reset()
        # The loaded sensors hold their parameters as literals; written once as opaque values now, the
        # first kernels already take them as inputs and no camera move compiles anything.
        self._assign(self._camera_values(description.camera))
        self._restart()

    def _rebuild(self, description: SceneDescription, reason: str) -> None:
        self._load(description)
        self._stats["rebuilds"] += 1
        self._stats["last_update"] = f"rebuild ({reason})"

    def _restart(self) -> None:
        # the footprint filter: each pass's samples share the pixel with the samples before them (docs/model.md
        # §11.2), so the footprint shrinks pass after pass and the running mean converges to the point image
        self._pixel = pixel_size(self._scene) if self._footprint_keys else None
        self._footprint_shown = None
        self._index = 0  #: renders since the change (preview, strips, passes): the seed's index
        self._pass_index = 0  #: passes begun since the change (a pass is all its strips)
        self._strip = 0  #: the next strip of the current pass
        self._plan = (False, 1)
        self._sum = None
        self._spp_done = 0
        self._started = time.perf_counter()
        self._finished = False

    def _updated(self, kind: str, began: float, *, replayable: bool = False) -> None:
        # Frozen passes see new array values only: anything else records them again (one traced pass).
        if not replayable:
            self._render.reset()
        self._stats["updates"] += 1
        self._stats["last_update"] = kind
        self._stats["last_update_seconds"] = time.perf_counter() - began
        self._restart()

    def _assign(self, values: dict) -> None:
        """Write parameters, opaque (a literal would be baked into the kernels), and notify the objects."""
        import drjit as dr

        for key, value in values.items():
            dr.make_opaque(value)
            self._params[key] = value
        self._params.update()

    def _assign_or_rebuild(self, values: dict | None, kind: str, began: float, reason: str) -> None:
        """Write ``values`` in place (an update of ``kind``), or rebuild where there are none (None)."""
        if values is None:
            self._rebuild(self.description, reason)
        else:
            self._assign(values)
            self._updated(kind, began)

    def _sensors(self, camera: Camera) -> list[tuple[str, Camera, Film]]:
        """(traversal prefix, camera, film) of the full-frame and preview sensors."""
        film = self.description.film
        sensors = [(updates.SENSOR + ".", camera, film)]
        if self.start_divisor > 1:
            sensors.append((updates.PREVIEW_SENSOR + ".", camera, _preview_film(film, self.start_divisor)))
        return sensors

    # ------------------------------------------------------------------ updates
    def _check_open(self) -> None:
        if self._closed:
            raise SessionClosed("the session is closed: build a new one")

    def apply(self, update: Update) -> None:
        """Apply ``update`` (one of :class:`Change`; ``BUILD`` is the caller's: it makes a new session)."""
        self._check_open()
        _expect(update, Update, "an update")
        methods = {Change.CAMERA: self.set_camera, Change.FILM: self.set_film, Change.TRANSFORM: self.set_transform,
                   Change.SCRATCHES: self.set_scratches, Change.MATERIAL: self.set_material,
                   Change.LIGHT: self.set_light, Change.WORLD: self.set_world}
        if update.change not in methods:
            raise ParameterError(f"a session cannot apply {update.change}: build a new session")
        method = methods[update.change]
        count = method.__code__.co_argcount - 1
        if not isinstance(update.args, tuple) or len(update.args) != count:
            raise ParameterError(f"a {update.change.name} update takes {count} argument{'s' * (count != 1)}, got "
                                 f"{update.args!r}")
        method(*update.args)

    def set_camera(self, camera: Camera) -> None:
        """Move the view: the sensors' ``to_world``, field of view, shift and clipping, in place."""
        self._check_open()
        _expect(camera, Camera, "the camera")
        began = time.perf_counter()
        previous = self.description.camera
        self.description = dataclasses.replace(self.description, camera=camera)
        if camera.projection != previous.projection:
            self._rebuild(self.description, "projection")
            return
        values = self._camera_values(camera)
        self._assign(values)
        self._updated("camera", began, replayable=not any(key.endswith("_clip") for key in values))

    def _camera_values(self, camera: Camera) -> dict:
        """The sensors' new parameters; the strip sensor's per strip go to ``_strip_values``."""
        values = {}
        for prefix, view, film in self._sensors(camera):
            values.update(self._sensor_values(prefix, view, film))
        if len(self._windows) > 1:
            strips = [builder.window_camera(camera, self.description.film, window) for window in self._windows]
            strip = updates.STRIP_SENSOR + "."
            self._strip_values = [self._sensor_values(strip, view, film, clip=False) for view, film in strips]
            # Which strip the sensor shows (assigning its own values again costs a comparison kernel).
            self._strip_shown = None
            # the strips share their clipping range: written (when it changes) with the other sensors'
            values.update(self._sensor_values(strip, *strips[0]))
        return values

    def _sensor_values(self, prefix: str, camera: Camera, film: Film, *, clip: bool = True) -> dict:
        return updates.sensor_values(self._params, prefix, camera, film, self.settings, clip=clip)

    def set_film(self, film: Film) -> None:
        """Another viewport size or filter: a rebuild (each film size is its own kernel)."""
        self._check_open()
        _expect(film, Film, "the film")
        if film != self.description.film:
            self._rebuild(dataclasses.replace(self.description, film=film), "film")

    def set_transform(self, shape_name: str, matrix) -> None:
        """Place every shape named ``shape_name`` with ``matrix`` (4×4, object → world): its vertices only."""
        self._check_open()
        began = time.perf_counter()
        matrix = affine(f"shape {shape_name!r}: matrix", matrix)
        indices = [i for i, shape in enumerate(self.description.shapes) if shape.name == shape_name]
        if not indices:
            raise ParameterError(f"no shape named {shape_name!r} in the scene")
        shapes = list(self.description.shapes)
        values = {}
        for i in indices:
            old, shapes[i] = shapes[i], dataclasses.replace(shapes[i], to_world=matrix)
            values.update(updates.shape_values(self._keys.shapes[i] + ".", old, shapes[i]))
        self.description = dataclasses.replace(self.description, shapes=tuple(shapes))
        self._assign(values)
        self._updated("transform", began)

    def set_scratches(self, material_key: str, scratches) -> None:
        """Swap the scratch set of the ``scratch_diffraction`` material ``material_key`` (its tables only)."""
        from ..bsdf import update_scratches

        self._check_open()
        _expect(scratches, ScratchSet, "the scratches")
        began = time.perf_counter()
        material = self.description.materials.get(material_key)
        if not isinstance(material, ScratchedMetal):
            raise ParameterError(f"{material_key!r} is not a scratched material of the scene")
        self._replace_material(material_key, dataclasses.replace(material, scratches=scratches))
        prefix = self._bsdf_prefix(material_key)
        if prefix is None:  # no shape uses it: nothing is rendered with it
            self._updated("scratches", began)
            return
        update_scratches(self._params, scratches, prefix=prefix)  # handed to the BSDF, no copies
        # Passes are recorded again (about one traced pass): replaying recordings across new scratch
        # tables crashed Dr.Jit 1.5 (a segmentation fault) even where the table sizes stayed the same.
        self._updated("scratches", began)

    def set_material(self, material_key: str, material) -> None:
        """Replace a material: its BSDF's parameters in place when the kind stays, else a rebuild."""
        self._check_open()
        _expect(material, Material.__args__, "the material")
        began = time.perf_counter()
        old = self.description.materials.get(material_key)
        if old is None:
            raise ParameterError(f"no material {material_key!r} in the scene")
        self._replace_material(material_key, material)
        prefix = self._bsdf_prefix(material_key)
        if prefix is None:
            self._updated("material", began)
            return
        values = updates.material_values(self._params, prefix, old, material, material_key)
        if values is None:
            self._rebuild(self.description, "material kind")
            return
        self._assign(values)
        if isinstance(material, ScratchedMetal) and material.scratches is not old.scratches:
            self.set_scratches(material_key, material.scratches)
        self._updated("material", began)

    def set_light(self, index: int, light) -> None:
        """Replace light ``index`` of the description: its emitter's parameters when the type stays."""
        self._check_open()
        count = len(self.description.lights)
        if isinstance(index, bool) or not isinstance(index, numbers.Integral) or not 0 <= index < count:
            raise ParameterError(f"light index must be a whole number from 0 to {count - 1}, got {index!r}"
                                 if count else f"the scene has no lights (light index {index!r})")
        _expect(light, LIGHT_TYPES, "the light")
        began = time.perf_counter()
        lights = list(self.description.lights)
        old, lights[index] = lights[index], light
        self.description = dataclasses.replace(self.description, lights=tuple(lights))
        values = updates.light_values(self._params, self._keys.light(index), old, light)
        self._assign_or_rebuild(values, "light", began, "light type")

    def set_world(self, world) -> None:
        """Replace the world: its emitter's parameters when the type stays (None: no world, a rebuild)."""
        self._check_open()
        if world is not None:
            _expect(world, WORLD_TYPES, "the world")
        began = time.perf_counter()
        old = self.description.world
        self.description = dataclasses.replace(self.description, world=world)
        values = updates.world_values(self._params, updates.WORLD + ".", old, world)
        self._assign_or_rebuild(values, "world", began, "world type")

    def rebuild(self, description: SceneDescription) -> None:
        """Load ``description`` from scratch (what no in-place update expresses)."""
        self._check_open()
        self._rebuild(_expect(description, SceneDescription, "the description"), "scene")

    def _replace_material(self, key: str, material) -> None:
        materials = dict(self.description.materials)
        materials[key] = material
        self.description = dataclasses.replace(self.description, materials=materials)

    def _bsdf_prefix(self, material_key: str) -> str | None:
        """The traversal prefix of the BSDF shared by the shapes of ``material_key`` (None: unused)."""
        return self._keys.bsdf(self.description.shapes, material_key)

    # ------------------------------------------------------------------ rendering
    @property
    def finished(self) -> bool:
        """Whether ``samples`` are done since the last change (``step`` then renders nothing)."""
        return self._finished

    def step(self, seconds: float = 0.0) -> Progress:
        """Render for up to ``seconds`` (at least one render, unless finished) and return the running image.

        The returned ``Progress`` holds the full-size (H, W, 4) image (an enlarged
        preview until the first full-resolution pass), the full-resolution
        samples done and ``samples`` as the total.  One render is the preview,
        a whole pass, or on the CPU one strip of a pass: the image (and the
        ``Progress`` object returned) changes only when a pass is complete.
        """
        self._check_open()
        if isinstance(seconds, bool) or not isinstance(seconds, numbers.Real) or math.isnan(seconds) or seconds < 0:
            raise ParameterError(f"step takes seconds >= 0 (inf: until finished), got {seconds!r}")
        began = time.perf_counter()
        while not self._finished:
            self._render_pass()
            if time.perf_counter() - began >= seconds:
                break
        return self._latest

    def _render_pass(self) -> None:
        """One render: the preview, one strip of a full-resolution pass, or a whole pass."""
        strips = len(self._windows)
        if self._strip == 0:
            self._plan = plan_pass(self._pass_index, self._spp_done, self.samples, self.start_divisor,
                                   BATCH_SPP if strips == 1 else 1)
        preview, spp = self._plan
        if preview:
            sensor = self._keys.sensor_index(updates.PREVIEW_SENSOR)
        elif strips > 1:
            if self._strip_shown != self._strip:  # opaque values: the recorded strip replays
                self._assign(self._strip_values[self._strip])
                self._strip_shown = self._strip
            sensor = self._keys.sensor_index(updates.STRIP_SENSOR)
        else:
            sensor = self._keys.sensor_index(updates.SENSOR)
        if self._footprint_keys:
            footprint = (1, self.start_divisor) if preview else (self._spp_done + spp, 1)
            if footprint != self._footprint_shown:  # opaque values: the recorded pass replays
                self._assign(footprint_values(self._footprint_keys, self._pixel, footprint[0], scale=footprint[1]))
                self._footprint_shown = footprint
        began = time.perf_counter()
        image = np.asarray(self._render(self._scene, sensor, spp, pass_seed(self.settings.seed, self._index)),
                           dtype=np.float32)
        self._counter.poll()
        self._stats["passes"] += 1
        self._stats["last_pass_seconds"] = time.perf_counter() - began
        self._index += 1
        width, height = self.description.film.size
        if preview:
            shown = _enlarge(image, height, width)
            self._pass_index += 1
        else:
            if self._sum is None:
                self._sum = np.zeros((height, width, image.shape[2]), np.float32)
            top = self._strip * self._windows[0][3]
            bottom = min(height, top + image.shape[0])
            self._sum[top:bottom] += image[:bottom - top] * spp
            self._strip = (self._strip + 1) % strips
            if self._strip:
                return  # the image changes when the pass is complete (no seams of unequal noise)
            self._spp_done += spp
            self._pass_index += 1
            self._finished = self._spp_done >= self.samples
            shown = self._sum / self._spp_done  # a new array: images handed out never change
        self._latest = Progress(self._index, self._spp_done, self.samples, time.perf_counter() - self._started,
                                shown=shown)

    @property
    def showing_preview(self) -> bool:
        """Whether the newest image is (still) the enlarged preview: no full-resolution strip yet."""
        return self._sum is None

    @property
    def stats(self) -> dict:
        """``kernels_compiled`` (since the session began), ``passes`` (renders: previews, strips, passes),
        ``rebuilds``, ``updates``, ``last_update`` (kind), ``last_update_seconds``, ``last_pass_seconds``,
        ``spp_done``, ``samples``, ``strips`` (per full-resolution pass), ``frozen``, ``freeze_failure``,
        ``recordings``."""
        return {**self._stats, "kernels_compiled": self._counter.compiled, "spp_done": self._spp_done,
                "samples": self.samples, "strips": len(self._windows), "frozen": self._render.enabled,
                "freeze_failure": self._render.failure, "recordings": self._render.recordings}

    def close(self) -> None:
        """Release the scene and restore Dr.Jit's kernel-history flag; the session cannot render afterwards."""
        if not self._closed:
            self._closed = True
            self._counter.close()
            self._scene = self._params = self._sum = None
