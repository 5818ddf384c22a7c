"""Volumes: homogeneous media inside closed meshes and around everything (the world's volume), against
closed forms: Beer–Lambert transmittance, energy conservation of a purely scattering medium in a
uniform world, and the dicts (volpath, media on shapes, lights and sensors, XML export)."""
import math

import numpy as np
import pytest

from bridge_scenes import camera_at, quad, simple_scene
from scratch_iridescence.mitsuba_bridge import builder
from scratch_iridescence.mitsuba_bridge import scene as S
from scratch_iridescence.mitsuba_bridge.builder.volumes import medium_dict

mi = pytest.importorskip("mitsuba")

UNIFORM = S.ConstantWorld((1.0, 1.0, 1.0))
TOP = S.Camera(camera_at((0, 0, 3)), projection="orthographic", ortho_width=1.0)


def box(size=(2.0, 2.0, 1.0), name="box") -> S.MeshData:
    """A closed axis-aligned box centred at the origin, faces wound outwards."""
    h = np.asarray(size, dtype=np.float32) / 2
    corners = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], np.float32) * h
    faces = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                      [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]], np.uint32)
    return S.MeshData(name, corners, faces)


def render(shapes, materials, *, world=UNIFORM, world_volume=None, lights=(), spp=256, size=(4, 4), seed=0,
           max_depth=64, camera=TOP):
    description = simple_scene(film=S.Film(*size), camera=camera, shapes=shapes, materials=materials,
                               lights=lights, world=world)
    description = S.SceneDescription(**{**description.__dict__, "world_volume": world_volume})
    scene = builder.load_scene(description, S.RenderSettings(spp=spp, max_depth=max_depth))
    return np.asarray(mi.render(scene, spp=spp, seed=seed))[..., :3]


def bernoulli_margin(p, samples):
    """Four standard deviations of the mean of ``samples`` draws that are 1 with probability ``p``, else 0."""
    return 4 * math.sqrt(p * (1 - p) / samples)


def test01_medium_dict_keeps_the_coefficients_within_mitsubas_rgb_range(variant):
    medium = medium_dict(S.Volume(scattering=(0.5, 1.0, 2.0), absorption=(1.5, 1.0, 0.0), anisotropy=0.3))
    assert medium["scale"] == pytest.approx(2.0)
    assert medium["sigma_t"]["value"] == pytest.approx([1.0, 1.0, 1.0])
    assert medium["albedo"]["value"] == pytest.approx([0.25, 0.5, 1.0])
    assert medium["phase"] == {"type": "hg", "g": 0.3}
    with pytest.raises(ValueError):
        S.Volume(scattering=(-1.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        S.Volume(anisotropy=1.0)


@pytest.mark.parametrize("density", [0.5, 2.0])
def test02_absorbing_box_transmits_beer_lambert(variant, density):
    """A box 1 unit thick with nothing on its surface and σ_a inside: the white world through it is e^(−σ_a)."""
    smoke = S.Volumetric(S.Interface(), S.Volume(absorption=(density,) * 3))
    image = render([S.Shape("box", box(), np.eye(4), "smoke")], {"smoke": smoke})
    expected = math.exp(-density)
    assert image.mean() == pytest.approx(expected, abs=bernoulli_margin(expected, 16 * 256) + 0.01)


def test03_scattering_box_in_a_uniform_world_keeps_the_world(variant):
    """A purely scattering medium (albedo 1) in a uniform world: radiance stays 1 everywhere (a furnace test
    of the interfaces, the medium's sampling and the phase function)."""
    cloud = S.Volumetric(S.Interface(), S.Volume(scattering=(1.5, 1.5, 1.5), anisotropy=0.4))
    image = render([S.Shape("box", box(), np.eye(4), "cloud")], {"cloud": cloud}, spp=128)
    assert image.mean() == pytest.approx(1.0, abs=0.02)


def test04_world_volume_dims_what_the_camera_sees_by_its_distance(variant):
    """Camera 3 units above a glowing quad in an absorbing world: e^(−3 σ_a) of its radiance reaches it."""
    glow = S.Shape("glow", quad(4.0, "glow"), np.eye(4), "glow")
    image = render([glow], {"glow": S.Emission((1.0, 1.0, 1.0))}, world=None,
                   world_volume=S.Volume(absorption=(0.2, 0.2, 0.2)))
    expected = math.exp(-3 * 0.2)
    assert image.mean() == pytest.approx(expected, abs=bernoulli_margin(expected, 16 * 256) + 0.01)


def test05_volume_under_a_glass_surface_tints_what_passes(variant):
    """A closed glass box with an absorbing inside: (1 − F)² e^(−σ_a) of the world passes at normal incidence
    (light reflected inside comes back tinted too, a few tenths of a per cent here)."""
    glass = S.Volumetric(S.Dielectric(ior=1.5), S.Volume(absorption=(1.0, 1.0, 1.0)))
    image = render([S.Shape("box", box(), np.eye(4), "glass")], {"glass": glass}, spp=512)
    fresnel = ((1.5 - 1) / (1.5 + 1)) ** 2
    passed = (1 - fresnel) ** 2 * math.exp(-1.0)
    reflected = fresnel  # the world mirrored by the top face
    assert image.mean() == pytest.approx(passed + reflected, abs=0.03)


def test06_dict_uses_volpath_and_gives_media_to_shapes_lights_and_sensor(variant):
    smoke = S.Volumetric(S.Interface(), S.Volume(scattering=(1.0, 1.0, 1.0)))
    area = S.AreaLight(np.eye(4), "rectangle", 1.0, 1.0, (1.0, 1.0, 1.0))
    description = simple_scene(shapes=[S.Shape("box", box(), np.eye(4), "smoke"),
                                       S.Shape("floor", quad(4.0), np.eye(4), "grey")],
                               materials={"smoke": smoke, "grey": S.Diffuse()}, lights=[area], world=UNIFORM)
    plain = builder.scene_dict(description, S.RenderSettings())
    assert plain["integrator"]["type"] == "volpath"
    assert "medium" not in plain["sensor"]
    assert plain["shape-box"].interior_medium() is not None and plain["shape-floor"].interior_medium() is None
    fog = S.Volume(absorption=(0.1, 0.1, 0.1))
    foggy = builder.scene_dict(S.SceneDescription(**{**description.__dict__, "world_volume": fog}),
                               S.RenderSettings())
    world = foggy["sensor"]["medium"]
    assert foggy["shape-box"].exterior_medium() is not None and foggy["shape-box"].interior_medium() is not world
    assert foggy["shape-floor"].interior_medium() is world and foggy["shape-floor"].exterior_medium() is world
    assert foggy["light-0"]["interior"] is world and foggy["light-0"]["exterior"] is world
    # no volume anywhere: the plain path tracer, as before
    assert builder.scene_dict(simple_scene(), S.RenderSettings())["integrator"]["type"] == "path"


def test07_empty_volume_gives_no_medium(variant):
    clear = S.Volumetric(S.Interface(), S.Volume())
    description = simple_scene(shapes=[S.Shape("box", box(), np.eye(4), "clear")], materials={"clear": clear})
    result = builder.scene_dict(description, S.RenderSettings())
    assert result["shape-box"].interior_medium() is None
    image = render([S.Shape("box", box(), np.eye(4), "clear")], {"clear": clear}, spp=256)
    # the interface lets the world through (the spread is the spectral sampling of a white world)
    assert image.mean() == pytest.approx(1.0, abs=0.01)


def test08_exported_folder_renders_the_volume_as_in_memory(variant, tmp_path):
    from scratch_iridescence.mitsuba_bridge.folder import export

    smoke = S.Volumetric(S.Interface(), S.Volume(absorption=(0.7, 0.7, 0.7), scattering=(0.3, 0.3, 0.3)))
    description = simple_scene(film=S.Film(4, 4), camera=TOP, shapes=[S.Shape("box", box(), np.eye(4), "smoke")],
                               materials={"smoke": smoke}, world=UNIFORM)
    description = S.SceneDescription(**{**description.__dict__, "world_volume": S.Volume(absorption=(0.05,) * 3)})
    settings = S.RenderSettings(spp=64, max_depth=32)
    export.export_folder(description, settings, tmp_path / "scene")
    text = (tmp_path / "scene" / "scene.xml").read_text()
    assert '<medium type="homogeneous" name="interior">' in text and 'name="medium"' in text
    from_folder = np.asarray(mi.render(export.load_folder(tmp_path / "scene"), spp=64, seed=3))[..., :3]
    in_memory = np.asarray(mi.render(builder.load_scene(description, settings), spp=64, seed=3))[..., :3]
    assert from_folder == pytest.approx(in_memory, abs=1e-4)


def test09_instanced_volumes_render_as_copies(variant):
    """Two boxes sharing one mesh and one volume become a shapegroup with two instances: the medium
    follows the group's mesh, so the image is the copies' (same samples, same image)."""
    smoke = S.Volumetric(S.Interface(), S.Volume(absorption=(1.0, 1.0, 1.0)))
    mesh = box((0.4, 0.4, 1.0))
    shapes = []
    for x in (-0.25, 0.25):
        matrix = np.eye(4)
        matrix[0, 3] = x
        shapes.append(S.Shape(f"box{x}", mesh, matrix, "smoke"))
    description = simple_scene(film=S.Film(8, 4), camera=TOP, shapes=shapes, materials={"smoke": smoke},
                               world=UNIFORM)
    settings = S.RenderSettings(spp=64, max_depth=32)
    assert any(entry.get("type") == "shapegroup" for entry in builder.scene_dict(description, settings).values()
               if isinstance(entry, dict))
    images = [np.asarray(mi.render(builder.load_scene(description, settings, instancing=instancing), spp=64,
                                   seed=1)) for instancing in (True, False)]
    assert images[0] == pytest.approx(images[1], abs=1e-5)


def test10_viewport_session_sees_the_world_volume_in_every_pass_and_rebuilds_for_a_new_volume(variant):
    """The live viewport's extra sensors (the enlarged first pass, the CPU's strips) start in the world's
    volume too, and a material whose volume changes is rebuilt (a medium is no BSDF parameter)."""
    import dataclasses

    from scratch_iridescence.mitsuba_bridge.render.session import Session

    glow = S.Shape("glow", quad(4.0, "glow"), np.eye(4), "glow")
    smoke = S.Shape("smoke", box((0.5, 0.5, 0.5)), np.eye(4), "smoke")
    materials = {"glow": S.Emission((1.0, 1.0, 1.0)),
                 "smoke": S.Volumetric(S.Interface(), S.Volume(absorption=(0.5,) * 3))}
    camera = S.Camera(camera_at((0, 0, 3)), projection="orthographic", ortho_width=4.0)
    description = simple_scene(film=S.Film(64, 64), camera=camera, shapes=[glow, smoke], materials=materials,
                               world=None)
    description = dataclasses.replace(description, world_volume=S.Volume(absorption=(0.2, 0.2, 0.2)))
    session = Session(description, S.RenderSettings(max_depth=16), samples=16, strip_pixels=64 * 16)
    try:
        preview = session.step(0.0).image  # one sample per pixel of a 16 × 16 film, enlarged
        while not session.finished:
            progress = session.step(0.0)
        assert session.stats["strips"] == 4
        outside = np.ones((64, 64), bool)
        outside[24:40, 24:40] = False  # the smoke box's shadow on the glow
        expected = math.exp(-3 * 0.2)  # without the medium the glow's radiance, 1, would reach the camera
        for image, samples in ((preview, 16 * 16), (progress.image, 64 * 64 * 16)):
            seen = image[..., :3].mean(axis=-1)[outside].mean()
            assert seen == pytest.approx(expected, abs=bernoulli_margin(expected, samples) + 0.01)
        thicker = S.Volumetric(S.Interface(), S.Volume(absorption=(4.0,) * 3))
        session.set_material("smoke", thicker)
        assert session.stats["rebuilds"] == 1
    finally:
        session.close()
