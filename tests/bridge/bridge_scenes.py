"""Small scenes built in code for the bridge tests."""
import numpy as np

from scratch_iridescence.mitsuba_bridge import scene as S


def quad(size=2.0, name="quad") -> S.MeshData:
    """A square in the XY plane facing +Z, UV (0, 0) at its (-x, -y) corner."""
    h = size / 2
    positions = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return S.MeshData(name, positions, faces, None, uvs)


def camera_at(position, look_down=True) -> np.ndarray:
    """A Blender-convention camera matrix at ``position`` looking along world −Z (+Y up in the image)."""
    matrix = np.eye(4)
    matrix[:3, 3] = position
    return matrix


def simple_scene(*, film=None, camera=None, shapes=None, materials=None, lights=(), world=None):
    film = film or S.Film(32, 24)
    camera = camera or S.Camera(camera_at((0, 0, 3)), fov_x_deg=60)
    if shapes is None:
        shapes = (S.Shape("floor", quad(4.0), np.eye(4), "grey"),)
    materials = materials if materials is not None else {"grey": S.Diffuse((0.5, 0.5, 0.5))}
    return S.SceneDescription(film=film, camera=camera, shapes=tuple(shapes), materials=materials,
                              lights=tuple(lights), world=world)


def emissive_dot(position, radius=0.05, name="dot") -> tuple:
    """(shape, material) of a small emissive square facing +Z at ``position``."""
    matrix = np.eye(4)
    matrix[:3, 3] = position
    return S.Shape(name, quad(2 * radius, name), matrix, "glow"), S.Emission((1.0, 1.0, 1.0))


def bright_centroid(image, threshold=0.2):
    """(x, y) centre of the pixels brighter than ``threshold``, pixel units from the top-left corner."""
    ys, xs = np.nonzero(image[..., :3].mean(axis=-1) > threshold)
    assert len(xs), "nothing bright in the image"
    return xs.mean() + 0.5, ys.mean() + 0.5
