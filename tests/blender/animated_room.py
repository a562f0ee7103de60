"""Make tests/scenes/blender_room: a room as a Blender user builds one, exported by
Blender's own glTF exporter (issue 53's animated room).

The room of room.py (a red left and a green right wall, a camera in the front
wall), a point lamp circling under the ceiling and a box sliding across the floor
(LINEAR keys, 24 fps, 2 s).
Run with Blender as a Python module (../shared/CRATES.md):

    target/bpy/bin/python tests/blender/animated_room.py tests/scenes/blender_room

With --cycles FRAME..., it also renders those frames with Cycles (CPU, 512
samples) to DIR/cycles_FRAME.exr, for checking by eye against ours.
"""

import math
import os
import sys

import bpy
import room


def main(out, cycles_frames):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 24
    scene.frame_start, scene.frame_end = 0, 48

    white = room.walls()

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

    room.camera(scene)

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
        room.cycles(scene, 512)
        scene.render.resolution_x = scene.render.resolution_y = 128
        for f in cycles_frames:
            scene.frame_set(f)
            scene.render.filepath = os.path.join(out, f"cycles_{f}.exr")
            bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    frames = [int(a) for a in args[args.index("--cycles") + 1 :]] if "--cycles" in args else []
    main(args[0], frames)
