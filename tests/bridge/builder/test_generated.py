"""Textures in Blender's Generated coordinates (the ``generated`` texture reading the mesh attribute):
Cycles' 3D checker and an image's Flat projection, seen straight from above, against the same
functions evaluated with numpy at the pixel centres; the export folder (PLY attribute) renders the same."""
import numpy as np
import pytest

from bridge_scenes import camera_at, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge import scene as S

mi = pytest.importorskip("mitsuba")

UNIFORM = S.ConstantWorld((1.0, 1.0, 1.0))
TOP = S.Camera(camera_at((0, 0, 3)), projection="orthographic", ortho_width=2.0)
SIZE = 16


def plate(generated_z=0.3) -> S.MeshData:
    """A 2-unit square (one pixel row per 1/8 unit) whose Generated coordinates are (x + 1) / 2, (y + 1) / 2 and a
    constant z: the texture space of a box of which the square is a slice."""
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    generated = np.column_stack([(positions[:, :2] + 1) / 2, np.full(4, generated_z)]).astype(np.float32)
    return S.MeshData("plate", positions, faces, uvs=np.zeros((4, 2), np.float32), generated=generated)


def render(material, mesh=None, *, spp=64):
    description = simple_scene(film=S.Film(SIZE, SIZE), camera=TOP,
                               shapes=[S.Shape("plate", mesh or plate(), np.eye(4), "m")], materials={"m": material},
                               world=UNIFORM)
    scene = builder.load_scene(description, S.RenderSettings(spp=spp))
    return np.asarray(mi.render(scene, spp=spp, seed=0))[..., :3].mean(axis=-1)


def pixel_generated():
    """Generated (x, y) at the pixel centres (row 0 at the top: y = 1)."""
    centres = (np.arange(SIZE) + 0.5) / SIZE
    return np.meshgrid(centres, centres[::-1])


def assert_pattern(image, expected, step):
    """Every pixel nearer its expected level than half a ``step`` between levels, and the mean error small
    (64 samples of a white world in spectral rendering spread a pixel by a few per cent)."""
    error = np.abs(image - expected)
    assert error.max() < step / 2 and error.mean() < 0.02


def cycles_checker(x, y, z, scale):
    """Cycles' svm_checker on Generated coordinates: True where it gives Color1."""
    cells = [np.abs(np.floor((c * scale + 1e-6) * 0.999999)).astype(int) % 2 for c in (x, y, z)]
    return (cells[0] == cells[1]) == (cells[2] == 1)


@pytest.mark.parametrize("z", [0.3, 0.6])
def test01_checker_in_generated_coordinates_is_cycles_3d_checker(variant, z):
    image = render(S.Diffuse(S.Checker((0.8, 0.8, 0.8), (0.2, 0.2, 0.2), scale=4.0, coordinates="generated")),
                   plate(z))
    x, y = pixel_generated()
    expected = np.where(cycles_checker(x, y, z, 4.0), 0.8, 0.2)
    assert_pattern(image, expected, step=0.6)
    # the z slice decides the parity: the two slices are each other's negative
    assert (cycles_checker(x, y, 0.3, 4.0) != cycles_checker(x, y, 0.6, 4.0)).all()


def test02_image_in_generated_coordinates_is_read_at_the_generated_xy(variant):
    columns = np.linspace(0.1, 0.9, 4, dtype=np.float32)
    pixels = np.repeat(np.broadcast_to(columns[None, :, None], (2, 4, 1)), 3, axis=2)
    texture = S.Texture("ramp", pixels=np.ascontiguousarray(pixels), srgb=False, interpolation="nearest",
                        coordinates="generated")
    image = render(S.Diffuse(texture))
    x, _ = pixel_generated()
    expected = columns[np.minimum((x * 4).astype(int), 3)]
    assert_pattern(image, expected, step=0.8 / 3)
    # the same texture in UV reads the plate's UVs, all (0, 0): one colour
    uv = render(S.Diffuse(S.Texture("ramp", pixels=np.ascontiguousarray(pixels), srgb=False,
                                    interpolation="nearest")))
    assert uv.std() < 0.01


def test03_exported_folder_carries_the_coordinates(variant, tmp_path):
    from scratch_iridescence.mitsuba_bridge.folder import export

    material = S.Diffuse(S.Checker((0.8, 0.8, 0.8), (0.2, 0.2, 0.2), scale=4.0, coordinates="generated"))
    description = simple_scene(film=S.Film(SIZE, SIZE), camera=TOP, shapes=[S.Shape("plate", plate(), np.eye(4), "m")],
                               materials={"m": material}, world=UNIFORM)
    settings = S.RenderSettings(spp=16)
    export.export_folder(description, settings, tmp_path / "scene")
    assert 'type="generated"' in (tmp_path / "scene" / "scene.xml").read_text()
    from_folder = np.asarray(mi.render(export.load_folder(tmp_path / "scene"), spp=16, seed=1))
    in_memory = np.asarray(mi.render(builder.load_scene(description, settings), spp=16, seed=1))
    assert from_folder == pytest.approx(in_memory, abs=1e-5)


def test04_textures_keep_their_coordinates(variant):
    with pytest.raises(ValueError):
        S.Checker(coordinates="object")
    with pytest.raises(ValueError):
        S.MeshData("bad", np.zeros((3, 3), np.float32), np.array([[0, 1, 2]], np.uint32),
                   generated=np.zeros((3, 2), np.float32))
