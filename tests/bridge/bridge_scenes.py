"""Small scenes built in code for the bridge tests."""
import contextlib
import gc

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


@contextlib.contextmanager
def interrupting_scene():
    """A plane whose Python BSDF sends the process a SIGINT whenever Mitsuba traces its ``sample``.

    What a Ctrl-C does when it lands while a Python plugin runs, at a moment that does not depend on
    timing. Python's own SIGINT handler is installed meanwhile (a suite run in the background ignores
    SIGINT). On exit the scene is dropped and collected: Dr.Jit traces every live BSDF instance of the
    variant in each render's method calls, so a lingering one would interrupt later tests' renders too.
    Callers drop what they hold of it (an exception's traceback holds the frames that hold the scene).
    """
    import signal

    import mitsuba as mi

    class Interrupting(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]

        def sample(self, ctx, si, sample1, sample2, active):
            signal.raise_signal(signal.SIGINT)
            return mi.BSDFSample3f(), mi.Spectrum(0.0)

        def eval(self, ctx, si, wo, active):
            return mi.Spectrum(0.0)

        def pdf(self, ctx, si, wo, active):
            return mi.Float(0.0)

        def eval_pdf(self, ctx, si, wo, active):
            return mi.Spectrum(0.0), mi.Float(0.0)

        def to_string(self):
            return "Interrupting[]"

    mi.register_bsdf("test_interrupting", Interrupting)
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": 3},
                          "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 4, "height": 4},
                                     "to_world": mi.ScalarTransform4f().look_at([0, 0, 3], [0, 0, 0], [0, 1, 0])},
                          "plane": {"type": "rectangle", "bsdf": {"type": "test_interrupting"}},
                          "world": {"type": "constant"}})
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield scene
    finally:
        signal.signal(signal.SIGINT, previous)
        del scene
        gc.collect()


def sphere(radius=0.5, name="sphere", rings=16, segments=32) -> S.MeshData:
    """A UV sphere centred on the origin, smooth normals."""
    theta = np.linspace(0.0, np.pi, rings + 1)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)[None, :]
    normals = np.stack(np.broadcast_arrays(np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                                           np.cos(theta)), axis=-1).reshape(-1, 3).astype(np.float32)
    row = segments + 1
    corners = np.array([(r * row + s, (r + 1) * row + s, (r + 1) * row + s + 1, r * row + s + 1)
                        for r in range(rings) for s in range(segments)], np.uint32)
    faces = np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])
    return S.MeshData(name, radius * normals, faces, normals, None)


def diffuse_scene(film) -> S.SceneDescription:
    """Two diffuse spheres on a grey floor, lit by a tilted area light out of view and a dim world.

    Soft shadows, indirect light and object edges: what a sampler's stratification smooths (the seed-to-seed
    noise of ``tests/bench/bench_sampler.py`` and ``tests/bridge/render/test_sampler.py``).
    """
    def at(x, y, z):
        matrix = np.eye(4)
        matrix[:3, 3] = (x, y, z)
        return matrix

    light = at(2.2, 0.0, 1.5)
    angle = np.radians(45.0)  # its -Z (the emitting side) turned towards the spheres
    light[:3, :3] = [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    shapes = (S.Shape("floor", quad(4.0), np.eye(4), "grey"),
              S.Shape("red", sphere(0.5, "red"), at(-0.3, 0.2, 0.5), "red"),
              S.Shape("blue", sphere(0.3, "blue"), at(0.6, -0.5, 0.3), "blue"))
    materials = {"grey": S.Diffuse((0.5, 0.5, 0.5)), "red": S.Diffuse((0.7, 0.2, 0.15)),
                 "blue": S.Diffuse((0.15, 0.25, 0.7))}
    return simple_scene(film=film, shapes=shapes, materials=materials, world=S.ConstantWorld((0.1, 0.1, 0.1)),
                        lights=[S.AreaLight(light, "rectangle", 1.0, 1.0, (6.0, 6.0, 6.0))])
