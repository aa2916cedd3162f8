"""Imports snowmodel outputs (GLB/glTF, OBJ, PLY) into Blender, headless, and
prints what arrived: one line per file with object and triangle counts.

Run through tools/blender-import, or directly:
    blender -b --factory-startup --python-exit-code 1 \
        --python tools/blender_import.py -- FILE...

Each file is imported into an empty scene. Output lines look like
    blender-import: snow.glb: 3 objects (2 meshes), 412 triangles, 260 vertices, UVs on 2 of 2 meshes
    blender-import:   snow/Floor: 300 triangles
The exit status is non-zero when a file fails to import or brings no mesh.
"""
import os
import sys

# Blender 3.4's glTF importer still uses numpy's `numpy.bool` alias, which
# numpy 1.24 removed; the add-on's runner restores it before the importer
# loads (OBJ and PLY import without numpy).
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "blender",
                                "snowmodel_addon"))
import runner  # noqa: E402  (the add-on's runner: plain Python, no bpy)

runner.restore_numpy_bool()

import bpy  # noqa: E402  (after the numpy fix on purpose)

PREFIX = "blender-import:"


def files_from_argv():
    argv = sys.argv
    return argv[argv.index("--") + 1:] if "--" in argv else []


def has_operator(module, name):
    """True when bpy.ops.<module>.<name> is registered (hasattr is always true)."""
    return name in dir(getattr(bpy.ops, module))


def importer_for(path):
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        return lambda: bpy.ops.import_scene.gltf(filepath=path)
    if ext == ".obj":
        if has_operator("wm", "obj_import"):  # C++ importer, Blender 3.3+
            return lambda: bpy.ops.wm.obj_import(filepath=path)
        return lambda: bpy.ops.import_scene.obj(filepath=path)
    if ext == ".ply":
        if has_operator("wm", "ply_import"):  # C++ importer, Blender 4.0+
            return lambda: bpy.ops.wm.ply_import(filepath=path)
        return lambda: bpy.ops.import_mesh.ply(filepath=path)
    return None


def triangles(obj):
    mesh = obj.data
    mesh.calc_loop_triangles()
    return len(mesh.loop_triangles)


def import_one(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    run = importer_for(path)
    if run is None:
        print(f"{PREFIX} {path}: unknown extension", flush=True)
        return False
    if not os.path.isfile(path):
        print(f"{PREFIX} {path}: no such file", flush=True)
        return False
    try:
        result = run()
    except Exception as error:  # the importers raise RuntimeError with a message
        print(f"{PREFIX} {path}: import failed: {str(error).splitlines()[0]}", flush=True)
        return False
    if "FINISHED" not in result:
        print(f"{PREFIX} {path}: import returned {sorted(result)}", flush=True)
        return False
    objects = list(bpy.context.scene.objects)
    meshes = [o for o in objects if o.type == "MESH"]
    tris = {o.name: triangles(o) for o in meshes}
    verts = sum(len(o.data.vertices) for o in meshes)
    with_uvs = sum(1 for o in meshes if len(o.data.uv_layers) > 0)
    print(f"{PREFIX} {os.path.basename(path)}: {len(objects)} objects ({len(meshes)} meshes), "
          f"{sum(tris.values())} triangles, {verts} vertices, UVs on {with_uvs} of "
          f"{len(meshes)} meshes", flush=True)
    for name in sorted(tris):
        print(f"{PREFIX}   {name}: {tris[name]} triangles", flush=True)
    return len(meshes) > 0


def main():
    files = files_from_argv()
    if not files:
        print(f"{PREFIX} usage: blender -b --python tools/blender_import.py -- FILE...",
              flush=True)
        sys.exit(2)
    ok = True
    for path in files:
        ok = import_one(os.path.abspath(path)) and ok
    sys.exit(0 if ok else 1)


main()
