"""Small meshes built with numpy for the Blender-free editor tests: (positions, triangles, triangle_uv)."""
from __future__ import annotations

import numpy as np


def grid(nx: int = 1, ny: int = 1, size=(2.0, 2.0), uv_size=(1.0, 1.0)):
    """A flat nx × ny grid in the z = 0 plane centred on the origin, UV = affine map of x, y."""
    xs = np.linspace(-size[0] / 2, size[0] / 2, nx + 1)
    ys = np.linspace(-size[1] / 2, size[1] / 2, ny + 1)
    x, y = np.meshgrid(xs, ys, indexing="ij")
    positions = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    uv = np.column_stack([(x.ravel() / size[0] + 0.5) * uv_size[0], (y.ravel() / size[1] + 0.5) * uv_size[1]])
    index = lambda i, j: i * (ny + 1) + j  # noqa: E731
    triangles = []
    for i in range(nx):
        for j in range(ny):
            triangles += [[index(i, j), index(i + 1, j), index(i + 1, j + 1)],
                          [index(i, j), index(i + 1, j + 1), index(i, j + 1)]]
    triangles = np.array(triangles)
    return positions, triangles, uv[triangles]


def ring(half: float = 1.0, uv_width: float = 1.0):
    """The four side faces of a cube (|x|, |y| <= half, |z| <= half), unwrapped as one strip.

    Face i spans u in [i/4, (i+1)/4] * uv_width and v in [0, 1]; the strip closes
    with a UV seam between face 3 and face 0 (on the edge at x = y = -half).
    Top and bottom are open (mesh boundary).  U is scaled differently from V,
    so UV lengths are not surface lengths.
    """
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * half
    positions = np.vstack([np.column_stack([corners, np.full(4, -half)]),
                           np.column_stack([corners, np.full(4, half)])])
    triangles, uv = [], []
    for i in range(4):
        b0, b1, t0, t1 = i, (i + 1) % 4, 4 + i, 4 + (i + 1) % 4
        u0, u1 = i / 4 * uv_width, (i + 1) / 4 * uv_width
        triangles += [[b0, b1, t1], [b0, t1, t0]]
        uv += [[[u0, 0], [u1, 0], [u1, 1]], [[u0, 0], [u1, 1], [u0, 1]]]
    return positions, np.array(triangles), np.array(uv, dtype=float)


def torus(n: int = 24, m: int = 12, major: float = 3.0, minor: float = 1.0):
    """A closed torus (no boundary) with UV [0, 1]²: seams along both wrap-around lines."""
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    theta, phi = 2 * np.pi * i / n, 2 * np.pi * j / m
    positions = np.column_stack([((major + minor * np.cos(phi)) * np.cos(theta)).ravel(),
                                 ((major + minor * np.cos(phi)) * np.sin(theta)).ravel(),
                                 (minor * np.sin(phi)).ravel()])
    vertex = lambda a, b: (a % n) * m + (b % m)  # noqa: E731
    triangles, uv = [], []
    for a in range(n):
        for b in range(m):
            quad = [(a, b), (a + 1, b), (a + 1, b + 1), (a, b + 1)]
            for tri in ((0, 1, 2), (0, 2, 3)):
                triangles.append([vertex(*quad[k]) for k in tri])
                uv.append([[quad[k][0] / n, quad[k][1] / m] for k in tri])
    return positions, np.array(triangles), np.array(uv, dtype=float)


def unequal_quads():
    """Two unit-UV-area quads side by side whose 3D areas are 1 and 3 (x in [0, 1] and [1, 4])."""
    positions = np.array([[0, 0, 0], [1, 0, 0], [4, 0, 0], [0, 1, 0], [1, 1, 0], [4, 1, 0]], dtype=float)
    triangles = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    uv_of = {0: (0.0, 0.0), 1: (0.5, 0.0), 2: (1.0, 0.0), 3: (0.0, 1.0), 4: (0.5, 1.0), 5: (1.0, 1.0)}
    return positions, triangles, np.array([[uv_of[v] for v in tri] for tri in triangles])
