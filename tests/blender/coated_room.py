"""Make tests/scenes/blender_coated: the rest of Blender's material model, as issue 54
found it, in the room of room.py, exported by Blender's own glTF exporter:

- a clear-coated red sphere (Principled Coat Weight 1, coat roughness 0.03):
  KHR_materials_clearcoat;
- a velvet box (Sheen Weight 1, sheen roughness 0.5): KHR_materials_sheen;
- a brushed-metal sphere (metallic 1, roughness 0.35, Anisotropic 0.8), exported
  with its tangents: KHR_materials_anisotropy;
- a floor tile: a thin scaled cube with Blender's default cube UVs and a 4 x 4
  base-colour texture read with "Closest" interpolation (the sampler's NEAREST):
  the texels its top face covers are yellow, the rest lilac.

Lit by an emissive quad under the ceiling, as material_room.py's room is.

Run with Blender as a Python module (../shared/CRATES.md):

    target/bpy/bin/python tests/blender/coated_room.py tests/scenes/blender_coated

With --cycles PX, it also renders the scene with Cycles (CPU, 512 samples, PX x
PX) to DIR/cycles.exr. With --gltf-anisotropy as well, Cycles renders the brushed
sphere as glTF defines the exported file's anisotropy rather than as Blender
does (the exporter writes Blender's Anisotropic as anisotropyStrength, but
Cycles stretches alpha along the tangent by 1 / sqrt(1 - 0.9 s) and glTF to
mix(alpha, 1, s^2)): its roughness and anisotropy set, after the export, to give
Cycles' alpha_x and alpha_y the file's alpha_t and alpha_b, with single-scattering
GGX, so that Cycles checks our anisotropic lobe. With --draco or --webp, the export uses Blender's Draco
mesh compression or WebP images, as a user who wants small files does (the
file name gets _draco or _webp).
"""

import math
import os
import sys

import bpy
import room
from material_room import ceiling_light, image, sphere
from room import principled

# The tile's texture: which texels are yellow. Blender's default cube UVs put
# the top face (+Z) on u in [0.625, 0.875], v in [0.5, 0.75]: texel columns 2
# and 3 of row 2 (rows counted from the bottom, as Blender stores them).
YELLOW = (0.85, 0.65, 0.05)
LILAC = (0.55, 0.45, 0.75)


def tile_texel(i, j):
    return YELLOW if j == 2 and i in (2, 3) else LILAC


def main(out, cycles_px, draco, webp, gltf_anisotropy):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    os.makedirs(out, exist_ok=True)
    scene = bpy.context.scene
    room.walls()
    z = room.Z

    coat, bsdf = principled("coated_red", (0.7, 0.05, 0.04), roughness=0.5)
    bsdf.inputs["Coat Weight"].default_value = 1.0
    bsdf.inputs["Coat Roughness"].default_value = 0.03
    sphere("coated_sphere", (-1.0, 0.8, 0.4), 0.4, coat)

    velvet, bsdf = principled("velvet", (0.15, 0.05, 0.3), roughness=1.0)
    bsdf.inputs["Sheen Weight"].default_value = 1.0
    bsdf.inputs["Sheen Roughness"].default_value = 0.5
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0.1, 1.2, 0.3))
    obj = bpy.context.active_object
    obj.name = "velvet_box"
    obj.rotation_euler = (0.0, 0.0, math.radians(25.0))
    obj.data.materials.append(velvet)

    brushed, bsdf = principled("brushed_metal", (0.9, 0.9, 0.9), roughness=0.35, metallic=1.0)
    bsdf.inputs["Anisotropic"].default_value = 0.8
    sphere("brushed_sphere", (1.1, 0.6, 0.4), 0.4, brushed)

    img = image("tile", 4, 4, tile_texel, out)
    tile_mat, bsdf = principled("tile", (1.0, 1.0, 1.0), roughness=0.8)
    tex = tile_mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Closest"
    tile_mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, -0.2, 0.01))
    obj = bpy.context.active_object
    obj.name = "floor_tile"
    obj.scale = (0.5, 0.5, 0.01)
    obj.data.materials.append(tile_mat)

    ceiling_light(z)

    room.camera(scene)
    scene.render.resolution_x = scene.render.resolution_y = max(cycles_px, 128)
    name = "blender_coated" + ("_draco" if draco else "") + ("_webp" if webp else "")
    bpy.ops.export_scene.gltf(
        filepath=os.path.join(out, f"{name}.gltf"),
        export_format="GLTF_SEPARATE",
        export_cameras=True,
        export_apply=True,
        export_tangents=True,
        export_draco_mesh_compression_enable=draco,
        export_image_format="WEBP" if webp else "AUTO",
    )
    if cycles_px and gltf_anisotropy:
        # glTF: alpha_t = a + (1 - a) s^2, alpha_b = a (a = roughness^2);
        # Cycles: alpha_x = r^2 / q, alpha_y = r^2 q, q = sqrt(1 - 0.9 s_c).
        a = 0.35 ** 2
        alpha_t, alpha_b = a + (1.0 - a) * 0.8 ** 2, a
        q = math.sqrt(alpha_b / alpha_t)
        b = brushed.node_tree.nodes["Principled BSDF"]
        b.inputs["Roughness"].default_value = (alpha_t * alpha_b) ** 0.25
        b.inputs["Anisotropic"].default_value = (1.0 - q * q) / 0.9
        b.distribution = "GGX"
    if cycles_px:
        room.cycles(scene, 512)
        scene.render.filepath = os.path.join(out, "cycles.exr")
        bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    px = int(args[args.index("--cycles") + 1]) if "--cycles" in args else 0
    main(args[0], px, "--draco" in args, "--webp" in args, "--gltf-anisotropy" in args)
