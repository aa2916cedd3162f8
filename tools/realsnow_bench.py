"""Times Blender's Real Snow add-on on one glTF scene, headless: the peer
snowmodel is compared with (tools/bench-peers runs it).

    blender -b --factory-startup -noaudio --python-exit-code 1 \\
        --python tools/realsnow_bench.py -- SCENE.glb [--height 0.3] [--coverage 100]

Imports the scene into an empty file, selects every mesh object, enables
the add-on (`real_snow`, shipped with Debian's blender package) and calls
`bpy.ops.snow.create()` with the given coverage (percent) and height
(metres). Real Snow builds metaballs and modifiers whose geometry Blender
only computes when the scene is evaluated, so the evaluation of the snow
objects to meshes is timed separately. Prints one line:

    realsnow: scene=building-small-a.glb triangles=452 create_s=2.91 evaluate_s=0.52 snow_triangles=81234 peak_mib=512

peak_mib is the Blender process's peak resident memory (ru_maxrss) at the
end, import included. Exit status non-zero when something fails.
"""
import os
import resource
import sys
import time

import addon_utils
import bpy

# Blender 3.4's glTF importer still uses numpy's `numpy.bool` alias, which
# numpy 1.24 removed (see tools/blender_import.py).
try:
    import warnings

    import numpy

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if not hasattr(numpy, "bool"):
            numpy.bool = numpy.bool_
except ImportError:
    pass


def parse_args(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    options = {"height": 0.3, "coverage": 100, "scene": None}
    i = 0
    while i < len(args):
        if args[i] in ("--height", "--coverage") and i + 1 < len(args):
            options[args[i][2:]] = float(args[i + 1])
            i += 2
        else:
            options["scene"] = args[i]
            i += 1
    if not options["scene"]:
        raise SystemExit("usage: realsnow_bench.py -- SCENE.glb [--height M] [--coverage PERCENT]")
    return options


def triangles(objects):
    depsgraph = bpy.context.evaluated_depsgraph_get()
    count = 0
    for obj in objects:
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        if mesh is not None:
            mesh.calc_loop_triangles()
            count += len(mesh.loop_triangles)
            evaluated.to_mesh_clear()
    return count


def main():
    options = parse_args(sys.argv)
    scene = os.path.abspath(options["scene"])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=scene)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    if not meshes:
        raise SystemExit("realsnow: %s holds no mesh" % scene)
    input_triangles = triangles(meshes)

    addon_utils.enable("real_snow", default_set=True)
    bpy.context.scene.snow.coverage = int(options["coverage"])
    bpy.context.scene.snow.height = options["height"]
    bpy.ops.object.select_all(action="DESELECT")
    for obj in meshes:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = meshes[0]

    start = time.perf_counter()
    result = bpy.ops.snow.create()
    create_s = time.perf_counter() - start
    if "FINISHED" not in result:
        raise SystemExit("realsnow: snow.create returned %s" % result)

    snow = [o for o in bpy.context.scene.objects if o.name.startswith("Snow") and o.type == "MESH"]
    start = time.perf_counter()
    snow_triangles = triangles(snow)
    evaluate_s = time.perf_counter() - start

    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print("realsnow: scene=%s triangles=%d create_s=%.2f evaluate_s=%.2f snow_triangles=%d "
          "peak_mib=%.0f" % (os.path.basename(scene), input_triangles, create_s, evaluate_s,
                             snow_triangles, peak_mib))


main()
