"""A Blender scene as the renderer reads it: the scene through Blender's own glTF
exporter, and what that exporter never writes, converted into pipeline.toml:

- the world: an Environment Texture as an EXR image (the renderer reads it in
  Blender's orientation: the image's centre faces +X, its top row the zenith),
  its strength and the Mapping node's rotation about Z; a plain Background colour
  as one colour of radiance; anything else (a Sky Texture, a node network)
  rendered by Cycles into an equirectangular image (`bake_world`);
- volumes: Principled Volume, Volume Scatter and Volume Absorption (and their
  sums and mixes) on object materials as `[media.NAME]` with absorption and
  scattering coefficients [m^-1 per channel] and the Henyey-Greenstein g, as
  Cycles defines them (intern/cycles/kernel/svm/closure.h,
  svm_node_principled_volume and svm_node_closure_volume):
      Principled Volume:  sigma_s = density * color,
                          sigma_a = density * max(1 - color, 0)
                                            * max(1 - sqrt(absorption color), 0)
      Volume Scatter:     sigma_s = density * color
      Volume Absorption:  sigma_a = density * (1 - color)
  A mesh whose material has a volume but no surface becomes an index-matched
  boundary (smooth transmission, ior 1) around its medium; a world volume is the
  scene's medium, `[media.scene]`;
- a sun's angular diameter (`sun_angle_deg`), the frame range and frame rate of
  an animation.

What cannot be converted is listed in `Export.warnings`, once each.
"""

import json
import math
import os

import bpy

from . import exr

# The layers the renderer writes into image.exr and the render passes they become.
PASSES = [("direct", "Direct"), ("indirect", "Indirect"), ("caustic", "Caustic"), ("specular", "Specular"),
          ("volume", "Volume")]


class Unconvertible(Exception):
    """A node set-up the renderer has no equivalent for; the message says what."""


class Medium:
    """A homogeneous medium: absorption and scattering coefficients [m^-1 per RGB
    channel] and the Henyey-Greenstein asymmetry g."""

    def __init__(self, sigma_a=(0.0, 0.0, 0.0), sigma_s=(0.0, 0.0, 0.0), g=0.0):
        self.sigma_a = tuple(float(x) for x in sigma_a)
        self.sigma_s = tuple(float(x) for x in sigma_s)
        self.g = float(g)

    def scaled(self, w):
        return Medium([w * x for x in self.sigma_a], [w * x for x in self.sigma_s], self.g)

    def plus(self, other):
        """Two media in the same place: coefficients add; g is the mean of their
        g weighed by scattering (a sum of two Henyey-Greenstein lobes is not one;
        the caller warns when they differ)."""
        ws, wo = sum(self.sigma_s), sum(other.sigma_s)
        g = (self.g * ws + other.g * wo) / (ws + wo) if ws + wo > 0 else 0.0
        return Medium([a + b for a, b in zip(self.sigma_a, other.sigma_a)],
                      [a + b for a, b in zip(self.sigma_s, other.sigma_s)], g)

    def toml(self, name):
        return (f"[media.{json.dumps(name)}]\nsigma_a = {_floats(self.sigma_a)}\n"
                f"sigma_s = {_floats(self.sigma_s)}\ng = {self.g!r}\n")


def _floats(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def _value(socket):
    """An input's own value: a float or an RGB triple. A linked input (a
    texture, an attribute, a node network) cannot be converted."""
    if socket.is_linked:
        raise Unconvertible(f"'{socket.name}' of node '{socket.node.name}' is driven by other nodes")
    v = socket.default_value
    try:
        return tuple(v)[:3]
    except TypeError:
        return float(v)


def _source(socket):
    """The node feeding `socket` (through reroutes), or None."""
    while socket.is_linked:
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return None
        node = link.from_node
        if node.bl_idname != "NodeReroute":
            return node
        socket = node.inputs[0]
    return None


def volume(socket, warnings):
    """The medium a material or world output's Volume input describes (None when
    nothing is linked)."""
    node = _source(socket)
    if node is None:
        return None
    kind = node.bl_idname
    if kind == "ShaderNodeVolumePrincipled":
        density = max(_value(node.inputs["Density"]), 0.0)
        color = [max(c, 0.0) for c in _value(node.inputs["Color"])]
        absorption = [max(c, 0.0) for c in _value(node.inputs["Absorption Color"])]
        g = _value(node.inputs["Anisotropy"])
        for name in ("Emission Strength", "Blackbody Intensity"):
            if node.inputs[name].is_linked or _value(node.inputs[name]) > 0.0:
                warnings.add(f"{node.name}: {name} (emission in a volume) is not rendered")
        sigma_s = [density * c for c in color]
        sigma_a = [density * max(1.0 - c, 0.0) * max(1.0 - math.sqrt(a), 0.0) for c, a in zip(color, absorption)]
        return Medium(sigma_a, sigma_s, g)
    if kind == "ShaderNodeVolumeScatter":
        phase = getattr(node, "phase", "HENYEY_GREENSTEIN")
        if phase != "HENYEY_GREENSTEIN":
            warnings.add(f"{node.name}: the {phase} phase function is rendered as Henyey-Greenstein")
        density = max(_value(node.inputs["Density"]), 0.0)
        color = [max(c, 0.0) for c in _value(node.inputs["Color"])]
        g = _value(node.inputs["Anisotropy"]) if "Anisotropy" in node.inputs else 0.0
        return Medium((0.0, 0.0, 0.0), [density * c for c in color], g)
    if kind == "ShaderNodeVolumeAbsorption":
        density = max(_value(node.inputs["Density"]), 0.0)
        color = [max(c, 0.0) for c in _value(node.inputs["Color"])]
        return Medium([density * max(1.0 - c, 0.0) for c in color], (0.0, 0.0, 0.0), 0.0)
    if kind == "ShaderNodeAddShader":
        parts = [m for m in (volume(node.inputs[0], warnings), volume(node.inputs[1], warnings)) if m]
        return _sum(parts, node, warnings)
    if kind == "ShaderNodeMixShader":
        fac = min(max(_value(node.inputs[0]), 0.0), 1.0)
        parts = [m.scaled(w) for m, w in ((volume(node.inputs[1], warnings), 1.0 - fac),
                                          (volume(node.inputs[2], warnings), fac)) if m]
        return _sum(parts, node, warnings)
    raise Unconvertible(f"volume node '{node.name}' ({kind}) has no equivalent")


def _sum(parts, node, warnings):
    if not parts:
        return None
    if len({round(m.g, 6) for m in parts if sum(m.sigma_s) > 0}) > 1:
        warnings.add(f"{node.name}: volumes of different anisotropy are rendered with their mean g")
    total = parts[0]
    for m in parts[1:]:
        total = total.plus(m)
    return total


def _output(tree, kind):
    """The active output node of a node tree."""
    outs = [n for n in tree.nodes if n.bl_idname == kind]
    active = [n for n in outs if getattr(n, "is_active_output", False)]
    return (active or outs or [None])[0]


def material_medium(mat, warnings):
    """(medium or None, True when the material has a surface shader)."""
    if mat is None or not mat.use_nodes or mat.node_tree is None:
        return None, True
    out = _output(mat.node_tree, "ShaderNodeOutputMaterial")
    if out is None:
        return None, True
    try:
        medium = volume(out.inputs["Volume"], warnings)
    except Unconvertible as e:
        warnings.add(f"material '{mat.name}': {e}; its volume is left out")
        medium = None
    return medium, _source(out.inputs["Surface"]) is not None


class World:
    """The world as pipeline.toml's keys: `environment` (a file name or an RGB
    colour of radiance [W sr^-1 m^-2]), its strength and rotation [degrees], and
    the scene medium."""

    def __init__(self):
        self.environment = None
        self.strength = 1.0
        self.rotation_deg = 0.0
        self.medium = None

    def toml(self):
        lines = []
        if isinstance(self.environment, str):
            lines.append(f"environment = {json.dumps(self.environment)}")
        elif self.environment is not None:
            lines.append(f"environment = {_floats(self.environment)}")
        if self.environment is not None:
            lines.append(f"environment_strength = {float(self.strength)!r}")
            lines.append(f"environment_rotation_deg = {float(self.rotation_deg)!r}")
        return "\n".join(lines) + ("\n" if lines else "")


def world(scene, folder, warnings):
    """Convert `scene`'s world; images are written into `folder`."""
    w = World()
    bw = scene.world
    if bw is None:
        return w
    if not bw.use_nodes or bw.node_tree is None:
        w.environment = tuple(bw.color)
        return w
    out = _output(bw.node_tree, "ShaderNodeOutputWorld")
    if out is None:
        return w
    try:
        w.medium = volume(out.inputs["Volume"], warnings)
    except Unconvertible as e:
        warnings.add(f"world: {e}; its volume is left out")
    node = _source(out.inputs["Surface"])
    if node is None:
        return w
    try:
        if node.bl_idname not in ("ShaderNodeBackground", "ShaderNodeEmission"):
            raise Unconvertible(f"the world's surface is a {node.bl_idname}")
        w.strength = max(_value(node.inputs["Strength"]), 0.0)
        colour = _source(node.inputs["Color"])
        if colour is None:
            w.environment = _value(node.inputs["Color"])
            return w
        if colour.bl_idname != "ShaderNodeTexEnvironment" or colour.projection != "EQUIRECTANGULAR":
            raise Unconvertible(f"the world's colour comes from a {colour.bl_idname}")
        w.rotation_deg = _mapping_rotation(colour.inputs["Vector"])
        w.environment = _environment_file(colour.image, folder)
    except Unconvertible as e:
        # Anything else the world shows (a Sky Texture, gradients, mixes): render
        # it with Cycles into an equirectangular image, strength and all.
        warnings.add(f"world: {e}; baked by Cycles into an image")
        w.environment, w.strength, w.rotation_deg = bake_world(scene, os.path.join(folder, "world.exr")), 1.0, 0.0
    return w


def _mapping_rotation(vector):
    """The Environment Texture's rotation about the up axis [degrees], from a
    Mapping node on its Vector input: a Point mapping's rotation about Z of
    +a turns the environment by -a, the renderer's environment_rotation_deg
    (checked against Cycles by the tests); other rotations, locations and
    scales cannot be converted."""
    node = _source(vector)
    if node is None:
        return 0.0
    if node.bl_idname != "ShaderNodeMapping":
        raise Unconvertible(f"the environment's vector comes from a {node.bl_idname}")
    rot = _value(node.inputs["Rotation"])
    loc = _value(node.inputs["Location"]) if "Location" in node.inputs else (0, 0, 0)
    scale = _value(node.inputs["Scale"]) if "Scale" in node.inputs else (1, 1, 1)
    if abs(rot[0]) > 1e-6 or abs(rot[1]) > 1e-6 or any(abs(x - 1) > 1e-6 for x in scale) or (
            node.vector_type == "POINT" and any(abs(x) > 1e-6 for x in loc)):
        raise Unconvertible("the environment's mapping does more than turn it about Z")
    source = _source(node.inputs["Vector"])
    if source is not None and source.bl_idname != "ShaderNodeTexCoord":
        raise Unconvertible(f"the mapping's vector comes from a {source.bl_idname}")
    # The Mapping node turns the lookup direction; the environment appears turned
    # the other way (a Texture-type mapping turns it by the inverse).
    sign = 1.0 if node.vector_type == "TEXTURE" else -1.0
    return sign * math.degrees(rot[2])


def _environment_file(image, folder):
    """The environment image as a file the renderer reads: the file itself when it
    is an OpenEXR or Radiance HDR on disk, else its pixels written as EXR
    (linear radiance)."""
    if image is None:
        raise Unconvertible("the Environment Texture has no image")
    path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
    if not image.packed_file and path.lower().endswith((".exr", ".hdr")) and os.path.isfile(path):
        return os.path.abspath(path)
    w, h = image.size
    if w == 0 or h == 0:
        raise Unconvertible(f"the image '{image.name}' has no pixels")
    import numpy as np

    px = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)[:, :, :3]
    if not image.is_float and image.colorspace_settings.name == "sRGB":
        px = np.where(px <= 0.04045, px / 12.92, ((px + 0.055) / 1.055) ** 2.4)
    out = os.path.join(folder, "world.exr")
    exr.write_rgb(out, px[::-1])
    return out


def bake_world(scene, path, width=1024, samples=16):
    """Render `scene`'s world alone with Cycles through an equirectangular camera
    at the origin, oriented so the image is what an Environment Texture would be
    (its centre towards +X, its top row the zenith), and save it as EXR. A
    temporary scene that shares the world; nothing stays behind."""
    tmp = bpy.data.scenes.new("photon_map_world_bake")
    cam_data = bpy.data.cameras.new("photon_map_world_bake")
    cam = bpy.data.objects.new("photon_map_world_bake", cam_data)
    try:
        tmp.world = scene.world
        tmp.collection.objects.link(cam)
        tmp.camera = cam
        cam_data.type = "PANO"
        if hasattr(cam_data, "panorama_type"):
            cam_data.panorama_type = "EQUIRECTANGULAR"
        else:
            cam_data.cycles.panorama_type = "EQUIRECTANGULAR"
        # Cycles' equirectangular camera looks along its local -Z with +Y up; turned
        # to look along +X with +Z up, its image's centre is the world's +X.
        cam.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
        r = tmp.render
        r.engine = "CYCLES"
        tmp.cycles.device = "CPU"
        tmp.cycles.samples = samples
        r.resolution_x, r.resolution_y, r.resolution_percentage = width, width // 2, 100
        r.image_settings.file_format = "OPEN_EXR"
        r.image_settings.color_depth = "32"
        tmp.view_settings.view_transform = "Standard"
        r.filepath = path
        bpy.ops.render.render(write_still=True, scene=tmp.name)
    finally:
        bpy.data.objects.remove(cam)
        bpy.data.cameras.remove(cam_data)
        bpy.data.scenes.remove(tmp)
    return path


class Export:
    """What `export` wrote: the glTF file, the pipeline file's top-level scene keys
    and its `[media.NAME]` tables (TOML text), and the warnings (each once)."""

    def __init__(self, gltf, keys, tables, warnings):
        self.gltf = gltf
        self.keys = keys
        self.tables = tables
        self.warnings = warnings


def _needs_tangents(materials):
    for m in materials:
        if m and m.use_nodes and m.node_tree:
            for n in m.node_tree.nodes:
                if n.bl_idname == "ShaderNodeBsdfPrincipled" and "Anisotropic" in n.inputs:
                    a = n.inputs["Anisotropic"]
                    if a.is_linked or a.default_value > 0.0:
                        return True
    return False


def export(scene, folder, animation):
    """Export `scene` into `folder` (scene.gltf, its buffers and images, the world
    image) and return the pipeline file's scene keys (world, sun sizes, media;
    the frame range when `animation`)."""
    warnings = set()
    os.makedirs(folder, exist_ok=True)
    objects = [o for o in scene.objects if o.visible_get() and not o.hide_render]
    materials = {s.material for o in objects for s in getattr(o, "material_slots", []) if s.material}

    # Volumes first: a material with a volume and no surface is written as an
    # index-matched boundary after the export.
    media, boundaries = {}, set()
    for mat in sorted(materials, key=lambda m: m.name):
        medium, has_surface = material_medium(mat, warnings)
        if medium is None:
            continue
        if ":" in mat.name or mat.name == "scene":
            warnings.add(f"material '{mat.name}': its name cannot name a medium; its volume is left out")
            continue
        media[mat.name] = medium
        if not has_surface:
            boundaries.add(mat.name)

    for o in objects:
        if o.type in ("CURVES", "VOLUME"):
            warnings.add(f"object '{o.name}' ({o.type.lower()}) is not exported by glTF")
        elif o.type == "LIGHT" and o.data.type == "AREA":
            warnings.add(f"area light '{o.name}' is not exported by glTF (use an emissive mesh)")
        elif o.type == "MESH":
            for mod in o.modifiers:
                if mod.type == "PARTICLE_SYSTEM" and mod.show_render:
                    warnings.add(f"object '{o.name}': particles and hair are not exported by glTF")
        if o.type == "LIGHT" and o.data.type in ("POINT", "SPOT") and o.data.shadow_soft_size > 0.0:
            warnings.add(f"light '{o.name}': its radius ({o.data.shadow_soft_size:g} m) is rendered as a point")

    gltf = os.path.join(folder, "scene.gltf")
    bpy.ops.export_scene.gltf(
        filepath=gltf,
        check_existing=False,
        export_format="GLTF_SEPARATE",
        export_yup=True,
        export_apply=True,
        export_cameras=True,
        export_lights=True,
        export_import_convert_lighting_mode="SPEC",
        export_animations=animation,
        export_tangents=_needs_tangents(materials),
        use_renderable=True,
        use_active_scene=True,
    )
    _solid_transmission(gltf, boundaries)

    w = world(scene, folder, warnings)
    suns = {o.name: math.degrees(o.data.angle) for o in objects if o.type == "LIGHT" and o.data.type == "SUN"}
    lines = ['scene = "scene.gltf"', 'light_units = "photometric"', w.toml().rstrip("\n")]
    suns = {n: a for n, a in suns.items() if 0.0 < a < 180.0}
    if suns:
        lines.append("sun_angle_deg = { " + ", ".join(f"{json.dumps(n)} = {a!r}" for n, a in suns.items()) + " }")
    fps = scene.render.fps / scene.render.fps_base
    if animation:
        lines.append(f"frames = [{scene.frame_start}, {scene.frame_end}]")
        lines.append(f"fps = {fps!r}")
    tables = [m.toml(name) for name, m in sorted(media.items())]
    if w.medium is not None:
        tables.append(w.medium.toml("scene"))
    return Export(gltf, "\n".join(x for x in lines if x) + "\n", tables, sorted(warnings))


def _solid_transmission(gltf, boundaries):
    """Edit the exported materials as Cycles renders them:

    - a material with transmission and no KHR_materials_volume is thin-walled by
      the glTF specification (light passes straight through, unrefracted), but
      Cycles refracts through a Principled BSDF's transmission as through a solid:
      it gets a KHR_materials_volume with thicknessFactor 1 (no attenuation);
    - the materials `boundaries` (a volume and no surface) become index-matched
      boundaries: smooth, clear transmission with ior 1 around their medium.
    """
    with open(gltf, encoding="utf-8") as f:
        doc = json.load(f)
    changed = set()
    for m in doc.get("materials", []):
        ext = m.setdefault("extensions", {})
        if m.get("name") in boundaries:
            m["pbrMetallicRoughness"] = {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0, "roughnessFactor": 0}
            ext["KHR_materials_transmission"] = {"transmissionFactor": 1}
            ext["KHR_materials_ior"] = {"ior": 1}
            m.pop("emissiveFactor", None)
            changed |= {"KHR_materials_transmission", "KHR_materials_ior"}
        t = ext.get("KHR_materials_transmission")
        if t and (t.get("transmissionFactor", 0) > 0 or "transmissionTexture" in t):
            v = ext.get("KHR_materials_volume")
            if v is None or v.get("thicknessFactor", 0) <= 0:
                ext["KHR_materials_volume"] = {**(v or {}), "thicknessFactor": 1}
                changed.add("KHR_materials_volume")
        if not ext:
            del m["extensions"]
    if not changed:
        return
    used = doc.setdefault("extensionsUsed", [])
    used.extend(sorted(e for e in changed if e not in used))
    tmp = gltf + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, gltf)
