# bpy.ops.snowmodel.add_snow: export the objects, run snowmodel, import the
# snow into the "Snow" collection with the snow material.
import os
import shutil
import tempfile

import bpy

from . import material, runner

COLLECTION_NAME = "Snow"


def snow_properties():
    """The snow settings as Blender properties (name -> property), for the
    scene's settings and the operator's arguments alike."""
    P = bpy.props
    return {
        "depth": P.FloatProperty(name="Depth", default=0.3, min=0.0, max=1000.0, unit="LENGTH",
                                 description="Fresh snow that falls on open flat ground"),
        "snow": P.EnumProperty(name="Snow", default="fresh", items=[
            ("powder", "Powder", "Cold, dry, little cohesion: sheds from steeper roofs sooner"),
            ("fresh", "Fresh", "Fresh snow, calibrated to EN 1991-1-3 roof loads"),
            ("wet", "Wet", "Sticky: clings to steeper roofs and stands higher at edges")]),
        "wind_speed": P.FloatProperty(name="Wind", default=0.0, min=0.0, max=25.0, unit="VELOCITY",
                                      description="Wind speed in m/s (above about 4 m/s fresh "
                                                  "snow drifts)"),
        "wind_heading": P.FloatProperty(name="Towards (deg)", default=0.0, min=-180.0, max=180.0,
                                        description="Where the wind blows to: degrees from +X "
                                                    "towards +Y"),
        "texel": P.FloatProperty(name="Texel (0 auto)", default=0.0, min=0.0, max=1000.0,
                                 unit="LENGTH",
                                 description="Map texel size (0: automatic from Max Side)"),
        "max_side": P.IntProperty(name="Max Side (0 auto)", default=0, min=0, max=16384,
                                  description="Longest map side in texels (0: automatic)"),
        "directions": P.IntProperty(name="Directions", default=64, min=1, max=4096,
                                    description="Fall directions sampled for the coverage"),
        "no_snow_on": P.StringProperty(name="No Snow On",
                                       description="Comma-separated name globs of objects that "
                                                   "get no snow but still shelter"),
        "ignore": P.StringProperty(name="Ignore",
                                   description="Comma-separated name globs of objects that "
                                               "neither get snow nor shelter"),
    }


def _meshes_to_snow(context):
    """The selected mesh objects, else every visible one; never the snow."""
    snow = bpy.data.collections.get(COLLECTION_NAME)
    skip = set(snow.all_objects) if snow else set()
    selected = [o for o in context.selected_objects if o.type == "MESH" and o not in skip]
    if selected:
        return selected
    return [o for o in context.view_layer.objects
            if o.type == "MESH" and o.visible_get() and o not in skip]


def _export(context, objects, path):
    """Writes `objects` to a GLB at `path` in the world frame (glTF's Y up),
    modifiers applied; the selection is restored after."""
    view_layer = context.view_layer
    selected = [o for o in view_layer.objects if o.select_get()]
    active = view_layer.objects.active
    try:
        for o in selected:
            o.select_set(False)
        for o in objects:
            o.select_set(True)
        result = bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", use_selection=True,
                                           export_apply=True, export_yup=True,
                                           export_materials="NONE", export_animations=False)
        if "FINISHED" not in result or not os.path.isfile(path):
            raise runner.SnowmodelError("Blender's glTF exporter wrote nothing")
    finally:
        for o in view_layer.objects:
            o.select_set(o in selected)
        view_layer.objects.active = active


def _snow_collection(context):
    """The "Snow" collection, emptied of the previous result; and the names
    that result's objects had."""
    snow = bpy.data.collections.get(COLLECTION_NAME)
    if snow is None:
        snow = bpy.data.collections.new(COLLECTION_NAME)
        context.scene.collection.children.link(snow)
    names = set()
    for o in list(snow.objects):
        names.add(o.name)
        data = o.data
        bpy.data.objects.remove(o, do_unlink=True)
        if data is not None and data.users == 0 and isinstance(data, bpy.types.Mesh):
            bpy.data.meshes.remove(data)
    return snow, names


def _import(context, path):
    """Imports the snow GLB into the emptied "Snow" collection with the snow
    material; returns the snow mesh objects."""
    runner.restore_numpy_bool()  # Blender 3.4's glTF importer on numpy 1.24
    before = set(bpy.data.objects)
    result = bpy.ops.import_scene.gltf(filepath=path)
    if "FINISHED" not in result:
        raise runner.SnowmodelError("Blender's glTF importer could not read the snow")
    new = [o for o in bpy.data.objects if o not in before]
    # The previous result goes only once the new one is in; the new objects
    # then take back its names (the importer gave them ".001" suffixes).
    snow, old_names = _snow_collection(context)
    for o in new:
        base = o.name.rsplit(".", 1)[0]
        if base != o.name and base in old_names:
            o.name = base
    mat = material.snow_material()
    meshes = []
    for o in new:
        for c in list(o.users_collection):
            c.objects.unlink(o)
        snow.objects.link(o)
        if o.type == "MESH":
            o.data.materials.clear()
            o.data.materials.append(mat)
            meshes.append(o)
    return meshes


class SNOWMODEL_OT_add_snow(bpy.types.Operator):
    """Snow the selected mesh objects (all visible ones when none is selected) with snowmodel"""
    bl_idname = "snowmodel.add_snow"
    bl_label = "Add Snow"
    bl_options = {"REGISTER", "UNDO"}
    __annotations__ = snow_properties()

    _run = None       # the snowmodel run (modal)
    _timer = None     # the modal run's timer
    _progress = None  # runner.progress_of's state
    _dir = None       # the temporary folder of the GLBs
    _objects = 0      # objects snowed

    def _settings(self, context):
        """The operator's arguments; those not given come from the scene's
        settings (the panel)."""
        scene = getattr(context.scene, "snowmodel", None)
        out = {}
        for name in snow_properties():
            given = self.properties.is_property_set(name) or scene is None
            out[name] = getattr(self, name) if given else getattr(scene, name)
        return out

    def _start(self, context):
        """Exports the objects and returns snowmodel's command line."""
        prefs = context.preferences.addons.get(__package__)
        binary = runner.find_binary(prefs.preferences.binary if prefs else "")
        objects = _meshes_to_snow(context)
        if not objects:
            raise runner.SnowmodelError("no mesh objects to snow (select some, or show them)")
        self._objects = len(objects)
        self._dir = tempfile.mkdtemp(prefix="snowmodel_")
        scene_glb = os.path.join(self._dir, "scene.glb")
        _export(context, objects, scene_glb)
        args = runner.command(binary, scene_glb, os.path.join(self._dir, "snow.glb"),
                              self._settings(context))
        scale = context.scene.unit_settings.scale_length
        if context.scene.unit_settings.system != "NONE" and abs(scale - 1.0) > 1e-9:
            args += ["--unit-scale", f"{scale:g}"]
        return args

    def _finish(self, context, status, lines):
        try:
            if status != 0:
                raise runner.SnowmodelError("snowmodel: " + runner.last_error(lines))
            meshes = _import(context, os.path.join(self._dir, "snow.glb"))
            self.report({"INFO"}, f"snowmodel: snowed {self._objects} objects, "
                                  f"{len(meshes)} snow meshes in '{COLLECTION_NAME}'")
        finally:
            self._cleanup(context)

    def _cleanup(self, context):
        if self._dir:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None
        if self._timer:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None
            context.window_manager.progress_end()
            if context.workspace:
                context.workspace.status_text_set(None)

    def execute(self, context):
        """Runs to completion (scripts, `blender -b`)."""
        try:
            run = runner.Run(self._start(context))
            status = run.wait()
            self._finish(context, status, run.lines)
        except runner.SnowmodelError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        finally:
            self._cleanup(context)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        try:
            self._run = runner.Run(self._start(context))
        except runner.SnowmodelError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        finally:
            if self._run is None:
                self._cleanup(context)
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        self._progress = {}
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._run.cancel()
            self._cleanup(context)
            self.report({"WARNING"}, "snowmodel: cancelled")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        new, status = self._run.poll()
        for line in new:
            seen = runner.progress_of(line, self._progress)
            if seen:
                done, stage = seen
                context.window_manager.progress_update(int(done * 100))
                if context.workspace:
                    context.workspace.status_text_set(
                        f"snowmodel: {stage} ({int(done * 100)} %), Esc cancels")
        if status is None:
            return {"RUNNING_MODAL"}
        try:
            self._finish(context, status, self._run.lines)
        except runner.SnowmodelError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}


classes = [SNOWMODEL_OT_add_snow]
