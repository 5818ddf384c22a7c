"""Paths traced on a :class:`~.surface.Surface`, all at once with numpy (no ``bpy``).

A path starts at a point inside a triangle (barycentric coordinates) with a
direction in that triangle's plane and walks a given 3D length.  Inside a
triangle it is straight (or turns by a fixed angle every ``turn_every`` for
gentle arcs); at an edge it continues into the neighbouring triangle with the
direction *unfolded* about the shared edge, which keeps it straight on the
surface (a geodesic).  It stops at the mesh boundary.

Every path records the vertices a scratch polyline needs: the start, every
turn, every crossing of a non-flat edge (so each UV segment lies inside one
triangle and maps to 3D exactly) and the end.  Crossing a UV seam records the
crossing point twice, once with the UV of each side, and marks where a new
scratch begins.  :func:`assemble` turns the records into polylines.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .surface import EDGE_CORNERS, Surface

__all__ = ["Trace", "trace_paths", "assemble", "Pieces", "enter_towards", "ON_EDGE_BARY"]

# Record kinds.
START, TURN, EDGE, SEAM_OUT, SEAM_IN, END, BOUNDARY = range(7)
_STUCK_STEPS = 16  # a path that makes no progress this many times in a row is stopped
_TURNS_PER_STEP = 8  # turns of an arc taken at once inside a triangle (closed form)
#: A barycentric coordinate at most this small puts a point on the edge opposite that corner.
ON_EDGE_BARY = 1e-7


@dataclass(frozen=True, eq=False)
class Trace:
    """Vertices recorded along paths, and where each path ended.

    Attributes
    ----------
    path, order : (N,) int64
        Which path a record belongs to, and its position along it.
    kind : (N,) int8
        ``START``, ``TURN``, ``EDGE``, ``SEAM_OUT`` (last point before a seam),
        ``SEAM_IN`` (first point after it), ``END`` or ``BOUNDARY``.
    triangle : (N,) int64, uv : (N, 2), point : (N, 3)
        Where the record lies.
    end_triangle, end_bary, end_direction, travelled :
        Final state of each path (travelled: 3D length walked).
    """

    path: np.ndarray
    order: np.ndarray
    kind: np.ndarray
    triangle: np.ndarray
    uv: np.ndarray
    point: np.ndarray
    end_triangle: np.ndarray
    end_bary: np.ndarray
    end_direction: np.ndarray
    travelled: np.ndarray


def trace_paths(surface: Surface, triangle, bary, direction, length, *, turn_angle=None,
                turn_every=None, first_turn=None, record: bool = True,
                max_steps: int = 1_000_000) -> Trace:
    """Walk paths over ``surface`` (see the module docstring).

    Parameters
    ----------
    triangle : (N,) int
        Start triangles (must be usable).
    bary : (N, 3) float
        Start points, barycentric.
    direction : (N, 3) float
        Start directions (projected into the triangle plane and normalised here).
    length : (N,) float
        3D length to walk (surface units).
    turn_angle, turn_every : (N,) float, optional
        Turn by ``turn_angle`` radians (right hand about the normal) every
        ``turn_every`` units of length: a polygonal arc of curvature
        ``turn_angle / turn_every``.
    first_turn : (N,) float, optional
        Distance to the first turn (default ``turn_every``).
    record : bool
        Record vertices (False: only the final state is wanted).
    max_steps : int
        Safety limit on the number of steps of one path.
    """
    triangle = np.array(triangle, dtype=np.int64)
    n = len(triangle)
    bary = np.array(bary, dtype=np.float64).reshape(n, 3)
    direction = np.array(direction, dtype=np.float64).reshape(n, 3)
    remaining = np.array(length, dtype=np.float64).reshape(n)
    normal = surface.normal[triangle]
    direction -= np.einsum("ni,ni->n", direction, normal)[:, None] * normal
    direction /= np.maximum(np.linalg.norm(direction, axis=1), 1e-300)[:, None]
    turning = turn_angle is not None and turn_every is not None
    if turning:
        turn_angle = np.broadcast_to(np.asarray(turn_angle, dtype=np.float64), (n,))
        turn_every = np.broadcast_to(np.asarray(turn_every, dtype=np.float64), (n,))
        first = turn_every if first_turn is None else np.broadcast_to(np.asarray(first_turn, float), (n,))
        next_turn = np.where(turn_angle != 0, first, np.inf)
    else:
        next_turn = np.full(n, np.inf)
    travelled = np.zeros(n)
    stuck = np.zeros(n, dtype=np.int64)

    recorder = _Recorder(surface, record)
    everyone = np.arange(n)
    recorder.add(everyone, 0, START, triangle, bary)
    sequence = np.ones(n, dtype=np.int64)  # order of each path's next record

    active = everyone[remaining > 0]
    recorder.add(everyone[remaining <= 0], 1, END, triangle[remaining <= 0], bary[remaining <= 0])
    step = 0
    while active.size:
        step += 1
        if turning:
            _advance_turns(surface, active, triangle, bary, direction, remaining, next_turn, travelled,
                           turn_angle, turn_every, sequence, recorder)
        order = sequence[active]
        t = triangle[active]
        b = bary[active]
        d = direction[active]
        # Barycentric velocity of the direction; exit where a coordinate reaches 0.
        v = _bary_velocity(surface, t, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            exit_at = np.where(v < 0, -b / v, np.inf)
        edge = np.argmin(exit_at, axis=1)
        to_exit = exit_at[np.arange(len(active)), edge]
        rem, turn = remaining[active], next_turn[active]
        h = np.minimum(np.minimum(to_exit, rem), turn)
        h = np.where(np.isfinite(h), h, 0.0)

        b = b + h[:, None] * v
        ends = rem <= np.minimum(to_exit, turn)
        turns = ~ends & (turn <= to_exit)
        exits = ~ends & ~turns
        b[exits, edge[exits]] = 0.0
        np.maximum(b, 0.0, out=b)
        b /= b.sum(axis=1, keepdims=True)
        bary[active] = b
        remaining[active] = rem - h
        next_turn[active] = turn - h
        travelled[active] += h
        stuck[active] = np.where(h > 0, 0, stuck[active] + 1)

        # -- ends
        done = active[ends]
        recorder.add(done, order[ends], END, triangle[done], bary[done])

        # -- turns: rotate about the normal
        turned = active[turns]
        if turned.size:
            recorder.add(turned, order[turns], TURN, triangle[turned], bary[turned])
            angle = turn_angle[turned]
            nrm = surface.normal[triangle[turned]]
            d = direction[turned]
            direction[turned] = np.cos(angle)[:, None] * d + np.sin(angle)[:, None] * np.cross(nrm, d)
            next_turn[turned] = turn_every[turned]

        # -- edge crossings
        crossing = active[exits]
        order = order[exits]
        k = edge[exits]
        t = triangle[crossing]
        other = surface.neighbour[t, k]
        blocked = (other < 0) | (stuck[crossing] > _STUCK_STEPS) | (step >= max_steps)
        stopped = crossing[blocked]
        recorder.add(stopped, order[blocked], BOUNDARY, triangle[stopped], bary[stopped])
        go = ~blocked
        crossing, k, t, other, order = crossing[go], k[go], t[go], other[go], order[go]
        if crossing.size:
            seam = surface.seam[t, k]
            flat = surface.flat[t, k]
            recorder.add(crossing[seam], order[seam], SEAM_OUT, t[seam], bary[crossing[seam]])
            visible = ~seam & ~flat
            recorder.add(crossing[visible], order[visible], EDGE, t[visible], bary[crossing[visible]])

            point = surface.point(t, bary[crossing])
            other_edge = surface.neighbour_edge[t, k]
            new_b = surface.barycentric(other, point)
            new_b[np.arange(len(other)), other_edge] = 0.0
            np.maximum(new_b, 0.0, out=new_b)
            new_b /= np.maximum(new_b.sum(axis=1, keepdims=True), 1e-300)

            # Unfold the direction about the shared edge.
            a_corner = surface.corners[t, EDGE_CORNERS[k, 0]]
            b_corner = surface.corners[t, EDGE_CORNERS[k, 1]]
            along = b_corner - a_corner
            along /= np.maximum(np.linalg.norm(along, axis=1), 1e-300)[:, None]
            d = direction[crossing]
            out_here = surface.edge_out[t, k]
            out_there = surface.edge_out[other, other_edge]
            new_d = (np.einsum("ni,ni->n", d, along)[:, None] * along
                     - np.einsum("ni,ni->n", d, out_here)[:, None] * out_there)
            new_d /= np.maximum(np.linalg.norm(new_d, axis=1), 1e-300)[:, None]

            triangle[crossing] = other
            bary[crossing] = new_b
            direction[crossing] = new_d
            recorder.add(crossing[seam], order[seam] + 1, SEAM_IN, other[seam], new_b[seam])

        sequence[active] += 2
        keep = ~ends
        keep[exits] = ~blocked
        active = active[keep]

    return recorder.finish(triangle, bary, direction, travelled)


def enter_towards(surface: Surface, triangle, bary, direction, *,
                  both_ways: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Move start points that lie on an edge or a vertex into the triangle the direction enters.

    A point on an edge (or a vertex) belongs to every triangle around it, but a
    path can only start in one whose plane holds the direction and that the
    direction points into: on a cube's edge, a direction into the other face
    projects to nothing in this face's plane.  Of the triangles around the
    point (the neighbour across the edge; at a vertex every triangle with a
    corner there) the one keeping most of the direction in its plane, without
    leaving it at once, is chosen; a point inside its triangle, or already in
    a fitting one, keeps it.

    Parameters
    ----------
    triangle : (N,) int, bary : (N, 3) float, direction : (N, 3) float
        Start points (on usable triangles) and 3D directions.
    both_ways : bool
        The path goes both ways from the point (a scratch traced from its
        centre): a triangle that ``-direction`` enters will do as well (the
        other half then leaves it at once and is unfolded across the edge).

    Returns
    -------
    (triangle, bary) with the same point in the chosen triangles.
    """
    triangle = np.array(triangle, dtype=np.int64)
    bary = np.array(bary, dtype=np.float64).reshape(-1, 3)
    direction = np.asarray(direction, dtype=np.float64).reshape(-1, 3)
    on_edge = bary <= ON_EDGE_BARY
    for i in np.flatnonzero(on_edge.any(axis=1)):
        t = triangle[i]
        point = surface.point(t[None], bary[i][None])[0]
        if on_edge[i].sum() >= 2:  # a vertex: every triangle with a corner there
            corner = surface.corners[t, int(np.argmax(bary[i]))]
            around = np.flatnonzero((surface.corners == corner).all(axis=2).any(axis=1) & surface.usable)
        else:
            around = surface.neighbour[t, on_edge[i]]
        candidates = np.r_[t, around[around >= 0]]
        b = surface.barycentric(candidates, np.repeat(point[None], len(candidates), axis=0))
        np.maximum(b, 0.0, out=b)
        b /= b.sum(axis=1, keepdims=True)
        score = _entering_fraction(surface, candidates, b, direction[i])
        if both_ways:
            score = np.maximum(score, _entering_fraction(surface, candidates, b, -direction[i]))
        best = int(np.argmax(score))
        if score[best] > score[0]:
            triangle[i], bary[i] = candidates[best], b[best]
    return triangle, bary


def _entering_fraction(surface, candidates, bary, direction) -> np.ndarray:
    """How much of ``direction`` lies in each candidate's plane, or -1 where it leaves the triangle at once."""
    length = max(float(np.linalg.norm(direction)), 1e-300)
    normal = surface.normal[candidates]
    in_plane = direction[None, :] - (normal @ direction)[:, None] * normal
    kept = np.linalg.norm(in_plane, axis=1) / length
    velocity = _bary_velocity(surface, candidates, in_plane / length)
    leaves = ((bary <= ON_EDGE_BARY) & (velocity < -1e-9 * np.abs(velocity).max(axis=1, keepdims=True))).any(axis=1)
    return np.where(leaves | (kept < 1e-9), -1.0, kept)


def _advance_turns(surface, candidates, triangle, bary, direction, remaining, next_turn, travelled,
                   turn_angle, turn_every, sequence, recorder) -> None:
    """Take up to ``_TURNS_PER_STEP`` turns of each arc at once, in closed form.

    Inside one (convex) triangle the arc is a polygon whose legs have known
    directions, so its next vertices follow from sums of barycentric velocities;
    the turns are accepted while the vertices stay inside the triangle and short
    of the path's end.  What comes after (an exit, the end, the next turn) is
    left to the ordinary step.
    """
    paths = candidates[turn_angle[candidates] != 0]
    if not paths.size:
        return
    t = triangle[paths]
    d = direction[paths]
    w = np.cross(surface.normal[t], d)
    v0 = _bary_velocity(surface, t, d)
    w0 = _bary_velocity(surface, t, w)
    phi = turn_angle[paths]
    k = np.arange(_TURNS_PER_STEP)
    angle = phi[:, None] * k  # direction of leg k: R(k phi) d
    velocity = np.cos(angle)[:, :, None] * v0[:, None, :] + np.sin(angle)[:, :, None] * w0[:, None, :]
    legs = np.empty((len(paths), _TURNS_PER_STEP))
    legs[:, 0] = next_turn[paths]
    legs[:, 1:] = turn_every[paths][:, None]
    vertex = bary[paths][:, None, :] + np.cumsum(legs[:, :, None] * velocity, axis=1)
    walked = np.cumsum(legs, axis=1)
    valid = (vertex.min(axis=2) >= -1e-12) & (walked < remaining[paths][:, None])
    taken = np.cumprod(valid, axis=1).sum(axis=1)
    go = taken > 0
    if not go.any():
        return
    paths, t, d, w, phi, taken = paths[go], t[go], d[go], w[go], phi[go], taken[go]
    vertex, walked = vertex[go], walked[go]
    np.maximum(vertex, 0.0, out=vertex)
    vertex /= vertex.sum(axis=2, keepdims=True)
    row, column = np.nonzero(k[None, :] < taken[:, None])
    recorder.add(paths[row], sequence[paths][row] + column, TURN, t[row], vertex[row, column])
    sequence[paths] += taken
    last = np.arange(len(paths)), taken - 1
    bary[paths] = vertex[last]
    turned = phi * taken
    direction[paths] = np.cos(turned)[:, None] * d + np.sin(turned)[:, None] * w
    remaining[paths] -= walked[last]
    travelled[paths] += walked[last]
    next_turn[paths] = turn_every[paths]


def _bary_velocity(surface, triangle, direction) -> np.ndarray:
    """Rate of change of the barycentric coordinates when moving along ``direction``."""
    v12 = np.einsum("nij,nj->ni", surface.to_bary[triangle], direction)
    return np.column_stack([-v12.sum(axis=1), v12])


class _Recorder:
    """Collects records iteration by iteration (one array append per kind and step)."""

    def __init__(self, surface: Surface, enabled: bool):
        self.surface, self.enabled = surface, enabled
        self.parts = []

    def add(self, paths, order, kind, triangle, bary):
        if self.enabled and len(paths):
            self.parts.append((paths, np.broadcast_to(np.asarray(order, dtype=np.int64), (len(paths),)),
                               np.full(len(paths), kind, dtype=np.int8), triangle.copy(), bary.copy()))

    def finish(self, triangle, bary, direction, travelled) -> Trace:
        if self.parts:
            paths, order, kind, tri, b = (np.concatenate(column) for column in zip(*self.parts))
        else:
            paths = order = tri = np.zeros(0, dtype=np.int64)
            kind = np.zeros(0, dtype=np.int8)
            b = np.zeros((0, 3))
        return Trace(path=paths, order=order, kind=kind, triangle=tri,
                     uv=self.surface.uv_at(tri, b), point=self.surface.point(tri, b),
                     end_triangle=triangle, end_bary=bary, end_direction=direction, travelled=travelled)


# ------------------------------------------------------------------ assembly
@dataclass(frozen=True, eq=False)
class Pieces:
    """Scratch polylines cut from traced paths.

    Attributes
    ----------
    uv : (P, 2) float64, offsets : (S + 1,) int64
        Polylines in the layout of a ``ScratchSet``.
    point : (P, 3) float64
        The same vertices in 3D.
    source : (S,) int64
        Which group (scratch request, stroke ...) each piece came from.
    length : (S,) float64
        3D length of each piece.
    """

    uv: np.ndarray
    offsets: np.ndarray
    point: np.ndarray
    source: np.ndarray
    length: np.ndarray

    @property
    def count(self) -> int:
        return len(self.offsets) - 1


def assemble(group, order, uv, point, breaks, *, min_length: float = 0.0,
             merge_distance: float = 0.0) -> Pieces:
    """Cut ordered records into polylines.

    Records are sorted by ``(group, order)``; a new piece starts at every new
    group and at every record with ``breaks`` set.  A vertex equal to its
    predecessor in the piece (same UV, or within ``merge_distance`` in 3D: a
    turn that rounding put a hair before the end) is dropped; pieces with fewer
    than two vertices or a 3D length of at most ``min_length`` are dropped.
    """
    group = np.asarray(group, dtype=np.int64)
    if len(group) == 0:
        return Pieces(np.zeros((0, 2)), np.zeros(1, dtype=np.int64), np.zeros((0, 3)),
                      np.zeros(0, dtype=np.int64), np.zeros(0))
    order = np.asarray(order, dtype=np.int64)
    span = int(order.max() - order.min()) + 1
    if group.max() < np.iinfo(np.int64).max // max(span, 1) - 1:
        sort = np.argsort(group * span + (order - order.min()), kind="stable")
    else:  # pragma: no cover - astronomically many records
        sort = np.lexsort((order, group))
    group, uv, point, breaks = group[sort], uv[sort], point[sort], np.asarray(breaks)[sort]

    new = np.empty(len(group), dtype=bool)
    new[0] = True
    new[1:] = (group[1:] != group[:-1]) | breaks[1:]
    # Drop a vertex equal to its predecessor in the same piece.
    duplicate = np.zeros(len(group), dtype=bool)
    close = np.all(uv[1:] == uv[:-1], axis=1)
    if merge_distance > 0:
        close |= np.einsum("ni,ni->n", point[1:] - point[:-1], point[1:] - point[:-1]) <= merge_distance ** 2
    duplicate[1:] = ~new[1:] & close
    keep = ~duplicate
    group, uv, point, new = group[keep], uv[keep], point[keep], new[keep]

    starts = np.flatnonzero(new)
    counts = np.diff(np.r_[starts, len(group)])
    piece = np.repeat(np.arange(len(starts)), counts)
    step = np.zeros(len(group))
    step[1:] = np.linalg.norm(point[1:] - point[:-1], axis=1)
    step[starts] = 0.0
    length = np.bincount(piece, weights=step, minlength=len(starts))
    good = (counts >= 2) & (length > min_length)

    keep_vertex = good[piece]
    offsets = np.zeros(int(good.sum()) + 1, dtype=np.int64)
    np.cumsum(counts[good], out=offsets[1:])
    return Pieces(uv=uv[keep_vertex], offsets=offsets, point=point[keep_vertex],
                  source=group[starts[good]], length=length[good])
