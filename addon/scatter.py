"""Scratches placed on a surface: generator, spray and pen, with numpy only (no ``bpy``).

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

from ..mitsuba_bridge.scratch import Distribution, Gaussian, Profile, ScratchSet, Uniform, sample_parameters
from ..mitsuba_bridge.scratch.noise import hash_uint32
from .surface import Surface
from .trace import BOUNDARY, END, SEAM_IN, SEAM_OUT, START, Pieces, assemble, trace_paths

__all__ = ["Looks", "ScatterSpec", "Placed", "scatter", "scratches_from_centres", "pen_scratches",
           "spray_centres", "piece_seeds", "SAGITTA_FRACTION", "MAX_SEGMENTS", "estimate_bytes"]

#: Arcs are cut into straight segments whose sagitta is at most this fraction of the width.
SAGITTA_FRACTION = 0.1
#: At most this many straight segments per arc (beyond it the sagitta rule is relaxed).
MAX_SEGMENTS = 256
#: Scratches traced per batch (bounds the memory of the temporaries).
CHUNK = 65536
# Rough peak memory per scratch and per vertex while generating (bytes; measured, with margin).
_BYTES_PER_SCRATCH = 1200
_BYTES_PER_VERTEX = 400


@dataclass(frozen=True)
class Looks:
    """What a scratch looks like apart from its path (MODEL.md §7).

    ``width`` and ``depth`` are distributions in metres; the variations are
    (relative amplitude, frequency) as in the scratch file.
    """

    width: Distribution
    depth: Distribution
    profile: Profile = Profile.RECTANGULAR
    width_variation: tuple[float, float] = (0.0, 0.0)
    depth_variation: tuple[float, float] = (0.0, 0.0)

    def sample(self, rng: np.random.Generator, count: int) -> dict:
        """Per-scratch parameter arrays (the non-geometric fields of a ScratchSet)."""
        return sample_parameters(rng, count, width=self.width, depth=self.depth, profile=self.profile,
                                 width_variation=self.width_variation, depth_variation=self.depth_variation)


@dataclass(frozen=True)
class ScatterSpec:
    """A request for ``count`` scratches scattered uniformly over a surface.

    Lengths are surface units (Blender units of the world-space mesh);
    ``unit_scale`` is metres per unit, used to compare lengths with widths.
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
    unit_scale: float = 1.0

    def __post_init__(self):
        if self.count < 0:
            raise ValueError("count must be >= 0")
        if not (0 < self.length_min <= self.length_max) or not math.isfinite(self.length_max):
            raise ValueError(f"lengths must satisfy 0 < min <= max; got {self.length_min}, {self.length_max}")


@dataclass(frozen=True, eq=False)
class Placed:
    """Scratches made on a surface, with what the caller may want to check or report.

    ``source[i]`` is the request (scratch, stroke ...) piece ``i`` came from;
    ``centre_*`` / ``length`` / ``direction`` describe the requests.
    """

    scratches: ScratchSet
    source: np.ndarray
    point: np.ndarray = field(repr=False)
    piece_length: np.ndarray = field(repr=False)
    requested: int = 0
    relaxed_arcs: int = 0  # arcs that needed more than MAX_SEGMENTS segments (sagitta rule relaxed)


def estimate_bytes(count: int, vertices_per_scratch: float = 4.0) -> int:
    """Rough peak memory (bytes) to generate ``count`` scratches."""
    return int(count * (_BYTES_PER_SCRATCH + _BYTES_PER_VERTEX * vertices_per_scratch))


def expected_vertices(spec: ScatterSpec) -> float:
    """Expected vertices per scratch from arcs alone (edge crossings come on top)."""
    if spec.bend == 0:
        return 4.0
    width_units = max(_typical(spec.looks.width), 1e-12) / spec.unit_scale
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
                                  unit_scale=spec.unit_scale)


def scratches_from_centres(surface: Surface, triangle, bary, direction, length, params: dict, *,
                           bend=None, unit_scale: float = 1.0) -> Placed:
    """Scratches centred at given surface points, traced in both directions.

    ``params`` holds one entry per scratch for every non-geometric field of a
    ScratchSet (as :meth:`Looks.sample` returns).
    """
    count = len(triangle)
    bend = np.zeros(count) if bend is None else np.asarray(bend, dtype=np.float64)
    width_units = params["width"] / unit_scale
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
        sets.append(_build_set(pieces, source, params))
        sources.append(source)
        points.append(pieces.point)
        lengths.append(pieces.length)
    scratches = ScratchSet.concatenate(sets) if sets else ScratchSet.empty()
    return Placed(scratches=scratches, source=_cat(sources, np.int64), point=_cat(points, np.float64, 3),
                  piece_length=_cat(lengths, np.float64), requested=count,
                  relaxed_arcs=int(np.count_nonzero(needed > MAX_SEGMENTS)))


def _trace_centred(surface, triangle, bary, direction, length, turn_angle, turn_every) -> Pieces:
    n = len(triangle)
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
    tiny = 1e-9 * max(float(length.max(initial=0.0)), 1e-300)
    return assemble(group, order, trace.uv[keep], trace.point[keep], breaks, min_length=tiny,
                    merge_distance=tiny)


def _build_set(pieces: Pieces, source: np.ndarray, params: dict) -> ScratchSet:
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


# ------------------------------------------------------------------ paint
def pen_scratches(surface: Surface, runs, params: dict) -> Placed:
    """One scratch following a stroke: ``runs`` is a list of (triangle, bary) hit sequences.

    Consecutive hits of a run are joined by paths traced on the surface (so the
    scratch follows the surface between them, over folds too); runs are
    separate (the stroke left the surface in between).  The scratch is cut at
    UV seams.  ``params`` holds arrays of length 1 (the stroke's single
    scratch, as ``Looks.sample(rng, 1)``).
    """
    starts_t, starts_b, group, segment = [], [], [], []
    for run_index, (triangle, bary) in enumerate(runs):
        triangle = np.asarray(triangle, dtype=np.int64)
        if len(triangle) < 2:
            continue
        starts_t.append(triangle)
        starts_b.append(np.asarray(bary, dtype=np.float64))
        group.append(np.full(len(triangle) - 1, run_index))
        segment.append(np.arange(len(triangle) - 1))
    if not starts_t:
        return _empty_placed()
    hit_t = np.concatenate([t[:-1] for t in starts_t])
    hit_b = np.concatenate([b[:-1] for b in starts_b])
    target = np.concatenate([surface.point(t[1:], b[1:]) for t, b in zip(starts_t, starts_b)])
    group = np.concatenate(group)
    segment = np.concatenate(segment)
    records, last_end, arrived = _trace_to_targets(surface, hit_t, hit_b, target)

    path, order, kind, triangle, uv, point = records
    n_segments = len(hit_t)
    # A segment's end joins the next segment's start (the next hit) when it arrived
    # there and lies in the same UV island; then the next start replaces it.
    last_of_run = np.r_[group[1:] != group[:-1], True]
    end_triangle = triangle[last_end]
    next_triangle = np.r_[hit_t[1:], 0]
    joins = (~last_of_run & arrived
             & (surface.island[end_triangle] == surface.island[next_triangle]))
    drop = np.zeros(len(path), dtype=bool)
    drop[last_end[joins]] = True
    breaks = kind == SEAM_IN
    # A start that does not continue its predecessor begins a new piece.
    breaks |= (kind == START) & (segment[path] > 0) & ~np.r_[False, joins[:-1]][path]
    keep = ~drop
    span = int(order.max()) + 2
    tiny = 1e-9 * max(surface.size, 1e-300)
    pieces = assemble(group[path][keep], (segment[path] * span + order)[keep], uv[keep], point[keep],
                      breaks[keep], min_length=tiny, merge_distance=tiny)
    source = np.zeros(pieces.count, dtype=np.int64)
    scratches = _build_set(pieces, source, params)
    return Placed(scratches=scratches, source=source, point=pieces.point, piece_length=pieces.length,
                  requested=1)


#: Re-aimed traces per pen segment (a fold or a curved surface needs more than one).
_PEN_STEPS = 6


def _trace_to_targets(surface: Surface, triangle, bary, target):
    """Trace from each start towards its target point, re-aiming until it arrives.

    Returns (records, last_end, arrived): the records (path = start index,
    order, kind, triangle, uv, point), the index of each path's final end
    record, and whether the path reached its target.
    """
    n = len(triangle)
    triangle, bary = triangle.copy(), bary.copy()
    tolerance = 1e-7 * max(surface.size, 1e-300)
    active = np.arange(n)
    parts = []
    span = 0
    blocked = np.zeros(n, dtype=bool)
    for step in range(_PEN_STEPS):
        gap = target[active] - surface.point(triangle[active], bary[active])
        distance = np.linalg.norm(gap, axis=1)
        if step:
            moving = distance > tolerance
            active, gap, distance = active[moving], gap[moving], distance[moving]
        if not active.size:
            break
        trace = trace_paths(surface, triangle[active], bary[active], gap, distance)
        keep = (trace.kind != START) | (step == 0)  # later starts repeat the previous end
        parts.append((active[trace.path[keep]], trace.order[keep] + span, trace.kind[keep],
                      trace.triangle[keep], trace.uv[keep], trace.point[keep]))
        span += int(trace.order.max()) + 2
        triangle[active], bary[active] = trace.end_triangle, trace.end_bary
        stopped = np.zeros(len(active), dtype=bool)
        stopped[trace.path[trace.kind == BOUNDARY]] = True
        blocked[active[stopped]] = True
        active = active[~stopped]
    records = tuple(np.concatenate(column) for column in zip(*parts))
    path, order, kind = records[0], records[1], records[2]
    ends = np.flatnonzero(np.isin(kind, (END, BOUNDARY)))
    last_end = np.full(n, -1)
    by_order = ends[np.argsort(order[ends], kind="stable")]
    last_end[path[by_order]] = by_order  # the latest end of each path wins
    final_gap = np.linalg.norm(target - surface.point(triangle, bary), axis=1)
    arrived = ~blocked & (final_gap <= tolerance * 10)
    return records, last_end, arrived


def _empty_placed() -> Placed:
    return Placed(scratches=ScratchSet.empty(), source=np.zeros(0, dtype=np.int64),
                  point=np.zeros((0, 3)), piece_length=np.zeros(0), requested=0)


def spray_centres(rng: np.random.Generator, runs_points, normals, radius: float, density: float,
                  jitter: float):
    """Where a spray stroke puts scratches, before they are snapped to the surface.

    Parameters
    ----------
    runs_points : list of (n_i, 3) arrays
        The stroke's on-surface points, run by run.
    normals : list of (n_i, 3) arrays
        Surface normals at those points.
    radius : float
        Brush radius: centres are spread uniformly over a disc of this radius
        (in the tangent plane) around points drawn uniformly along the stroke.
    density : float
        Expected scratches per brush radius of stroke length; a single dab
        (a click) sprays ``density`` scratches on average.
    jitter : float
        Directions follow the stroke within ± ``jitter`` radians.

    Returns
    -------
    centres (N, 3), directions (N, 3) — directions are zero where the stroke has
    no direction (a click); the caller then draws them at random.
    """
    lengths = [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() if len(p) > 1 else 0.0 for p in runs_points]
    weights = np.array([length / radius + 1.0 for length in lengths])
    counts = rng.poisson(density * weights)
    centres, directions = [], []
    for points, nrm, n in zip(runs_points, normals, counts):
        if n == 0:
            continue
        points = np.asarray(points, dtype=np.float64)
        nrm = np.asarray(nrm, dtype=np.float64)
        if len(points) > 1:
            step = np.linalg.norm(np.diff(points, axis=0), axis=1)
            arc = np.r_[0.0, np.cumsum(step)]
            s = rng.uniform(0.0, arc[-1], n)
            segment = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, len(step) - 1)
            f = ((s - arc[segment]) / np.where(step[segment] > 0, step[segment], 1.0))[:, None]
            base = points[segment] + f * (points[segment + 1] - points[segment])
            along = points[segment + 1] - points[segment]
            normal = nrm[segment]
        else:
            base = np.repeat(points, n, axis=0)
            along = np.zeros((n, 3))
            normal = np.repeat(nrm, n, axis=0)
        along = along - np.einsum("ni,ni->n", along, normal)[:, None] * normal
        norm = np.linalg.norm(along, axis=1)
        has_direction = norm > 0
        along = np.where(has_direction[:, None], along / np.where(has_direction, norm, 1.0)[:, None], 0.0)
        # A tangent basis for the disc even where the stroke has no direction.
        helper = np.where(np.abs(normal[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        e1 = np.where(has_direction[:, None], along, np.cross(normal, helper))
        e1 /= np.maximum(np.linalg.norm(e1, axis=1), 1e-300)[:, None]
        e2 = np.cross(normal, e1)
        rho = radius * np.sqrt(rng.uniform(0.0, 1.0, n))
        phi = rng.uniform(0.0, 2.0 * np.pi, n)
        centres.append(base + (rho * np.cos(phi))[:, None] * e1 + (rho * np.sin(phi))[:, None] * e2)
        turn = rng.uniform(-jitter, jitter, n)[:, None]
        directions.append(np.where(has_direction[:, None],
                                   np.cos(turn) * along + np.sin(turn) * np.cross(normal, along), 0.0))
    if not centres:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.concatenate(centres), np.concatenate(directions)
