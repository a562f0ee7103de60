"""Make a Blender room lit by many lamps (issue 55's many-light check): the room of
room.py lit by 48 small coloured point lamps (Blender Point lights of radius 0,
0.5-2.5 W each) 20 cm under the ceiling and a glowing sphere (Emission Strength
3) on the floor, exported by Blender's own glTF exporter (the lamps as
KHR_lights_punctual in candela, the sphere as an emissive mesh).

Run with Blender as a Python module (../shared/CRATES.md):

    target/bpy/bin/python tests/blender/lamps_room.py DIR [--cycles PX [--samples N]]

With --cycles PX, it also renders the scene with Cycles (CPU, 512 samples or N,
PX x PX; Cycles samples its lights with its own light tree) to DIR/cycles.exr,
half floats. The test's reference, tests/scenes/blender_lamps/cycles_64.exr, is

    target/bpy/bin/python tests/blender/lamps_room.py DIR --cycles 64 --samples 4096
"""

import os
import sys

import bpy
import room
from material_room import sphere
from room import principled

COLOURS = [(1.0, 0.55, 0.3), (0.35, 0.6, 1.0), (1.0, 0.9, 0.6), (0.5, 1.0, 0.5), (1.0, 0.4, 0.7), (0.9, 0.9, 0.9)]


def main(out, cycles_px, samples):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    os.makedirs(out, exist_ok=True)
    scene = bpy.context.scene
    room.walls()
    for i in range(6):
        for j in range(8):
            k = i * 8 + j
            lamp = bpy.data.lights.new(f"lamp_{i}_{j}", type="POINT")
            lamp.energy = 0.5 + 2.0 * ((k * 7) % 11) / 10.0
            lamp.color = COLOURS[(i + j) % 6]
            lamp.shadow_soft_size = 0.0
            obj = bpy.data.objects.new(f"lamp_{i}_{j}", lamp)
            obj.location = (-1.75 + 0.7 * i, -1.75 + 0.5 * j, room.Z - 0.2)
            bpy.context.collection.objects.link(obj)
    glow, bsdf = principled("glow", (0.8, 0.8, 0.8))
    bsdf.inputs["Emission Color"].default_value = (1.0, 0.85, 0.6, 1.0)
    bsdf.inputs["Emission Strength"].default_value = 3.0
    sphere("glowing_sphere", (0.3, 0.9, 0.2), 0.2, glow)
    room.camera(scene)
    scene.render.resolution_x = scene.render.resolution_y = cycles_px or 128
    bpy.ops.export_scene.gltf(
        filepath=os.path.join(out, "blender_lamps.gltf"),
        export_format="GLTF_SEPARATE",
        export_cameras=True,
        export_lights=True,
        export_apply=True,
    )
    if cycles_px:
        room.render_reference(scene, out, samples)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(args[0], *room.reference_args(args))
