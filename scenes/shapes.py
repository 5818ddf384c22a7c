"""Objects modelled in code for the paper's scenes where we have no asset (bpy).

Every object is a grid of quads over a parametric surface, with the UV map of
its parameters: straight lines of the parameters are straight in UV, so a
scratch set given in UV (a CD's tracks, a brushed ring's grain) follows the
surface, and the add-on's operators trace scratches across it as on any mesh.
A surface closed in one direction (a ring around its axis, a disc around its
centre) has a UV seam where the parameter wraps, as an unwrapped mesh has.

The geometry itself (points of a parameter grid) is plain numpy in the
``*_grid`` functions, so tests can check sizes without Blender.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["grid_object", "annulus_grid", "ring_surface", "ring_grid", "spoon_surface", "spoon_grid", "door_panels",
           "panel_rise", "panel_door_grid", "door_relief", "polar_annulus", "ring", "spoon", "door", "box"]


# ------------------------------------------------------------------- meshes
def grid_object(name: str, points, uv, *, wrap_u: bool = False, wrap_v: bool = False, flip: bool = False,
                mat=None, smooth: bool = True, location=(0.0, 0.0, 0.0)):
    """A mesh object of quads over a parameter grid.

    Parameters
    ----------
    points : (nu + 1, nv + 1, 3) array
        Positions in metres (object space).  With ``wrap_u`` the last row
        repeats the first and is welded to it (a closed surface).
    uv : (nu + 1, nv + 1, 2) array
        The UV map at the grid points.  Wrapped rows keep their own UVs, so
        the welded edge is a UV seam.
    """
    import bpy

    points = np.asarray(points, dtype=np.float64)
    uv = np.asarray(uv, dtype=np.float64)
    rows, columns = points.shape[:2]
    index = np.arange(rows * columns).reshape(rows, columns)
    if wrap_u:
        index[-1] = index[0]
    if wrap_v:
        index[:, -1] = index[:, 0]
    corners = np.stack([index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], axis=-1).reshape(-1, 4)
    corner_uv = np.stack([uv[:-1, :-1], uv[1:, :-1], uv[1:, 1:], uv[:-1, 1:]], axis=-2).reshape(-1, 4, 2)
    if flip:
        corners, corner_uv = corners[:, ::-1], corner_uv[:, ::-1]
    used = np.unique(corners)
    remap = np.full(rows * columns, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))

    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(len(used))
    mesh.vertices.foreach_set("co", points.reshape(-1, 3)[used].astype(np.float32).ravel())
    mesh.loops.add(corners.size)
    mesh.loops.foreach_set("vertex_index", remap[corners].astype(np.int32).ravel())
    mesh.polygons.add(len(corners))
    mesh.polygons.foreach_set("loop_start", (4 * np.arange(len(corners))).astype(np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(len(corners), 4, dtype=np.int32))
    layer = mesh.uv_layers.new(name="UVMap")
    layer.data.foreach_set("uv", corner_uv.astype(np.float32).ravel())
    mesh.update(calc_edges=True)
    mesh.validate()
    if smooth:
        mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    if mat is not None:
        obj.data.materials.append(mat)
    return obj


def box(name: str, size, location, mat=None):
    """A box (``size`` = x, y, z in metres) centred at ``location``, with the cube primitive's UVs."""
    import bpy

    bpy.ops.mesh.primitive_cube_add(size=1.0, location=location)
    obj = bpy.context.active_object
    obj.scale = size
    bpy.ops.object.transform_apply(location=False, rotation=False, scale=True)
    obj.name = name
    if mat is not None:
        obj.data.materials.append(mat)
    return obj


# --------------------------------------------------------------- the grids
def annulus_grid(inner_m: float, outer_m: float, segments: int, rings: int):
    """A flat annulus in polar parameters: u = angle / 2π (counter-clockwise from +X), v = radial fraction.

    Lines of constant v are circles: parallel tracks in UV are concentric in
    3D, at the radial spacing ``(outer_m - inner_m) · Δv``.
    """
    u = np.linspace(0.0, 1.0, segments + 1)
    v = np.linspace(0.0, 1.0, rings + 1)
    angle, radius = 2.0 * np.pi * u[:, None], inner_m + (outer_m - inner_m) * v[None, :]
    points = np.stack([radius * np.cos(angle), radius * np.sin(angle), np.zeros_like(radius * angle)], axis=-1)
    uv = np.stack(np.meshgrid(u, v, indexing="ij"), axis=-1)
    return points, uv


def ring_surface(u, v, radius_m: float, width_m: float, thickness_m: float, squareness: float = 4.0):
    """Points of a finger ring lying on its side (axis Z, middle at z = 0) at parameters (``u``, ``v``);
    broadcasts.

    A band whose cross-section is a rounded rectangle (a superellipse):
    ``radius_m`` is the inner radius (the finger's), ``width_m`` the band's
    width along Z, ``thickness_m`` its radial thickness; ``squareness`` the
    superellipse exponent (2: an elliptic tube, large: a flat band with
    sharp edges).  u goes around the ring (the circumference, from +X
    counter-clockwise), v around the cross-section, starting on the inner
    face's centre line (the finger's side, where a seam shows least).
    """
    angle = 2.0 * np.pi * np.asarray(u, dtype=np.float64)
    phi = 2.0 * np.pi * np.asarray(v, dtype=np.float64) + np.pi
    power = 2.0 / squareness
    radial = 0.5 * thickness_m * np.sign(np.cos(phi)) * np.abs(np.cos(phi)) ** power
    axial = 0.5 * width_m * np.sign(np.sin(phi)) * np.abs(np.sin(phi)) ** power
    distance = radius_m + 0.5 * thickness_m + radial
    x, y, z = np.broadcast_arrays(distance * np.cos(angle), distance * np.sin(angle), axial)
    return np.stack([x, y, z], axis=-1)


def ring_grid(radius_m: float, width_m: float, thickness_m: float, segments: int, sections: int,
              squareness: float = 4.0):
    """:func:`ring_surface` on a grid of ``segments`` quads around the ring and ``sections`` around the band,
    the latter spaced at equal arc length of the cross-section.

    The UV map fills the unit square: u around the ring, v the arc length
    around the cross-section over its perimeter, so a UV square is about four
    times longer around the ring than across the band.  (An unwrap at one
    scale, v over [0, perimeter / circumference], makes the scratch BSDF's
    automatic grid four times finer for this dense set and its table build
    twice as slow: docs/rendering.md, The ring.)
    """
    fine = np.linspace(0.0, 1.0, 8 * sections + 1)
    section = ring_surface(0.0, fine, radius_m, width_m, thickness_m, squareness)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(section, axis=0), axis=1))]
    along = np.linspace(0.0, arc[-1], sections + 1)
    v = np.interp(along, arc, fine)
    u = np.linspace(0.0, 1.0, segments + 1)
    points = ring_surface(u[:, None], v[None, :], radius_m, width_m, thickness_m, squareness)
    uv = np.stack(np.meshgrid(u, along / arc[-1], indexing="ij"), axis=-1)
    return points, uv


#: The spoon's outline: (distance from the bowl's tip along the spoon, half width), metres.
SPOON_OUTLINE = ((0.0, 0.0), (0.004, 0.0125), (0.012, 0.0185), (0.025, 0.0205), (0.038, 0.0185), (0.050, 0.012),
                 (0.060, 0.0055), (0.068, 0.0042), (0.110, 0.0055), (0.160, 0.0085), (0.182, 0.0095),
                 (0.190, 0.0070), (0.193, 0.0))
SPOON_BOWL_M = (0.0, 0.058)   # where the bowl lies along the spoon
SPOON_BOWL_DEPTH_M = 0.009
#: The door's panels: how far they stand out, and the width of their bevels (metres).
DOOR_RAISE_M, DOOR_BEVEL_M = 0.008, 0.04


def spoon_surface(x_m, t):
    """Points of the spoon's upper surface at ``x_m`` metres from the bowl's tip along it and ``t`` across
    (-1: its left edge seen from above, +1: its right edge); broadcasts.  The handle points towards +X, the
    spoon's middle lies at x = 0.

    The bowl is an ellipsoidal dish ``SPOON_BOWL_DEPTH_M`` deep; the neck
    rises out of it and the handle runs straight, curved across (a shallow
    channel) and lifted towards its end, as a table spoon lies on a table.
    """
    x, t = np.broadcast_arrays(np.asarray(x_m, dtype=np.float64), np.asarray(t, dtype=np.float64))
    outline = np.asarray(SPOON_OUTLINE)
    length = outline[-1, 0]
    half = np.maximum(np.interp(x, outline[:, 0], outline[:, 1]), 2e-4)  # the tips: a tiny edge, not a point
    bowl_start, bowl_end = SPOON_BOWL_M
    along = np.clip((x - bowl_start) / (bowl_end - bowl_start), 0.0, 1.0)
    dish = np.sin(np.pi * along) ** 0.8 * (x <= bowl_end)          # 0 at the bowl's ends, 1 in its middle
    handle = np.clip((x - bowl_end) / (length - bowl_end), 0.0, 1.0)  # 0 up to the bowl's end
    lift = 0.012 * handle ** 1.5                                    # the handle rises towards its end
    channel = 0.0008 * np.clip((x - bowl_end) / 0.01, 0.0, 1.0)     # ... curved across, a shallow channel
    across = 1.0 - t ** 2
    z = SPOON_BOWL_DEPTH_M * (1.0 - dish * across) + lift - channel * across
    return np.stack([x - 0.5 * length, half * t, z], axis=-1)


def spoon_grid(lengthwise: int, across: int):
    """The spoon's upper surface (:func:`spoon_surface`) as a grid of ``lengthwise`` × ``across`` quads, rows
    along the spoon from the bowl's tip (denser at both ends, where the outline turns fast), columns across.

    The UV map fills the unit square: u = the row's parameter (the grid's
    spacing, so a UV unit along the spoon is shorter at its ends), v across
    from its left edge (0) to its right (1).  (A projection from above at
    one scale makes the scratch BSDF's automatic grid four times finer and
    its table build slower: docs/rendering.md, The ring.)
    """
    s = np.linspace(0.0, 1.0, lengthwise + 1)
    t = np.linspace(-1.0, 1.0, across + 1)
    x = SPOON_OUTLINE[-1][0] * (0.5 - 0.5 * np.cos(np.pi * s))
    points = spoon_surface(x[:, None], t[None, :])
    uv = np.stack(np.meshgrid(s, 0.5 * (t + 1.0), indexing="ij"), axis=-1)
    return points, uv


def door_panels(width_m: float, height_m: float):
    """Two raised panels, a low one and a tall one, 12 cm inside the leaf's edges: (x0, z0, x1, z1) each,
    metres from the leaf's lower left corner."""
    return ((0.12, 0.12, width_m - 0.12, 0.86), (0.12, 1.0, width_m - 0.12, height_m - 0.12))


def panel_rise(x, z, panels, raise_m: float, bevel_m: float):
    """How far the front stands out (metres, towards -Y) at (``x``, ``z``) from the leaf's lower left corner:
    each panel rises over a bevel ``bevel_m`` wide to a flat field ``raise_m`` high."""
    x, z = np.asarray(x, dtype=np.float64), np.asarray(z, dtype=np.float64)
    rise = np.zeros(np.broadcast(x, z).shape)
    for x0, z0, x1, z1 in panels:
        inside = np.minimum.reduce([x - x0, x1 - x, z - z0, z1 - z])  # distance inside the panel's outline
        rise = np.maximum(rise, raise_m * np.clip(inside / bevel_m, 0.0, 1.0))
    return rise


def panel_door_grid(width_m: float, height_m: float, panels, raise_m: float, bevel_m: float, step_m: float = 0.01):
    """The front face of a door leaf (in the XZ plane, facing -Y, x from its middle), with raised panels.

    ``panels`` as :func:`door_panels` gives them; each rises ``raise_m``
    towards the viewer over a bevel ``bevel_m`` wide (:func:`panel_rise`).  The
    grid lines are placed at every panel's and bevel's edge (and every
    ``step_m`` between), so the faces are planar; the UV map is the front
    view at one scale, one UV unit per leaf height (u over [0, width /
    height]): the bevels are slightly compressed in UV, which the scratch
    BSDF reads through its UV Jacobian.
    """
    def lines(extent, edges):
        breaks = sorted({0.0, extent, *edges})
        grid = [breaks[0]]
        for a, b in zip(breaks[:-1], breaks[1:]):
            pieces = max(1, int(math.ceil((b - a) / step_m)))
            grid.extend(a + (b - a) * np.arange(1, pieces + 1) / pieces)
        return np.asarray(grid)

    xs = lines(width_m, [e for x0, _, x1, _ in panels for e in (x0, x0 + bevel_m, x1 - bevel_m, x1)])
    zs = lines(height_m, [e for _, z0, _, z1 in panels for e in (z0, z0 + bevel_m, z1 - bevel_m, z1)])
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    points = np.stack([X - 0.5 * width_m, -panel_rise(X, Z, panels, raise_m, bevel_m), Z], axis=-1)
    uv = np.stack([X / height_m, Z / height_m], axis=-1)
    return points, uv


def door_relief(width_m: float, height_m: float, raise_m: float = DOOR_RAISE_M, bevel_m: float = DOOR_BEVEL_M):
    """``rise(points)``: the relief of :func:`door`'s front at (x from the leaf's middle, height) points."""
    panels = door_panels(width_m, height_m)
    return lambda points: panel_rise(np.asarray(points)[:, 0] + 0.5 * width_m, np.asarray(points)[:, 1], panels,
                                     raise_m, bevel_m)


# ----------------------------------------------------------------- objects
def polar_annulus(name: str, inner_m: float, outer_m: float, *, segments: int = 720, rings: int = 8, mat=None,
                  location=(0.0, 0.0, 0.0)):
    """A flat annulus with the polar UV map of :func:`annulus_grid` (seam along +X)."""
    points, uv = annulus_grid(inner_m, outer_m, segments, rings)
    return grid_object(name, points, uv, wrap_u=True, flip=True, mat=mat, location=location)  # normal +Z


def ring(name: str, radius_m: float, width_m: float, thickness_m: float, *, segments: int = 192,
         sections: int = 48, mat=None, location=(0.0, 0.0, 0.0)):
    """A closed finger ring (:func:`ring_grid`), seams where the angle and the cross-section wrap."""
    points, uv = ring_grid(radius_m, width_m, thickness_m, segments, sections)
    return grid_object(name, points, uv, wrap_u=True, wrap_v=True, mat=mat, location=location)


def spoon(name: str, *, lengthwise: int = 160, across: int = 24, thickness_m: float = 0.0015, mat=None,
          location=(0.0, 0.0, 0.0)):
    """The spoon's scratched upper surface (:func:`spoon_grid`) and its underside, two objects.

    The underside is the upper surface lowered by ``thickness_m`` and closed
    to it along the rim; it carries no scratches (the camera sees the top).
    """
    points, uv = spoon_grid(lengthwise, across)
    top = grid_object(name, points, uv, mat=mat, location=location)
    below = points.copy()
    below[..., 2] -= thickness_m
    rim = np.concatenate([below[:, :1], points[:, :1]], axis=1)      # left edge, facing -Y
    other = np.concatenate([points[:, -1:], below[:, -1:]], axis=1)  # right edge, facing +Y
    parts = [(below[:, ::-1], uv[:, ::-1]), (rim, np.zeros(rim.shape[:2] + (2,))),
             (other, np.zeros(other.shape[:2] + (2,)))]
    objects = [grid_object(f"{name} underside {i}", p, q, mat=mat, location=location) for i, (p, q) in
               enumerate(parts)]
    return top, objects


def door(name: str, *, width_m: float = 0.86, height_m: float = 2.0, handle=(0.355, 1.05),
         raise_m: float = DOOR_RAISE_M, bevel_m: float = DOOR_BEVEL_M, mat=None, handle_mat=None,
         thickness_m: float = 0.04):
    """A door leaf with the raised panels of :func:`door_panels` (its front face scratched), its edges and a
    lever handle.

    Returns (front face, other objects).  The leaf stands on the floor (z = 0)
    in the XZ plane, its front facing -Y, x from its middle; the handle's rose
    sits at ``handle`` (x, height), its lever pointing towards the leaf's middle.
    """
    points, uv = panel_door_grid(width_m, height_m, door_panels(width_m, height_m), raise_m, bevel_m)
    front = grid_object(name, points, uv, mat=mat, smooth=False)
    others = [box(f"{name} leaf", (width_m, thickness_m, height_m), (0.0, 0.5 * thickness_m + 1e-4,
                                                                     0.5 * height_m), mat)]
    # the lever: a round rose on the leaf, a neck out of it, a lever towards the leaf's middle
    hx, hz = handle
    import bpy

    bpy.ops.mesh.primitive_cylinder_add(vertices=64, radius=0.026, depth=0.012, location=(hx, -0.006, hz),
                                        rotation=(math.pi / 2, 0.0, 0.0))
    rose = bpy.context.active_object
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=0.009, depth=0.055, location=(hx, -0.035, hz),
                                        rotation=(math.pi / 2, 0.0, 0.0))
    neck = bpy.context.active_object
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=0.009, depth=0.13, location=(hx - 0.06, -0.062, hz),
                                        rotation=(0.0, math.pi / 2, 0.0))
    lever = bpy.context.active_object
    for obj, label in ((rose, "rose"), (neck, "neck"), (lever, "lever")):
        obj.name = f"{name} handle {label}"
        if handle_mat is not None:
            obj.data.materials.append(handle_mat)
        bpy.ops.object.shade_smooth()
        others.append(obj)
    return front, others
