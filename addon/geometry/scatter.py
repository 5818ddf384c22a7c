"""Scratches placed on a surface: the generator and what every placement shares (no ``bpy``).

Every scratch is traced on the surface (:mod:`.trace`) from its centre, half its
length forward and half backward, so its length is a length *on the surface*
(in surface units; metres after the scene's unit scale) and the centres are
uniform per 3D area.  Where a path crosses a UV seam it is cut into separate
scratches, one per island; where it reaches the mesh boundary it is cut short.

Per-scratch parameters (width, depth, profile, variation, seed) come from
:func:`mitsuba_bridge.scratch.sample_parameters`.  Pieces of one scratch share
its width and depth; each gets its own seed, and its variation frequency is
scaled by its share of the scratch's length so that the noise keeps the same
number of oscillations per metre (the file's frequency is per whole scratch).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...mitsuba_bridge.errors import ParameterError
from ...mitsuba_bridge.scratch import (Distribution, Gaussian, Profile, ScratchSet, Uniform, check_looks,
                                       sample_parameters)
from ...mitsuba_bridge.scratch.noise import hash_uint32
from .surface import Surface
from .trace import SEAM_IN, SEAM_OUT, START, Pieces, assemble, enter_towards, trace_paths

__all__ = ["Looks", "ScatterSpec", "Placed", "scatter", "scratches_from_centres", "build_set", "piece_seeds",
           "empty_placed", "SAGITTA_FRACTION", "MAX_SEGMENTS", "estimate_bytes", "expected_vertices",
           "check_length_range", "MAX_LENGTH_PER_SIZE"]

#: Arcs are cut into straight segments whose sagitta is at most this fraction of the width.
SAGITTA_FRACTION = 0.1
#: At most this many straight segments per arc (beyond it the sagitta rule is relaxed).
MAX_SEGMENTS = 256
#: Longest scratch, in multiples of the surface's size (its bounding box diagonal): a longer one only
#: winds round and round (on a closed surface) or is cut at the boundary anyway.
MAX_LENGTH_PER_SIZE = 100.0
#: Scratches traced per batch (bounds the memory of the temporaries).
CHUNK = 65536
# Rough peak memory per scratch and per vertex while generating (bytes; measured, with margin).
_BYTES_PER_SCRATCH = 1200
_BYTES_PER_VERTEX = 400


@dataclass(frozen=True)
class Looks:
    """What a scratch looks like apart from its path (docs/model.md §7).

    ``width`` and ``depth`` are distributions in metres; the variations are
    (relative amplitude, frequency) as in the scratch file.
    """

    width: Distribution
    depth: Distribution
    profile: Profile = Profile.RECTANGULAR
    width_variation: tuple[float, float] = (0.0, 0.0)
    depth_variation: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self):
        check_looks(width=self.width, depth=self.depth, width_variation=self.width_variation,
                    depth_variation=self.depth_variation)

    def sample(self, rng: np.random.Generator, count: int) -> dict:
        """Per-scratch parameter arrays (the non-geometric fields of a ScratchSet)."""
        return sample_parameters(rng, count, width=self.width, depth=self.depth, profile=self.profile,
                                 width_variation=self.width_variation, depth_variation=self.depth_variation)


@dataclass(frozen=True)
class ScatterSpec:
    """A request for ``count`` scratches scattered uniformly over a surface.

    Lengths are surface units (Blender units of the world-space mesh);
    ``metres_per_unit`` converts them to metres, to compare lengths with widths
    (which are metres, like everything physical).
    ``angle`` None draws directions uniformly; otherwise they are uniform in
    ``angle ± angle_spread`` (radians, from the tangent towards the bitangent).
    ``bend`` is the largest angle (radians) by which a scratch turns along its
    length: each scratch draws its own bend uniformly in [-bend, bend].
    """

    count: int
    length_min: float
    length_max: float
    looks: Looks
    angle: float | None = None
    angle_spread: float = 0.0
    bend: float = 0.0
    metres_per_unit: float = 1.0

    def __post_init__(self):
        # Messages name the operator's properties: this is where its numbers become distributions.
        if self.count < 1:
            raise ParameterError(f"Count is {self.count}: nothing to generate (ask for at least 1 scratch)")
        check_length_range(self.length_min, self.length_max)
        # (1 + 1e-6: a full turn typed into a single-precision property rounds up past 2π.)
        if self.angle is not None and not (math.isfinite(self.angle) and abs(self.angle) <= 2.0 * math.pi * (1 + 1e-6)):
            raise ParameterError(f"Angle must lie within ±360°; got {math.degrees(self.angle):g}°")
        for name, value in (("Spread", self.angle_spread), ("Bend", self.bend)):
            if not 0.0 <= value <= math.pi * (1 + 1e-6):
                raise ParameterError(f"{name} must lie in [0°, 180°]; got {math.degrees(value):g}°")
        if not (math.isfinite(self.metres_per_unit) and self.metres_per_unit > 0):
            raise ParameterError(f"the scene's metres per unit must be > 0; got {self.metres_per_unit:g}")


@dataclass(frozen=True, eq=False)
class Placed:
    """Scratches made on a surface, with what the caller may want to check or report.

    ``source[i]`` is the request (scratch, stroke ...) scratch ``i`` was cut
    from; ``point`` holds the 3D position of every vertex; ``piece_length`` the
    3D length of every scratch; ``requested`` how many scratches were asked for.
    """

    scratches: ScratchSet
    source: np.ndarray
    point: np.ndarray = field(repr=False)
    piece_length: np.ndarray = field(repr=False)
    requested: int = 0
    relaxed_arcs: int = 0  # arcs that needed more than MAX_SEGMENTS segments (sagitta rule relaxed)


def check_length_range(length_min: float, length_max: float, surface: Surface | None = None) -> None:
    """Refuse scratch lengths that are not numbers, not ordered, or (given the surface) absurdly long.

    Lengths are surface units; the limit is :data:`MAX_LENGTH_PER_SIZE` times the surface's size.
    """
    if not (math.isfinite(length_min) and length_min > 0):
        raise ParameterError(f"Length Min must be a length > 0; got {length_min:g}")
    if not math.isfinite(length_max):
        raise ParameterError(f"Length Max must be a finite length; got {length_max:g}")
    if length_max < length_min:
        raise ParameterError("Length Max is below Length Min")
    if surface is not None and length_max > MAX_LENGTH_PER_SIZE * surface.size:
        raise ParameterError(f"Length Max ({length_max:.4g}) is more than {MAX_LENGTH_PER_SIZE:g} times the "
                         f"object's size ({surface.size:.4g}, its bounding box diagonal)")


def estimate_bytes(count: int, vertices_per_scratch: float = 4.0) -> int:
    """Rough peak memory (bytes) to generate ``count`` scratches."""
    return int(count * (_BYTES_PER_SCRATCH + _BYTES_PER_VERTEX * vertices_per_scratch))


def expected_vertices(spec: ScatterSpec) -> float:
    """Expected vertices per scratch from arcs alone (edge crossings come on top)."""
    if spec.bend == 0:
        return 4.0
    width_units = max(_typical(spec.looks.width), 1e-12) / spec.metres_per_unit
    length = 0.5 * (spec.length_min + spec.length_max)
    return 4.0 + float(min(MAX_SEGMENTS, _segments_for(length, 0.5 * spec.bend, width_units)))


def _typical(distribution) -> float:
    """A typical value of a width or depth distribution (metres)."""
    if isinstance(distribution, Uniform):
        return distribution.mean()
    if isinstance(distribution, Gaussian):
        return max(distribution.mean, distribution.std)
    return float(distribution.value)


def _segments_for(length, bend, width_units):
    """Straight segments an arc of total turn ``bend`` needs (sagitta <= SAGITTA_FRACTION * width)."""
    curvature = np.abs(bend) / np.maximum(length, 1e-300)
    with np.errstate(divide="ignore"):
        longest = np.sqrt(8.0 * SAGITTA_FRACTION * width_units / curvature)
    return np.where(curvature > 0, np.ceil(length / longest), 1)


# ------------------------------------------------------------------ generator
def scatter(surface: Surface, spec: ScatterSpec, rng: np.random.Generator) -> Placed:
    """``spec.count`` scratches uniformly over the surface area (see the module docstring)."""
    check_length_range(spec.length_min, spec.length_max, surface)
    count = spec.count
    triangle, bary = surface.sample_points(rng, count)
    length = rng.uniform(spec.length_min, spec.length_max, count)
    if spec.angle is None:
        angle = rng.uniform(0.0, 2.0 * np.pi, count)
    else:
        angle = spec.angle + rng.uniform(-spec.angle_spread, spec.angle_spread, count)
    bend = rng.uniform(-spec.bend, spec.bend, count) if spec.bend > 0 else np.zeros(count)
    params = spec.looks.sample(rng, count)
    direction = surface.direction(triangle, angle)
    return scratches_from_centres(surface, triangle, bary, direction, length, params, bend=bend,
                                  metres_per_unit=spec.metres_per_unit)


def scratches_from_centres(surface: Surface, triangle, bary, direction, length, params: dict, *,
                           bend=None, metres_per_unit: float = 1.0) -> Placed:
    """Scratches centred at given surface points, traced in both directions.

    ``params`` holds one entry per scratch for every non-geometric field of a
    ScratchSet (as :meth:`Looks.sample` returns).
    """
    count = len(triangle)
    bend = np.zeros(count) if bend is None else np.asarray(bend, dtype=np.float64)
    width_units = params["width"] / metres_per_unit
    needed = _segments_for(length, bend, width_units)
    segments = np.minimum(needed, MAX_SEGMENTS)
    turn_every = length / segments
    turn_angle = bend / segments

    sets, sources, points, lengths = [], [], [], []
    for start in range(0, count, CHUNK):
        part = slice(start, min(start + CHUNK, count))
        pieces = _trace_centred(surface, triangle[part], bary[part], direction[part], length[part],
                                turn_angle[part], turn_every[part])
        source = pieces.source + start
        sets.append(build_set(pieces, source, params))
        sources.append(source)
        points.append(pieces.point)
        lengths.append(pieces.length)
    scratches = ScratchSet.concatenate(sets) if sets else ScratchSet.empty()
    return Placed(scratches=scratches, source=_cat(sources, np.int64), point=_cat(points, np.float64, 3),
                  piece_length=_cat(lengths, np.float64), requested=count,
                  relaxed_arcs=int(np.count_nonzero(needed > MAX_SEGMENTS)))


def _trace_centred(surface, triangle, bary, direction, length, turn_angle, turn_every) -> Pieces:
    n = len(triangle)
    # A centre on an edge (a sprayed centre snapped there) starts both halves in a triangle whose plane
    # holds the direction: in the other, the direction may have no component and the scratch vanish.
    triangle, bary = enter_towards(surface, triangle, bary, direction, both_ways=True)
    trace = trace_paths(
        surface, np.r_[triangle, triangle], np.r_[bary, bary], np.r_[direction, -direction],
        np.r_[0.5 * length, 0.5 * length],
        turn_angle=np.r_[turn_angle, -turn_angle], turn_every=np.r_[turn_every, turn_every],
        first_turn=np.r_[0.5 * turn_every, 0.5 * turn_every])
    # The centre is always collinear with its neighbours (the halves start straight in
    # opposite directions, the first turn half a segment away): not a vertex.
    keep = trace.kind != START
    path, kind = trace.path[keep], trace.kind[keep]
    backward = path >= n
    group = np.where(backward, path - n, path)
    order = np.where(backward, -trace.order[keep], trace.order[keep])
    # Walking backward, the record *after* a seam (in path order) is the one before it in scratch order.
    breaks = np.where(backward, kind == SEAM_OUT, kind == SEAM_IN)
    # Pieces this short are rounding at seams and boundaries (relative to the object too: a request for
    # very long scratches must not make every short piece "rounding").
    tiny = 1e-9 * max(min(float(length.max(initial=0.0)), surface.size), 1e-300)
    return assemble(group, order, trace.uv[keep], trace.point[keep], breaks, min_length=tiny,
                    merge_distance=tiny)


def build_set(pieces: Pieces, source: np.ndarray, params: dict) -> ScratchSet:
    """A ScratchSet from pieces, each taking the parameters of the request it came from."""
    fields = {name: np.asarray(value)[source] for name, value in params.items()}
    # Total traced length per request (pieces of one scratch), to scale variation frequencies.
    _, first, inverse = np.unique(source, return_index=True, return_inverse=True)
    total = np.bincount(inverse, weights=pieces.length)[inverse]
    share = np.where(total > 0, pieces.length / np.where(total > 0, total, 1.0), 1.0)
    for name in ("width_variation", "depth_variation"):
        variation = fields[name].copy()
        variation[:, 1] *= share
        fields[name] = variation
    fields["seed"] = piece_seeds(fields["seed"], np.arange(len(source)) - first[inverse])
    return ScratchSet(uv=pieces.uv, offsets=pieces.offsets, **fields)


def piece_seeds(seed, rank) -> np.ndarray:
    """Seeds for the pieces a scratch is cut into: the first keeps the scratch's seed, the others
    get well-mixed new ones (so pieces do not repeat each other's noise)."""
    seed = np.asarray(seed, dtype=np.uint32)
    rank = np.asarray(rank, dtype=np.uint32)
    with np.errstate(over="ignore"):
        mixed = hash_uint32(seed ^ hash_uint32(rank * np.uint32(0x9E3779B9)))
    return np.where(rank == 0, seed, mixed).astype(np.uint32)


def _cat(parts, dtype, width=None):
    if parts:
        return np.concatenate(parts)
    return np.zeros((0,) if width is None else (0, width), dtype=dtype)


def empty_placed() -> Placed:
    """No scratches."""
    return Placed(scratches=ScratchSet.empty(), source=np.zeros(0, dtype=np.int64),
                  point=np.zeros((0, 3)), piece_length=np.zeros(0), requested=0)
