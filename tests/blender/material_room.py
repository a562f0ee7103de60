"""Make tests/scenes/blender_materials: Blender's material model in a room, exported by
Blender's own glTF exporter (issue 53's "materials from Blender" case).

The room of room.py (red left and green right walls), an emissive quad under the
ceiling for its light, and on the floor and walls what a Blender user's Principled
BSDF materials export to:

- an emissive panel on the back wall whose Emission Color is an image texture
  (a 16 x 8 texel pattern, linear interpolation; Emission Strength 6), exported as
  emissiveTexture with KHR_materials_emissive_strength;
- a sphere with a base-colour image texture (roughness 0.6);
- a rough metal sphere (metallic 1, roughness 0.3);
- a clear glass sphere (transmission 1, roughness 0, IOR 1.5). The exporter writes
  no KHR_materials_volume for it, so glTF makes it thin-walled (a bubble), while
  Cycles renders a solid ball: compare the rest of the image with Cycles.

Run with Blender as a Python module (../shared/CRATES.md):

    target/bpy/bin/python tests/blender/material_room.py tests/scenes/blender_materials

With --cycles PX, it also renders the scene with Cycles (CPU, 1024 samples, PX x PX)
to DIR/cycles.exr, for checking by eye against ours.
"""

import math
import os
import sys

import bpy
import room
from room import principled, quad


def image(name, w, h, texel, out):
    """An image written as PNG beside the scene: texel(i, j) gives linear RGB."""
    img = bpy.data.images.new(name, width=w, height=h, alpha=False)
    px = []
    for j in range(h):
        for i in range(w):
            px.extend([*texel(i, j), 1.0])
    img.pixels = px
    img.filepath_raw = os.path.join(out, f"{name}.png")
    img.file_format = "PNG"
    img.save()
    # Read back from the file, as a user's scene holds it (Cycles then sees what the
    # exporter writes).
    img.source = "FILE"
    img.reload()
    return img


def srgb_decode(v):
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def textured(m, bsdf, img, socket):
    tex = m.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Linear"
    m.node_tree.links.new(tex.outputs["Color"], bsdf.inputs[socket])


def sphere(name, loc, radius, mat):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=radius, location=loc)
    obj = bpy.context.active_object
    obj.name = name
    bpy.ops.object.shade_smooth()
    obj.data.materials.append(mat)
    return obj


def ceiling_light(z):
    """The room's light: an emissive 1 m quad 1 cm under the ceiling at height `z`
    (what a Blender user's area light must become in glTF, which has none),
    facing down."""
    light_mat, bsdf = principled("ceiling_light", (0.0, 0.0, 0.0))
    bsdf.inputs["Emission Color"].default_value = (1.0, 0.95, 0.85, 1.0)
    bsdf.inputs["Emission Strength"].default_value = 12.0
    lz = z - 0.01
    quad("ceiling_light", [(-0.5, -0.5, lz), (-0.5, 0.5, lz), (0.5, 0.5, lz), (0.5, -0.5, lz)], light_mat)


def main(out, cycles_px):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    os.makedirs(out, exist_ok=True)
    scene = bpy.context.scene

    room.walls()
    x, y, z = room.X, room.Y, room.Z

    # The emissive panel: 1.6 x 0.8 m, 1 cm in front of the back wall, facing the room.
    # Warm and cool stripes with a dark border texel, so its edge is textured.
    def panel_texel(i, j):
        if i in (0, 15) or j in (0, 7):
            return (0.05, 0.05, 0.05)
        return (1.0, 0.8, 0.5) if (i // 2) % 2 == 0 else (0.4, 0.6, 1.0)

    panel_img = image("panel_emission", 16, 8, panel_texel, out)
    panel_mat, bsdf = principled("panel", (0.05, 0.05, 0.05))
    textured(panel_mat, bsdf, panel_img, "Emission Color")
    bsdf.inputs["Emission Strength"].default_value = 6.0
    py = y - 0.01
    panel = quad("panel", [(-0.8, py, 1.2), (0.8, py, 1.2), (0.8, py, 2.0), (-0.8, py, 2.0)], panel_mat)
    uv = panel.data.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(panel.data.loops, [(0, 0), (1, 0), (1, 1), (0, 1)]):
        uv.data[loop.index].uv = (u, v)

    checker_img = image(
        "checker", 8, 8, lambda i, j: (0.8, 0.7, 0.1) if (i + j) % 2 == 0 else (0.1, 0.2, 0.7), out
    )
    tex_mat, bsdf = principled("textured", (1.0, 1.0, 1.0), roughness=0.6)
    textured(tex_mat, bsdf, checker_img, "Base Color")
    sphere("textured_sphere", (-1.1, 0.6, 0.45), 0.45, tex_mat)

    metal, _ = principled("rough_metal", (0.9, 0.7, 0.5), roughness=0.3, metallic=1.0)
    sphere("metal_sphere", (0.0, 1.0, 0.45), 0.45, metal)

    glass, bsdf = principled("glass", (1.0, 1.0, 1.0), roughness=0.0)
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    sphere("glass_sphere", (1.1, 0.4, 0.45), 0.45, glass)

    # A point lamp would make the glass sphere's caustic a path no path tracer samples.
    ceiling_light(z)

    room.camera(scene)
    # The exporter derives yfov from the render's aspect ratio: square, as ours renders.
    scene.render.resolution_x = scene.render.resolution_y = max(cycles_px, 128)

    bpy.ops.export_scene.gltf(
        filepath=os.path.join(out, "blender_materials.gltf"),
        export_format="GLTF_SEPARATE",
        export_cameras=True,
        export_apply=True,
    )

    if cycles_px:
        # Cycles filters an 8-bit sRGB texture before decoding it (its images keep
        # such texels as bytes), glTF viewers and we decode first: between the
        # panel's dark border texel and a bright one the two differ by half, 26%
        # in 8 x 8 blocks along the panel's edge. Given the decoded texels as a
        # float image, Cycles filters them as we do.
        for img in (panel_img, checker_img):
            decoded = bpy.data.images.new(img.name + "_linear", *img.size, float_buffer=True)
            decoded.colorspace_settings.name = "Linear Rec.709"
            decoded.pixels = [srgb_decode(v) if k % 4 != 3 else v for k, v in enumerate(img.pixels[:])]
            for m in bpy.data.materials:
                for node in m.node_tree.nodes if m.node_tree else []:
                    if node.type == "TEX_IMAGE" and node.image == img:
                        node.image = decoded
        room.cycles(scene, 1024)
        scene.render.filepath = os.path.join(out, "cycles.exr")
        bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    px = int(args[args.index("--cycles") + 1]) if "--cycles" in args else 0
    main(args[0], px)
