"""``python moving_square.py OUT.blend``: a .blend whose emissive square moves from x = -1 to x = 1 over frames 1-3,
set to render with this engine at 32 x 24 pixels and 16 spp (the farm and render-frames tests' animation)."""
import sys


def save_moving_square(path):
    import bpy
    import scratch_iridescence

    if not hasattr(bpy.types.Scene, "scratch_iridescence"):
        scratch_iridescence.register()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "MITSUBA_SCRATCH"
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 32, 24, 100
    scene.scratch_iridescence.samples = 16
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.ops.mesh.primitive_plane_add(size=0.4, location=(0, 0, 0.1))
    square = bpy.context.active_object
    material = bpy.data.materials.new("glow")
    nodes = material.node_tree.nodes
    nodes.clear()
    emission, output = nodes.new("ShaderNodeEmission"), nodes.new("ShaderNodeOutputMaterial")
    emission.inputs["Strength"].default_value = 5.0
    material.node_tree.links.new(emission.outputs[0], output.inputs[0])
    square.data.materials.append(material)
    for frame, x in ((1, -1.0), (3, 1.0)):
        square.location.x = x
        square.keyframe_insert("location", frame=frame)
    bpy.ops.object.camera_add(location=(0, 0, 5))
    scene.camera = bpy.context.active_object
    scene.frame_start, scene.frame_end = 1, 3
    bpy.ops.wm.save_as_mainfile(filepath=str(path))


if __name__ == "__main__":
    save_moving_square(sys.argv[1])
