"""Make tests/scenes/blender_room: a room as a Blender user builds one, exported by
Blender's own glTF exporter (issue 53's animated room).

A 4 x 2.6 x 4 m room (a cube seen from inside: its faces' normals flipped), a red
left and a green right wall, a point lamp circling under the ceiling and a box
sliding across the floor (LINEAR keys, 24 fps, 2 s), a camera in the front wall.
Run with Blender as a Python module (../shared/CRATES.md):

    target/bpy/bin/python tests/blender/animated_room.py tests/scenes/blender_room

With --cycles FRAME..., it also renders those frames with Cycles (CPU, 512
samples) to DIR/cycles_FRAME.exr, for checking by eye against ours.
"""

import math
import os
import sys

import bpy


def material(name, rgb):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    return m


def quad(name, corners, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(obj)
    return obj


def main(out, cycles_frames):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 24
    scene.frame_start, scene.frame_end = 0, 48

    white = material("white", (0.75, 0.75, 0.75))
    red = material("red", (0.7, 0.08, 0.06))
    green = material("green", (0.1, 0.6, 0.1))
    # Blender is Z-up; the exporter turns it into glTF's Y-up.
    x, y, z = 2.0, 2.0, 2.6
    # Faces wound to face into the room (what "flip normals" on a cube gives).
    quad("floor", [(-x, -y, 0), (x, -y, 0), (x, y, 0), (-x, y, 0)], white)
    quad("ceiling", [(-x, -y, z), (-x, y, z), (x, y, z), (x, -y, z)], white)
    quad("back", [(-x, y, 0), (x, y, 0), (x, y, z), (-x, y, z)], white)
    quad("front", [(-x, -y, 0), (-x, -y, z), (x, -y, z), (x, -y, 0)], white)
    quad("left", [(-x, -y, 0), (-x, y, 0), (-x, y, z), (-x, -y, z)], red)
    quad("right", [(x, -y, 0), (x, -y, z), (x, y, z), (x, y, 0)], green)

    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-1.0, 0.6, 0.4))
    box = bpy.context.active_object
    box.name = "sliding_box"
    box.scale = (0.8, 0.8, 0.8)
    box.data.materials.append(white)
    for frame, bx in [(0, -1.0), (48, 1.0)]:
        box.location.x = bx
        box.keyframe_insert("location", frame=frame)

    lamp_data = bpy.data.lights.new("lamp", "POINT")
    lamp_data.energy = 400.0
    lamp_data.shadow_soft_size = 0.0
    lamp = bpy.data.objects.new("lamp", lamp_data)
    bpy.context.collection.objects.link(lamp)
    for frame in range(0, 49, 6):
        a = 2.0 * math.pi * frame / 48.0
        lamp.location = (1.0 * math.cos(a), 1.0 * math.sin(a), 2.2)
        lamp.keyframe_insert("location", frame=frame)

    for obj in [box, lamp]:
        for fc in obj.animation_data.action.fcurves:
            for k in fc.keyframe_points:
                k.interpolation = "LINEAR"

    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens_unit = "FOV"
    cam_data.angle = math.radians(70.0)
    cam = bpy.data.objects.new("camera", cam_data)
    bpy.context.collection.objects.link(cam)
    cam.location = (0.0, -1.95, 1.3)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.camera = cam

    os.makedirs(out, exist_ok=True)
    bpy.ops.export_scene.gltf(
        filepath=os.path.join(out, "blender_room.gltf"),
        export_format="GLTF_SEPARATE",
        export_animations=True,
        export_cameras=True,
        export_lights=True,
        export_apply=True,
    )

    if cycles_frames:
        world = bpy.data.worlds.new("black")
        world.use_nodes = True
        world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
        scene.world = world
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = 512
        scene.cycles.max_bounces = 16
        scene.cycles.diffuse_bounces = 16
        scene.view_settings.view_transform = "Standard"
        scene.render.resolution_x = scene.render.resolution_y = 128
        scene.render.image_settings.file_format = "OPEN_EXR"
        for f in cycles_frames:
            scene.frame_set(f)
            scene.render.filepath = os.path.join(out, f"cycles_{f}.exr")
            bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    frames = [int(a) for a in args[args.index("--cycles") + 1 :]] if "--cycles" in args else []
    main(args[0], frames)
