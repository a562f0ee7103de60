"""The room both Blender scenes are built in (animated_room.py, material_room.py), as a
Blender user builds one: a 4 x 2.6 x 4 m room whose faces are wound to face into it
(what "flip normals" on a cube gives), a white floor, ceiling, back and front, a red
left and a green right wall, and a camera in the front wall. Blender is Z-up; the
exporter turns it into glTF's Y-up.
"""

import math
import os

import bpy

# Half the width and depth, and the height [m].
X, Y, Z = 2.0, 2.0, 2.6


def principled(name, rgb, roughness=1.0, metallic=0.0):
    """A Principled BSDF material and its node."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return m, bsdf


def quad(name, corners, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.collection.objects.link(obj)
    return obj


def walls():
    """The six walls; returns the white material."""
    white, _ = principled("white", (0.75, 0.75, 0.75))
    red, _ = principled("red", (0.7, 0.08, 0.06))
    green, _ = principled("green", (0.1, 0.6, 0.1))
    x, y, z = X, Y, Z
    quad("floor", [(-x, -y, 0), (x, -y, 0), (x, y, 0), (-x, y, 0)], white)
    quad("ceiling", [(-x, -y, z), (-x, y, z), (x, y, z), (x, -y, z)], white)
    quad("back", [(-x, y, 0), (x, y, 0), (x, y, z), (-x, y, z)], white)
    quad("front", [(-x, -y, 0), (-x, -y, z), (x, -y, z), (x, -y, 0)], white)
    quad("left", [(-x, -y, 0), (-x, y, 0), (-x, y, z), (-x, -y, z)], red)
    quad("right", [(x, -y, 0), (x, -y, z), (x, y, z), (x, y, 0)], green)
    return white


def camera(scene):
    """The camera in the front wall, 70 degrees wide, looking along +Y."""
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens_unit = "FOV"
    cam_data.angle = math.radians(70.0)
    cam = bpy.data.objects.new("camera", cam_data)
    bpy.context.collection.objects.link(cam)
    cam.location = (0.0, -1.95, 1.3)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.camera = cam


def cycles(scene, samples):
    """Cycles on the CPU as the reference for checking by eye: a black world, every
    bounce and caustic path allowed, no clamping or glossy blur, linear EXR."""
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.max_bounces = 16
    scene.cycles.diffuse_bounces = 16
    scene.cycles.glossy_bounces = 16
    scene.cycles.transmission_bounces = 16
    scene.cycles.caustics_reflective = True
    scene.cycles.caustics_refractive = True
    scene.cycles.blur_glossy = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"


def reference_args(args):
    """--cycles PX and --samples N (default 512) from a script's arguments: the
    reference's size (0: no render) and samples."""
    px = int(args[args.index("--cycles") + 1]) if "--cycles" in args else 0
    samples = int(args[args.index("--samples") + 1]) if "--samples" in args else 512
    return px, samples


def render_reference(scene, out, samples):
    """Render `scene` with `cycles` at `samples` to OUT/cycles.exr as half-float
    RGB with ZIP compression, so that a committed test reference stays small."""
    cycles(scene, samples)
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "16"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.render.filepath = os.path.join(out, "cycles.exr")
    bpy.ops.render.render(write_still=True)
