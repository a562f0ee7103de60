"""Photon Map: the photon-mapping renderer (Christensen 1999's batch pipeline, and
the path tracer, SPPM, BDPT and VCM beside it) as a Blender render engine.

F12 (or `bpy.ops.render.render()`) exports the scene with Blender's glTF
exporter, converts what the exporter cannot write (the world, volumes, sun
sizes: convert.py), writes pipeline.toml with the settings of the Render
Properties panel, runs the renderer's stages (`xtask run`, run.py) and loads
image.exr into the Render Result, its layers as the passes Direct, Indirect,
Caustic, Specular and Volume. Render Animation renders the frame range as the
renderer's frame tasks (one per frame, photon maps traced per frame) and Blender
writes each frame where its output path says.

The settings are made from the renderer's own parameter definitions
(schema.json, written by `cargo xtask blender-addon` from `cargo xtask schema`):
their names, documentation, defaults and ranges are not repeated here.
"""

import json
import os
import queue
import shutil
import tempfile
import time

import bpy

from . import convert, run

_HERE = os.path.dirname(os.path.abspath(__file__))

# The warnings of the last export (what could not be converted), for scripts and tests.
last_warnings = []
# The folder of the last render (kept when the preference says so), for scripts and tests.
last_folder = None
# For scripts and tests: a render behaves as if Esc were pressed this many seconds
# after it started (None: only when it is).
break_after = None
# When Esc was seen in the last render (time.time()), for scripts and tests.
stop_requested_at = None


def _schema():
    path = os.path.join(_HERE, "schema.json")
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except OSError as e:
        raise RuntimeError(f"{path}: cannot read ({e.strerror}): build the add-on with cargo xtask blender-addon") from e


SCHEMA = _schema()

# Sections of pipeline.toml shown as settings, and the keys Blender itself decides
# (the image size, the exposure of a PNG Blender does not use).
SECTIONS = ["trace", "irradiance", "render", "sppm", "bdpt", "vcm"]
FROM_BLENDER = {"render": {"width", "height", "exposure"}}
INT_MAX = 2**31 - 1


def _property(p):
    """A Blender property for one parameter of the schema, or None for a kind the
    panel does not show (lists, optional values, tables)."""
    t, default, doc = p["rust_type"], p["default"], p["doc"]
    if default is None:
        return None
    if t == "bool":
        return bpy.props.BoolProperty(name=p["key"], description=doc, default=default == "true")
    if p["choices"]:
        items = [(c, c, "") for c in p["choices"]]
        return bpy.props.EnumProperty(name=p["key"], description=doc, items=items, default=default)
    if t in ("u32", "u64", "usize"):
        if int(default) > INT_MAX:
            return None
        lo = int(p["min"]) if p["min"] is not None else 0
        hi = min(int(p["max"]), INT_MAX) if p["max"] is not None else INT_MAX
        return bpy.props.IntProperty(name=p["key"], description=doc, default=int(default), min=lo, max=hi)
    if t in ("f32", "f64"):
        kw = {}
        if p["min"] is not None:
            kw["min"] = p["min"]
        if p["max"] is not None:
            kw["max"] = p["max"]
        return bpy.props.FloatProperty(name=p["key"], description=doc, default=float(default), precision=4, **kw)
    return None


def _section_group(section):
    annotations = {}
    shown = []
    for p in SCHEMA["sections"][section]:
        if p["key"] in FROM_BLENDER.get(section, ()):
            continue
        prop = _property(p)
        if prop is not None:
            annotations[p["key"]] = prop
            shown.append(p)
    cls = type(f"PHOTON_MAP_PG_{section}", (bpy.types.PropertyGroup,), {"__annotations__": annotations})
    cls.params = shown
    return cls


GROUPS = {s: _section_group(s) for s in SECTIONS}


def _words(kind):
    """EnumProperty items of the schema's words (methods, qualities)."""
    label = {"sppm": "SPPM", "bdpt": "BDPT", "vcm": "VCM"}
    return [(w["name"], label.get(w["name"], w["name"].capitalize()), w["help"] or "") for w in SCHEMA[kind]]


class PhotonMapSettings(bpy.types.PropertyGroup):
    """`scene.photon_map`: the method, quality or time budget, seed, and one group
    per pipeline.toml section."""

    __annotations__ = {
        "method": bpy.props.EnumProperty(name="Method", description="What makes the image ([render] mode)",
                                         items=_words("modes"), default="full"),
        "quality": bpy.props.EnumProperty(
            name="Quality",
            description="Settings picked from the measured accuracy/time front (replace the photon counts and "
                        "render settings below); Custom uses them as set",
            items=[("CUSTOM", "Custom", "The settings below")] + _words("qualities"), default="CUSTOM"),
        "time_budget_s": bpy.props.FloatProperty(
            name="Time Budget", description="Seconds for the whole pipeline at this image size (0: off); picks "
                                            "the setting with the least error that fits", min=0.0, default=0.0,
            unit="TIME_ABSOLUTE"),
        "seed": bpy.props.IntProperty(name="Seed", description="Random seed: equal seeds give identical images",
                                      min=0, default=1),
        **{s: bpy.props.PointerProperty(type=g) for s, g in GROUPS.items()},
    }

    def toml(self, width, height):
        """The settings as pipeline.toml text for an image of `width` x `height`
        pixels: top-level keys, and a table per section with the values that
        differ from the renderer's defaults."""
        top = [f"seed = {self.seed}"]
        if self.quality != "CUSTOM":
            top.append(f'quality = "{self.quality}"')
        elif self.time_budget_s > 0:
            top.append(f"time_budget_s = {self.time_budget_s!r}")
        tables = []
        for s, g in GROUPS.items():
            group = getattr(self, s)
            lines = [f'mode = "{self.method}"', f"width = {width}", f"height = {height}"] if s == "render" else []
            for p in g.params:
                v = getattr(group, p["key"])
                text = _toml_value(p, v)
                if text != _toml_value(p, _default(p)):
                    lines.append(f"{p['key']} = {text}")
            if lines:
                tables.append(f"[{s}]\n" + "\n".join(lines) + "\n")
        return "\n".join(top) + "\n", tables


def _default(p):
    t = p["rust_type"]
    if t == "bool":
        return p["default"] == "true"
    if p["choices"]:
        return p["default"]
    return int(p["default"]) if t in ("u32", "u64", "usize") else float(p["default"])


def _toml_value(p, v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, int):
        return str(v)
    # Blender keeps floats as f32: write the shortest text of that f32.
    import numpy as np

    return repr(float(np.float32(v)))


class PhotonMapPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    bins: bpy.props.StringProperty(
        name="Renderer programs", subtype="DIR_PATH",
        description="Folder of the renderer's programs (the repository's target/release after cargo build "
                    "--release --workspace); the environment variable PHOTON_MAP_BIN wins",
        default=SCHEMA.get("bins", ""))
    keep_files: bpy.props.BoolProperty(
        name="Keep files", default=False,
        description="Keep each render's folder (scene.gltf, pipeline.toml, photon maps, image.exr) in the "
                    "temporary folder instead of deleting it")

    def draw(self, context):
        self.layout.prop(self, "bins")
        self.layout.prop(self, "keep_files")


def _prefs(context):
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


# An animation being rendered: its folder and frame range, so that each frame's
# render call takes its image from the one run of frame tasks.
_animation = {}


# Work a render thread hands to Blender's main thread (run.on_main_thread): put
# here from any thread, run by _run_main_tasks, a timer registered on the main
# thread. (Registering a timer from the render thread would touch Blender's timer
# list while the main loop walks it.)
_main_tasks = queue.Queue()


def _run_main_tasks():
    """Run the tasks waiting for the main thread; Blender calls this again in a
    tenth of a second (a timer of the main loop, which never runs headless)."""
    while True:
        try:
            task = _main_tasks.get_nowait()
        except queue.Empty:
            return 0.1
        task()


def export(scene_name, view_layer_name, folder, animation):
    """Export the scene `scene_name` as its view layer `view_layer_name` sees it
    into `folder` (convert.export). Called on Blender's main thread
    (run.on_main_thread), from the original data, not the render's evaluated copy:
    the glTF exporter reads bpy.context's scene and view layer, which are set here."""
    scene = bpy.data.scenes[scene_name]
    layer = scene.view_layers.get(view_layer_name) or bpy.context.view_layer
    with bpy.context.temp_override(scene=scene, view_layer=layer):
        return convert.export(scene, folder, animation)


class PhotonMapEngine(bpy.types.RenderEngine):
    bl_idname = "PHOTON_MAP"
    bl_label = "Photon Map"
    bl_use_preview = False
    bl_use_postprocess = True

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for _, name in convert.PASSES:
            self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")

    def render(self, depsgraph):
        try:
            self._render(depsgraph)
        except run.Cancelled:
            self.update_stats("Photon Map", "cancelled")
        except (run.Failed, OSError, ValueError, RuntimeError) as e:
            self.report({"ERROR"}, f"Photon Map: {e}")

    def _render(self, depsgraph):
        global last_warnings, last_folder, stop_requested_at
        stop_requested_at = None
        scene = depsgraph.scene
        settings = scene.photon_map
        prefs = _prefs(bpy.context)
        bins, xtask = run.binaries(prefs.bins if prefs else "", SCHEMA.get("bins", ""))
        keep = bool(prefs and prefs.keep_files) or bool(os.environ.get("PHOTON_MAP_KEEP"))
        scale = scene.render.resolution_percentage / 100.0
        w, h = int(scene.render.resolution_x * scale), int(scene.render.resolution_y * scale)
        frame = scene.frame_current
        key = (scene.name, scene.frame_start, scene.frame_end, w, h)
        animation = self.is_animation
        started = time.time()

        def stop():
            global stop_requested_at
            pressed = self.test_break() or (break_after is not None and time.time() - started > break_after)
            if pressed and stop_requested_at is None:
                stop_requested_at = time.time()
            return pressed

        if animation and _animation.get("key") == key:
            folder = _animation["folder"]
        else:
            folder = tempfile.mkdtemp(prefix="photon_map_")
            self.update_stats("Photon Map", "exporting the scene")
            names = (scene.name, depsgraph.view_layer.name)
            try:
                ex = run.on_main_thread(lambda: export(*names, folder, animation), stop, _main_tasks.put)
                last_warnings = ex.warnings
                if ex.warnings:
                    self.report({"WARNING"}, "Photon Map: not converted: " + "; ".join(ex.warnings))
                top, tables = settings.toml(w, h)
                pipeline = os.path.join(folder, "pipeline.toml")
                with open(pipeline, "w", encoding="utf-8") as f:
                    f.write("# Written by the Blender add-on photon_map.\n" + ex.keys + top + "\n" + "\n".join(
                        ex.tables + tables))
                run.run([xtask, "run", "--bins", bins, "--pipeline", pipeline, "--out",
                         os.path.join(folder, "out")], self, "Photon Map", stop)
            except BaseException:
                if not keep:
                    shutil.rmtree(folder, ignore_errors=True)
                raise
            if animation:
                _animation.clear()
                _animation.update(key=key, folder=folder)
        out = os.path.join(folder, "out")
        image = os.path.join(out, f"frame-{frame}" if animation else "", "image.exr")
        layers = run.layers(xtask, image, os.path.join(folder, f"layers-{frame}"), self)
        self._fill(layers, w, h)
        last_folder = folder
        last = not animation or frame >= scene.frame_end
        if last:
            _animation.clear()
            if not keep:
                shutil.rmtree(folder, ignore_errors=True)
                last_folder = None

    def _fill(self, layers, w, h):
        import numpy as np

        total = layers.get("total")
        if total is None or total.shape[:2] != (h, w):
            raise run.Failed(f"the image is not {w} x {h}")
        for _, name in convert.PASSES:
            self.add_pass(name, 3, "RGB")
        result = self.begin_result(0, 0, w, h)
        passes = result.layers[0].passes
        rgba = np.ones((h * w, 4), dtype=np.float32)
        rgba[:, :3] = total.reshape(-1, 3)
        passes["Combined"].rect = rgba
        for layer, name in convert.PASSES:
            p = passes.get(name)
            if p is not None:
                px = layers.get(layer)
                p.rect = px.reshape(-1, 3) if px is not None else np.zeros((h * w, 3), dtype=np.float32)
        self.end_result(result)


class PHOTON_MAP_PT_render(bpy.types.Panel):
    bl_label = "Photon Map"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {"PHOTON_MAP"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        s = context.scene.photon_map
        col = self.layout.column()
        col.use_property_split = True
        col.prop(s, "method")
        col.prop(s, "quality")
        sub = col.column()
        sub.enabled = s.quality == "CUSTOM"
        sub.prop(s, "time_budget_s")
        col.prop(s, "seed")
        if s.method in ("full", "photons", "radiance", "indirect"):
            for key in ("global_photons", "caustic_photons", "volume_photons"):
                if hasattr(s.trace, key):
                    col.prop(s.trace, key)


def _section_panel(section):
    def draw(self, context):
        col = self.layout.column()
        col.use_property_split = True
        group = getattr(context.scene.photon_map, section)
        for p in GROUPS[section].params:
            col.prop(group, p["key"])

    return type(f"PHOTON_MAP_PT_section_{section}", (bpy.types.Panel,), {
        "bl_label": f"[{section}]",
        "bl_space_type": "PROPERTIES",
        "bl_region_type": "WINDOW",
        "bl_context": "render",
        "bl_parent_id": "PHOTON_MAP_PT_render",
        "bl_options": {"DEFAULT_CLOSED"},
        "COMPAT_ENGINES": {"PHOTON_MAP"},
        "poll": classmethod(lambda cls, context: context.engine == "PHOTON_MAP"),
        "draw": draw,
    })


PANELS = [_section_panel(s) for s in SECTIONS]


def _generic_panels():
    """Blender's own panels that any engine uses (output, dimensions, materials,
    lights, world): those that list BLENDER_RENDER."""
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is not None and "BLENDER_RENDER" in engines:
            yield panel


CLASSES = [*GROUPS.values(), PhotonMapSettings, PhotonMapPreferences, PhotonMapEngine, PHOTON_MAP_PT_render, *PANELS]


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.photon_map = bpy.props.PointerProperty(type=PhotonMapSettings)
    for p in _generic_panels():
        p.COMPAT_ENGINES.add("PHOTON_MAP")
    bpy.app.timers.register(_run_main_tasks, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(_run_main_tasks):
        bpy.app.timers.unregister(_run_main_tasks)
    for p in _generic_panels():
        p.COMPAT_ENGINES.discard("PHOTON_MAP")
    del bpy.types.Scene.photon_map
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
