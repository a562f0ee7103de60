"""Write brushed_floor.gltf: a brushed white metal floor (KHR_materials_anisotropy,
F0 = 1, roughness 0.3, strength 0.8, texture coordinates with u along +x, no
TANGENT: the loader generates them) in a grey room with red and green side
walls, lit by a square ceiling light, for `cargo xtask peer` against Mitsuba 3's
roughconductor with alpha_u / alpha_v (its shading frame follows dp/du too).

    python3 tests/scenes/peer/make_brushed_floor.py tests/scenes/peer
"""

import base64
import json
import struct
import sys


def quad(corners, normal, uvs=None):
    """Two triangles of four corners (counter-clockwise seen from `normal`'s side)."""
    return {"p": corners, "n": [normal] * 4, "uv": uvs, "i": [0, 1, 2, 0, 2, 3]}


def main(out):
    S, H = 1.0, 2.0
    meshes = {
        # u along +x, v along +z (glTF: y up).
        "floor": (quad([(-S, 0, -S), (-S, 0, S), (S, 0, S), (S, 0, -S)], (0, 1, 0),
                       [(0, 0), (0, 1), (1, 1), (1, 0)]), 0),
        "ceiling": (quad([(-S, H, -S), (S, H, -S), (S, H, S), (-S, H, S)], (0, -1, 0)), 1),
        "back": (quad([(-S, 0, -S), (S, 0, -S), (S, H, -S), (-S, H, -S)], (0, 0, 1)), 1),
        "left": (quad([(-S, 0, -S), (-S, H, -S), (-S, H, S), (-S, 0, S)], (1, 0, 0)), 2),
        "right": (quad([(S, 0, -S), (S, 0, S), (S, H, S), (S, H, -S)], (-1, 0, 0)), 3),
        "light": (quad([(-0.25, H - 0.01, -0.65), (0.25, H - 0.01, -0.65), (0.25, H - 0.01, -0.15),
                        (-0.25, H - 0.01, -0.15)], (0, -1, 0)), 4),
    }
    materials = [
        {"name": "brushed", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 1,
                                                     "roughnessFactor": 0.3},
         "extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 0.8}}},
        {"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1], "metallicFactor": 0},
         "extensions": {"KHR_materials_specular": {"specularFactor": 0}}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.1, 0.1, 1], "metallicFactor": 0},
         "extensions": {"KHR_materials_specular": {"specularFactor": 0}}},
        {"name": "green", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.6, 0.1, 1], "metallicFactor": 0},
         "extensions": {"KHR_materials_specular": {"specularFactor": 0}}},
        {"name": "light", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0},
         "emissiveFactor": [1, 1, 1],
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 20},
                        "KHR_materials_specular": {"specularFactor": 0}}},
    ]
    data = bytearray()
    views, accessors, gl_meshes, nodes = [], [], [], []

    def add(values, fmt, count, kind, target, minmax=None):
        while len(data) % 4:
            data.append(0)
        start = len(data)
        for v in values:
            data.extend(struct.pack(fmt, *v) if isinstance(v, tuple) else struct.pack(fmt, v))
        views.append({"buffer": 0, "byteOffset": start, "byteLength": len(data) - start, "target": target})
        acc = {"bufferView": len(views) - 1, "componentType": 5126 if "f" in fmt else 5125, "count": count,
               "type": kind}
        if minmax:
            acc["min"], acc["max"] = minmax
        accessors.append(acc)
        return len(accessors) - 1

    for name, (q, mat) in meshes.items():
        p = [tuple(float(c) for c in v) for v in q["p"]]
        lo = [min(v[k] for v in p) for k in range(3)]
        hi = [max(v[k] for v in p) for k in range(3)]
        attrs = {"POSITION": add(p, "<3f", 4, "VEC3", 34962, (lo, hi)),
                 "NORMAL": add([tuple(map(float, n)) for n in q["n"]], "<3f", 4, "VEC3", 34962)}
        if q["uv"]:
            attrs["TEXCOORD_0"] = add([tuple(map(float, t)) for t in q["uv"]], "<2f", 4, "VEC2", 34962)
        idx = add(q["i"], "<I", 6, "SCALAR", 34963)
        gl_meshes.append({"name": name, "primitives": [{"attributes": attrs, "indices": idx, "material": mat}]})
        nodes.append({"name": name, "mesh": len(gl_meshes) - 1})
    nodes.append({"name": "camera", "camera": 0, "translation": [0, 1.6, 1.6],
                  "rotation": [-0.3007058, 0, 0, 0.9537170]})  # 35 degrees down
    gltf = {
        "asset": {"version": "2.0", "generator": "make_brushed_floor.py"},
        "extensionsUsed": ["KHR_materials_anisotropy", "KHR_materials_specular", "KHR_materials_emissive_strength"],
        "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01, "aspectRatio": 1.0}}],
        "meshes": gl_meshes, "materials": materials, "accessors": accessors, "bufferViews": views,
        "buffers": [{"byteLength": len(data),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(data)).decode()}],
    }
    with open(f"{out}/brushed_floor.gltf", "w") as f:
        json.dump(gltf, f, indent=1)


if __name__ == "__main__":
    main(sys.argv[1])
