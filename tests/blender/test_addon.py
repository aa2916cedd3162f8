# The Blender add-on (tools/blender/snowmodel_addon) in Debian's Blender,
# headless: installed from its zip, it snows a floor and a table built here
# and the snow is where it must be. Run by tests/blender/run-addon-test:
#   blender -b --factory-startup --python test_addon.py -- SNOWMODEL ADDON.zip
# Exits non-zero on the first failed check.
import os
import sys

import addon_utils
import bpy
from mathutils import Vector
from mathutils.bvhtree import BVHTree

snowmodel, addon_zip = sys.argv[sys.argv.index("--") + 1:]
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what)
    if not ok:
        failures.append(what)


def box(name, centre, size):
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=centre)
    o = bpy.context.active_object
    o.name = name
    o.scale = size
    bpy.ops.object.transform_apply(scale=True)
    return o


# A floor of 8 x 8 m at z = 0 and a table (top 1.5 x 1 m, 5 cm thick, its
# top at 0.8 m) on four legs, in Blender's Z-up world.
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
bpy.context.active_object.name = "Floor"
box("TableTop", (0, 0, 0.775), (1.5, 1.0, 0.05))
for x in (-0.7, 0.7):
    for y in (-0.45, 0.45):
        box("TableLeg", (x, y, 0.375), (0.05, 0.05, 0.75))
bpy.ops.object.select_all(action="DESELECT")
scene_objects = len(bpy.data.objects)

bpy.ops.preferences.addon_install(filepath=addon_zip, overwrite=True)
addon_utils.enable("snowmodel_addon", default_set=True)
prefs = bpy.context.preferences.addons["snowmodel_addon"].preferences
prefs.binary = snowmodel


def snow_meshes():
    return [o for o in bpy.data.collections["Snow"].objects if o.type == "MESH"]


def snow_tree():
    depsgraph = bpy.context.evaluated_depsgraph_get()
    verts, faces = [], []
    for o in snow_meshes():
        mesh = o.evaluated_get(depsgraph).to_mesh()
        base = len(verts)
        verts += [o.matrix_world @ v.co for v in mesh.vertices]
        faces += [[base + i for i in p.vertices] for p in mesh.polygons]
    return BVHTree.FromPolygons(verts, faces)


def top_at(tree, x, y, z_from=10.0):
    """z of the first snow surface below (x, y, z_from), or None."""
    hit = tree.ray_cast(Vector((x, y, z_from)), Vector((0, 0, -1)))
    return None if hit[0] is None else hit[0].z


# Nothing selected: every visible mesh is snowed.
result = bpy.ops.snowmodel.add_snow(depth=0.3, max_side=256, directions=16)
check(result == {"FINISHED"}, f"the operator finished ({result})")
meshes = snow_meshes()
check(len(meshes) >= 2, f"snow meshes in the Snow collection ({len(meshes)})")
check(all(m.material_slots and m.material_slots[0].material.name == "snowmodel Snow"
          for m in meshes), "every snow mesh has the snow material")
tree = snow_tree()
on_table = top_at(tree, 0.0, 0.0)
on_floor = top_at(tree, 3.0, 3.0)
under_table = top_at(tree, 0.0, 0.0, z_from=0.7)
print(f"snow top: on the table {on_table}, on the open floor {on_floor}, "
      f"under the table from 0.7 m {under_table}")
check(on_table is not None and abs(on_table - (0.8 + 0.3)) < 0.05,
      "the table top carries the requested 0.3 m (within 5 cm)")
check(on_floor is not None and abs(on_floor - 0.3) < 0.03,
      "the open floor carries the requested 0.3 m (within 3 cm)")
check(under_table is None or under_table < 0.01, "no snow on the floor under the table")

# A second run replaces the first one's snow.
names = sorted(o.name for o in bpy.data.collections["Snow"].objects)
objects = len(bpy.data.objects)
result = bpy.ops.snowmodel.add_snow(depth=0.3, max_side=256, directions=16)
check(result == {"FINISHED"}, "the second run finished")
check(len(bpy.data.objects) == objects, "the second run replaced the snow (as many objects)")
check(sorted(o.name for o in bpy.data.collections["Snow"].objects) == names,
      "the Snow collection holds the new snow only")
check(len(bpy.data.objects) - len(bpy.data.collections["Snow"].objects) == scene_objects,
      "the scene's own objects are untouched")

# With the table selected, only the table is snowed.
bpy.ops.object.select_all(action="DESELECT")
bpy.data.objects["TableTop"].select_set(True)
result = bpy.ops.snowmodel.add_snow(depth=0.3, max_side=256, directions=16)
tree = snow_tree()
check(result == {"FINISHED"} and top_at(tree, 0.0, 0.0) is not None and
      top_at(tree, 3.0, 3.0) is None, "with the table top selected, only it is snowed")
bpy.ops.object.select_all(action="DESELECT")
objects = len(bpy.data.objects)

# A missing binary: a clear report, nothing changed.
prefs.binary = "/nonexistent/snowmodel"
try:
    bpy.ops.snowmodel.add_snow()
    check(False, "a missing binary is reported")
except RuntimeError as e:
    print(f"report: {e}")
    check("snowmodel not found at /nonexistent/snowmodel" in str(e),
          "a missing binary is reported, naming the path")
check(len(bpy.data.objects) == objects, "nothing changed after the error")

print(f"{len(failures)} failed" if failures else "all checks passed")
sys.exit(1 if failures else 0)
