"""Make tests/scenes/blender_film: thin-film iridescence (KHR_materials_iridescence)
in the room of room.py, exported by Blender's own glTF exporter:

- a dark dielectric sphere (base colour 0.05, roughness 0.2) under a film of ior
  1.8 and 320 nm (Principled Thin Film Thickness and IOR);
- a silver metal sphere (base colour 0.95 0.93 0.88, roughness 0.25) under a film
  of ior 1.5 and 250 nm;

both with single-scattering GGX (what glTF's lobe is), lit by material_room.py's
emissive quad under the ceiling.

Blender 4.5's exporter does not write Thin Film, so after the export this script
adds KHR_materials_iridescence to the two materials with Blender's values
(iridescenceFactor 1, iridescenceIor the film's IOR, iridescenceThicknessMaximum
its thickness), as a tool that writes the extension would.

Run with Blender as a Python module (../shared/CRATES.md):

    target/bpy/bin/python tests/blender/film_room.py tests/scenes/blender_film

With --cycles PX, it also renders the scene with Cycles (CPU, 512 samples or
--samples N, PX x PX) to DIR/cycles.exr: Cycles' thin film (exact Fresnel at
both interfaces, its own spectral integration) checks ours. The test's
reference, tests/scenes/blender_film/cycles_64.exr, is

    target/bpy/bin/python tests/blender/film_room.py DIR --cycles 64 --samples 4096
"""

import json
import os
import sys

import bpy
import room
from material_room import ceiling_light, sphere
from room import principled

# (material, base colour, roughness, metallic, film ior, film thickness [nm], centre)
FILMS = [
    ("film_dielectric", (0.05, 0.05, 0.05), 0.2, 0.0, 1.8, 320.0, (-0.9, 0.9, 0.45)),
    ("film_metal", (0.95, 0.93, 0.88), 0.25, 1.0, 1.5, 250.0, (0.9, 0.9, 0.45)),
]


def add_iridescence(path):
    """Write KHR_materials_iridescence into the exported file for FILMS."""
    with open(path) as f:
        g = json.load(f)
    for m in g["materials"]:
        for name, _, _, _, ior, thickness, _ in FILMS:
            if m.get("name") == name:
                m.setdefault("extensions", {})["KHR_materials_iridescence"] = {
                    "iridescenceFactor": 1.0,
                    "iridescenceIor": ior,
                    "iridescenceThicknessMaximum": thickness,
                }
    used = g.setdefault("extensionsUsed", [])
    if "KHR_materials_iridescence" not in used:
        used.append("KHR_materials_iridescence")
    with open(path, "w") as f:
        json.dump(g, f, indent=1)


def main(out, cycles_px, samples):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    os.makedirs(out, exist_ok=True)
    scene = bpy.context.scene
    room.walls()
    for name, rgb, roughness, metallic, ior, thickness, centre in FILMS:
        mat, bsdf = principled(name, rgb, roughness=roughness, metallic=metallic)
        bsdf.inputs["Thin Film Thickness"].default_value = thickness
        bsdf.inputs["Thin Film IOR"].default_value = ior
        bsdf.distribution = "GGX"
        sphere(name + "_sphere", centre, 0.45, mat)
    ceiling_light(room.Z)
    room.camera(scene)
    scene.render.resolution_x = scene.render.resolution_y = cycles_px or 128
    path = os.path.join(out, "blender_film.gltf")
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLTF_SEPARATE", export_cameras=True, export_apply=True)
    add_iridescence(path)
    if cycles_px:
        room.render_reference(scene, out, samples)


if __name__ == "__main__":
    args = sys.argv[1:]
    main(args[0], *room.reference_args(args))
