"""Instanced objects (collection instances, geometry-nodes instances) gather into shapes sharing one mesh,
which the builder turns into one ``shapegroup`` with an ``instance`` per object."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from render_scenes import add_camera  # noqa: E402
from scratch_iridescence.addon.render.gather import gather_scene  # noqa: E402
from scratch_iridescence.mitsuba_bridge import builder  # noqa: E402
from scratch_iridescence.mitsuba_bridge.device import variants  # noqa: E402
from scratch_iridescence.mitsuba_bridge.render.activation import activate
from scratch_iridescence.mitsuba_bridge import scene as S  # noqa: E402


@pytest.fixture
def staged(empty_scene):
    add_camera(empty_scene)
    activate("llvm_ad_spectral")
    return empty_scene


def kinds(description):
    result = builder.scene_dict(description, S.RenderSettings())
    return [value.get("type") if isinstance(value, dict) else "mesh" for key, value in result.items()
            if key.startswith(("shape-", "group-"))]


def test_collection_instances_share_one_mesh_and_become_one_shapegroup(staged):
    source = bpy.data.collections.new("Pebbles")  # not linked to the scene: only its instances render
    mesh = bpy.data.meshes.new("pebble")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    source.objects.link(bpy.data.objects.new("Pebble", mesh))
    for index in range(20):
        empty = bpy.data.objects.new(f"Instance{index}", None)
        empty.instance_type, empty.instance_collection = "COLLECTION", source
        empty.location = (index, 0, 0)
        staged.collection.objects.link(empty)
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    assert len(description.shapes) == 20 and len({id(shape.mesh) for shape in description.shapes}) == 1
    offsets = sorted(shape.to_world[0, 3] for shape in description.shapes)
    assert np.allclose(offsets, np.arange(20))
    assert kinds(description).count("shapegroup") == 1 and kinds(description).count("instance") == 20


def test_geometry_nodes_instances_become_one_shapegroup(staged):
    host = bpy.data.objects.new("Host", bpy.data.meshes.new("host"))
    staged.collection.objects.link(host)
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket(name="Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    grid = tree.nodes.new("GeometryNodeMeshGrid")
    grid.inputs["Vertices X"].default_value, grid.inputs["Vertices Y"].default_value = 5, 4
    instance = tree.nodes.new("GeometryNodeInstanceOnPoints")
    tree.links.new(grid.outputs["Mesh"], instance.inputs["Points"])
    tree.links.new(tree.nodes.new("GeometryNodeMeshIcoSphere").outputs["Mesh"], instance.inputs["Instance"])
    tree.links.new(instance.outputs["Instances"], tree.nodes.new("NodeGroupOutput").inputs["Geometry"])
    host.modifiers.new("Scatter", "NODES").node_group = tree
    description = gather_scene(bpy.context.evaluated_depsgraph_get())
    assert len(description.shapes) == 20 and len({id(shape.mesh) for shape in description.shapes}) == 1
    assert kinds(description).count("shapegroup") == 1 and kinds(description).count("instance") == 20
