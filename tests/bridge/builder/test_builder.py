"""The builder: neutral description → Mitsuba dict → image, checked against closed-form expectations."""
import math

import numpy as np
import pytest

from bridge_scenes import bright_centroid, camera_at, emissive_dot, quad, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge import scene as S

mi = pytest.importorskip("mitsuba")


def render_description(description, spp=16, settings=None, seed=0):
    """One ``mi.render`` with a fixed seed: the same image on every run, whatever the machine's load.

    (``render.render_image`` sized its passes by measured time, so its samples, and the noise of every
    comparison below, changed from run to run.)  The tolerances below hold with a wide margin over
    seeds 0-7, not only for seed 0: ``docs/testing.md`` lists the spread measured for each.
    """
    settings = settings or S.RenderSettings(spp=spp)
    return np.asarray(mi.render(builder.load_scene(description, settings), spp=spp, seed=seed))


def expected_pixel(camera: S.Camera, film: S.Film, point):
    """Where a pinhole/orthographic camera puts ``point`` (pixels from the top-left), computed by hand."""
    local = np.linalg.inv(camera.to_world) @ np.append(point, 1.0)
    x, y, depth = local[0], local[1], -local[2]
    if camera.projection == "perspective":
        tan_x = math.tan(math.radians(camera.fov_x_deg) / 2)
        nx, ny = x / depth / tan_x, y / depth / (tan_x * film.height / film.width)
    else:
        half_w = camera.ortho_width / 2
        nx, ny = x / half_w, y / (half_w * film.height / film.width)
    u = film.width / 2 * (1 + nx) - camera.shift_x * film.width
    v = film.height / 2 * (1 - ny) + camera.shift_y * film.height
    return u, v


# ---- camera ---------------------------------------------------------------------------------

@pytest.mark.parametrize("projection, shift", [
    ("perspective", (0.0, 0.0)), ("perspective", (0.2, 0.0)), ("perspective", (0.0, -0.15)),
    ("perspective", (0.1, 0.1)), ("orthographic", (0.0, 0.0)), ("orthographic", (-0.1, 0.2)),
])
def test_a_point_lands_where_the_camera_model_puts_it(variant, projection, shift):
    film = S.Film(64, 40)
    yaw = np.radians(10)
    matrix = camera_at((0.3, -0.2, 4.0))
    matrix[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]]
    camera = S.Camera(matrix, projection=projection, fov_x_deg=50, ortho_width=3.0, shift_x=shift[0],
                      shift_y=shift[1])
    point = (0.5, 0.3, 0.0)
    dot, glow = emissive_dot(point, radius=0.03)
    image = render_description(simple_scene(film=film, camera=camera, shapes=[dot], materials={"glow": glow}))
    got = bright_centroid(image, 0.05)
    want = expected_pixel(camera, film, point)
    assert np.allclose(got, want, atol=0.6), (got, want)


def test_image_row_zero_is_the_top_and_column_zero_the_left(variant):
    film = S.Film(40, 40)
    camera = S.Camera(camera_at((0, 0, 4)), fov_x_deg=40)
    dot, glow = emissive_dot((-0.8, 0.8, 0), radius=0.1)  # world -X is left, +Y is up in this camera
    image = render_description(simple_scene(film=film, camera=camera, shapes=[dot], materials={"glow": glow}))
    x, y = bright_centroid(image)
    assert x < 20 and y < 20


def test_crop_window_renders_exactly_that_part_of_the_frame(variant):
    dot, glow = emissive_dot((0.4, -0.3, 0), radius=0.3)
    # sigma of the sums' ratio: 0.3 % at 256 spp (0.6 % at 64 spp) against the 3 % tolerance
    full = render_description(simple_scene(film=S.Film(48, 32), shapes=[dot], materials={"glow": glow}), spp=256)
    crop = (20, 12, 20, 14)
    part = render_description(simple_scene(film=S.Film(48, 32, crop=crop), shapes=[dot], materials={"glow": glow}),
                              spp=256)
    assert part.shape == (14, 20, 4)
    x, y, w, h = crop
    window = full[y:y + h, x:x + w, 0]
    exact = (window == 0) | (window > 0.999)  # pixels fully outside or inside the dot: no noise
    assert exact.sum() > 200 and (window > 0.999).sum() > 10
    assert np.array_equal(part[..., 0][exact] > 0.5, window[exact] > 0.5)
    assert part[..., 0].sum() == pytest.approx(window.sum(), rel=0.03)


def test_sensor_dict_carries_clipping_filter_and_samples(variant):
    description = simple_scene(film=S.Film(10, 10, filter="tent"),
                               camera=S.Camera(np.eye(4), near=0.5, far=50.0))
    sensor = builder.sensor_dict(description.camera, description.film, S.RenderSettings(spp=7, seed=3))
    assert sensor["near_clip"] == 0.5 and sensor["far_clip"] == 50.0
    assert sensor["film"]["rfilter"] == {"type": "tent"} and sensor["film"]["pixel_format"] == "rgba"
    assert sensor["sampler"]["sample_count"] == 7


def test_clipping_hides_geometry_outside_the_range(variant):
    dot, glow = emissive_dot((0, 0, 0), radius=0.5)
    near = S.Camera(camera_at((0, 0, 3)), fov_x_deg=60, near=3.5, far=10)
    image = render_description(simple_scene(camera=near, shapes=[dot], materials={"glow": glow}))
    assert image[..., :3].max() < 1e-3


# ---- lights ---------------------------------------------------------------------------------

def lit_floor(lights, spp=1024):
    """Mean radiance at the centre of a grey (albedo 0.5) floor seen from 3 units above (4×4 pixels).

    Its relative standard deviation over seeds is 0.1 % at 1024 spp (0.85 % at 64 spp, which made the
    1 % tolerances below fail for one seed in four); the tolerances are at least 5 of these sigmas.
    """
    image = render_description(simple_scene(lights=lights), spp=spp)
    return image[10:14, 14:18, :3].mean()


def floor_expectation(irradiance, n=24):
    """What :func:`lit_floor` should see: albedo/π × the irradiance averaged over those pixels' footprint."""
    half = 2 * 3.0 * math.tan(math.radians(30)) / 32 * 2  # 4 pixels of 32 across a 60° view from 3 units
    xs = (np.arange(n) + 0.5) / n * 2 * half - half
    x, y = np.meshgrid(xs, xs)
    return 0.5 / math.pi * irradiance(x, y).mean()


def test_point_light_irradiance_follows_the_inverse_square_law(variant):
    intensity, h = 2.0, 2.0
    got = lit_floor([S.PointLight((0, 0, h), (intensity,) * 3)])
    assert got == pytest.approx(floor_expectation(lambda x, y: intensity * h / (x * x + y * y + h * h) ** 1.5),
                                rel=0.01)


def test_spherical_light_has_the_intensity_of_a_point_light(variant):
    # Off to the side: unlike Blender's, Mitsuba's emitting sphere is visible to the camera.
    point = lit_floor([S.PointLight((1.5, 0, 1), (2.0,) * 3)])
    sphere = lit_floor([S.PointLight((1.5, 0, 1), (2.0,) * 3, radius=0.2)], spp=256)
    assert sphere == pytest.approx(point, rel=0.03)


def test_sun_irradiance_is_its_strength(variant):
    got = lit_floor([S.SunLight((0, 0, -1), (3.0,) * 3)])
    assert got == pytest.approx(0.5 / math.pi * 3.0, rel=0.01)


def test_spot_is_as_bright_as_a_point_light_on_its_axis_and_dark_outside(variant):
    down = np.eye(4)
    down[:3, 3] = (0, 0, 2)  # local -Z is world -Z: shining down
    point = lit_floor([S.PointLight((0, 0, 2), (2.0,) * 3)])
    assert lit_floor([S.SpotLight(down, (2.0,) * 3, 30, 20)]) == pytest.approx(point, rel=0.01)
    tilted = down.copy()
    tilted[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # now shining along +Y, away from the centre
    assert lit_floor([S.SpotLight(tilted, (2.0,) * 3, 30, 20)]) < 1e-4


def test_area_light_radiance_gives_the_lambertian_irradiance(variant):
    radiance, size, height = 5.0, 0.4, 2.0
    matrix = np.eye(4)
    matrix[:3, 3] = (0, 0, height)
    got = lit_floor([S.AreaLight(matrix, "rectangle", size, size, (radiance,) * 3)], spp=4096)  # sigma 0.14 %
    # E = L ∫ cos θ cos θ' / r² dA over the square straight above (the camera sees through its back).
    n = 40
    lx = (np.arange(n) + 0.5) / n * size - size / 2

    def irradiance(x, y):
        dx = x[..., None, None] - lx[:, None]
        dy = y[..., None, None] - lx[None, :]
        r2 = dx * dx + dy * dy + height * height
        return radiance * (height ** 2 / r2 ** 2).sum(axis=(-2, -1)) * (size / n) ** 2

    assert got == pytest.approx(floor_expectation(irradiance, n=12), rel=0.01)


def test_area_light_shines_along_its_local_minus_z_only(variant):
    matrix = np.eye(4)
    matrix[:3, 3] = (1.5, 0, 1)  # off to the side, out of the camera's view
    assert lit_floor([S.AreaLight(matrix, "disk", 0.5, 0.5, (5.0,) * 3)]) > 0.01
    matrix[:3, :3] = np.diag([1, -1, -1])  # flipped: shines up, away from the floor
    assert lit_floor([S.AreaLight(matrix, "disk", 0.5, 0.5, (5.0,) * 3)]) < 1e-4


# ---- world ----------------------------------------------------------------------------------

def test_constant_world_lights_a_diffuse_floor_with_albedo_times_radiance(variant):
    image = render_description(simple_scene(world=S.ConstantWorld((0.4, 0.4, 0.4))), spp=1024)  # sigma 0.23 %
    assert image[10:14, 14:18, :3].mean() == pytest.approx(0.5 * 0.4, rel=0.02)


def equirect(colour_at) -> np.ndarray:
    """A 64×32 equirectangular image in Blender's layout, coloured by direction."""
    height, width = 32, 64
    v = 1 - (np.arange(height) + 0.5) / height  # row 0 is the top (v = 1)
    u = (np.arange(width) + 0.5) / width
    uu, vv = np.meshgrid(u, v)
    phi = -(uu - 0.5) * 2 * np.pi  # Blender: u = -atan2(y, x) / 2π + 0.5
    theta = (vv - 0.5) * np.pi
    d = np.stack([np.cos(theta) * np.cos(phi), np.cos(theta) * np.sin(phi), np.sin(theta)], axis=-1)
    return colour_at(d).astype(np.float32)


@pytest.mark.parametrize("look, channel", [((1, 0, 0), 0), ((0, 1, 0), 1), ((0, 0, 1), 2)])
def test_environment_map_is_oriented_as_in_blender(variant, look, channel):
    # Red towards +X, green towards +Y, blue towards +Z (negative axes black).
    texture = S.Texture("axes", pixels=equirect(lambda d: np.maximum(d, 0) ** 8), srgb=False)
    matrix = np.eye(4)
    forward = np.array(look, float)
    up = np.array((0, 0, 1.0)) if channel != 2 else np.array((0, 1.0, 0))
    right = np.cross(forward, up)
    matrix[:3, :3] = np.stack([right, np.cross(right, forward), -forward], axis=1)
    camera = S.Camera(matrix, fov_x_deg=20)
    image = render_description(simple_scene(camera=camera, shapes=[], world=S.EnvironmentWorld(texture)))
    mean = image[..., :3].mean(axis=(0, 1))
    assert mean.argmax() == channel and mean[channel] > 0.5, mean


def test_environment_rotation_turns_the_map(variant):
    texture = S.Texture("axes", pixels=equirect(lambda d: np.maximum(d, 0) ** 8), srgb=False)
    quarter = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])  # looked up at R·d: +Y now reads +X's colour
    camera_y = np.eye(4)
    camera_y[:3, :3] = np.stack([[1, 0, 0], [0, 0, 1], [0, -1, 0]], axis=1)  # looks along +Y
    image = render_description(simple_scene(camera=S.Camera(camera_y, fov_x_deg=20), shapes=[],
                                            world=S.EnvironmentWorld(texture, rotation=quarter.T)))
    mean = image[..., :3].mean(axis=(0, 1))
    assert mean.argmax() == 0, mean


def test_sky_is_z_up_and_the_sun_lights_what_faces_it(variant):
    high = render_description(simple_scene(world=S.SkyWorld((0, 0.3, 1.0))), spp=64)[10:14, 14:18, :3].mean()
    low = render_description(simple_scene(world=S.SkyWorld((0, 1.0, 0.05))), spp=64)[10:14, 14:18, :3].mean()
    assert high > 2 * low > 0


# ---- materials and textures --------------------------------------------------------------------

def test_textures_are_looked_up_with_blenders_v_axis(variant):
    # Image top row red, bottom row blue: in Blender the top of an image is at v = 1,
    # here the quad's +Y edge, which the camera shows at the top.
    pixels = np.zeros((8, 8, 3), np.float32)
    pixels[:4, :, 0] = 1
    pixels[4:, :, 2] = 1
    texture = S.Texture("tb", pixels=pixels, srgb=False, interpolation="nearest")
    camera = S.Camera(camera_at((0, 0, 3)), projection="orthographic", ortho_width=2.0)
    image = render_description(simple_scene(film=S.Film(16, 16), camera=camera, shapes=[
        S.Shape("q", quad(2.0), np.eye(4), "tex")], materials={"tex": S.Diffuse(texture)},
        world=S.ConstantWorld((1, 1, 1))), spp=32)
    top, bottom = image[:6].mean(axis=(0, 1)), image[-6:].mean(axis=(0, 1))
    assert top[0] > 3 * top[2] and bottom[2] > 3 * bottom[0]


def test_srgb_pixels_are_linearised(variant):
    pixels = np.full((2, 2, 3), 0.5, np.float32)
    camera = S.Camera(camera_at((0, 0, 3)), projection="orthographic", ortho_width=1.0)
    values = []
    for srgb in (True, False):
        texture = S.Texture(f"grey{srgb}", pixels=pixels, srgb=srgb)
        image = render_description(simple_scene(film=S.Film(8, 8), camera=camera, shapes=[
            S.Shape("q", quad(2.0), np.eye(4), "e")], materials={"e": S.Emission((1, 1, 1), S.Diffuse(texture))},
            world=S.ConstantWorld((1, 1, 1))), spp=256)  # sigma 0.0007 (0.003 at 16 spp)
        values.append(image[..., 1].mean() - 1.0)  # minus the emission
    assert values[0] == pytest.approx(0.214, abs=0.01) and values[1] == pytest.approx(0.5, abs=0.01)


def test_surfaces_reflect_on_both_sides_as_in_blender(variant):
    below = np.diag([1.0, -1.0, -1.0, 1.0])  # the floor turned upside down: its back faces the camera
    front = lit_floor([S.SunLight((0, 0, -1), (1,) * 3)])
    image = render_description(simple_scene(shapes=[S.Shape("floor", quad(4.0), below, "grey")],
                                            lights=[S.SunLight((0, 0, -1), (1,) * 3)]), spp=1024)
    assert image[10:14, 14:18, :3].mean() == pytest.approx(front, rel=0.02)


def test_emission_radiance_is_seen_directly(variant):
    # Spectral rendering round-trips RGB through a spectrum: a few per cent for saturated colours.
    image = render_description(simple_scene(materials={"grey": S.Emission((2.0, 1.0, 0.5))}), spp=256)
    assert np.allclose(image[8:16, 12:20, :3].mean(axis=(0, 1)), (2.0, 1.0, 0.5), rtol=0.05)


def test_every_material_kind_builds_and_renders(variant):
    materials = {
        "d": S.Diffuse((0.5, 0.2, 0.1)), "p": S.Principled(metallic=1.0, roughness=0.2),
        "g": S.Glossy((0.9, 0.9, 0.9), alpha=0.0), "r": S.Glossy((0.9, 0.5, 0.2), alpha=0.1),
        "t": S.Principled(transmission=1.0, roughness=0.0), "e": S.Emission((1, 1, 1), S.Principled()),
    }
    shapes = []
    for index, key in enumerate(materials):
        matrix = np.eye(4)
        matrix[:3, 3] = (index - 2.5, 0, 0)
        shapes.append(S.Shape(key, quad(0.9, key), matrix, key))
    image = render_description(simple_scene(film=S.Film(64, 16), shapes=shapes, materials=materials,
                                            world=S.ConstantWorld((0.5, 0.5, 0.5))))
    assert np.isfinite(image).all() and image[..., :3].mean() > 0.05


def test_mirrored_instances_keep_their_normals(variant):
    mesh = S.MeshData("tri", np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32),
                      np.array([[0, 1, 2]], np.uint32), np.array([[0, 0, 1]] * 3, np.float32))
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    from scratch_iridescence.mitsuba_bridge.builder.resources import world_geometry

    positions, faces, normals = world_geometry(S.Shape("m", mesh, mirror, "grey"))
    geometric = np.cross(positions[faces[0, 1]] - positions[faces[0, 0]], positions[faces[0, 2]] - positions[faces[0, 0]])
    assert np.dot(geometric, normals[0]) > 0 and np.allclose(normals, [[0, 0, 1]] * 3)


def test_shapes_sharing_a_material_share_one_bsdf(variant):
    shapes = [S.Shape(f"q{i}", quad(1.0, f"q{i}"), np.eye(4), "grey") for i in range(3)]
    scene = builder.load_scene(simple_scene(shapes=shapes), S.RenderSettings())
    bsdfs = {id(shape.bsdf()) for shape in scene.shapes()}
    assert len(scene.shapes()) == 3 and len(bsdfs) == 1


def test_mesh_buffers_start_on_64_bytes_whatever_numpy_gave(variant):
    """Dr.Jit maps numpy's memory and gathers in packets or element by element by its alignment: unaligned
    mesh buffers gave each process other kernels, which missed the kernel cache (docs/bsdf.md, Performance)."""
    def misaligned(array):  # the same values 4 bytes past a 64-byte boundary: never aligned
        raw = np.zeros(array.nbytes + 128, np.uint8)
        start = (-raw.ctypes.data) % 64 + 4
        view = raw[start:start + array.nbytes].view(array.dtype).reshape(array.shape)
        view[...] = array
        return view

    plain = quad(1.0)
    mesh = S.MeshData("q", *(misaligned(getattr(plain, name)) for name in ("positions", "faces")),
                      misaligned(np.tile([0.0, 0.0, 1.0], (4, 1)).astype(np.float32)), misaligned(plain.uvs))
    assert all(getattr(mesh, name).ctypes.data % 64 == 4 for name in ("positions", "faces", "normals", "uvs"))
    scene = builder.load_scene(simple_scene(shapes=[S.Shape("q", mesh, np.eye(4), "grey")]), S.RenderSettings())
    params = mi.traverse(scene.shapes()[0])
    for key, values in (("vertex_positions", plain.positions), ("faces", plain.faces), ("vertex_texcoords", plain.uvs)):
        buffer = np.asarray(params[key])
        assert buffer.ctypes.data % 64 == 0, key
        assert np.array_equal(buffer, values.ravel()), key
    assert np.asarray(params["vertex_normals"]).ctypes.data % 64 == 0
