# The Blender add-on in a Blender window (under Xvfb, with
# --enable-event-simulate): the panel's way, bpy.ops.snowmodel.add_snow
# invoked, runs snowmodel in the background (the operator returns at once
# and keeps running modally) and imports the snow; a second run cancelled
# with Esc while snowmodel works leaves the first one's snow. Run by tests/blender/run-addon-test --window.
#   blender --factory-startup --enable-event-simulate --python test_addon_window.py -- SNOWMODEL ZIP
import os
import sys

import addon_utils
import bpy

snowmodel, addon_zip = sys.argv[sys.argv.index("--") + 1:]
failures = []
seen = {"ticks": 0}


def check(ok, what):
    print(("ok: " if ok else "FAILED: ") + what, flush=True)
    if not ok:
        failures.append(what)


def finish():
    print(f"{len(failures)} failed" if failures else "all checks passed", flush=True)
    os._exit(1 if failures else 0)


for o in list(bpy.data.objects):
    bpy.data.objects.remove(o, do_unlink=True)
bpy.ops.mesh.primitive_plane_add(size=8.0)
bpy.ops.preferences.addon_install(filepath=addon_zip, overwrite=True)
addon_utils.enable("snowmodel_addon", default_set=True)
bpy.context.preferences.addons["snowmodel_addon"].preferences.binary = snowmodel
window = bpy.context.window
area = next(a for a in bpy.context.screen.areas if a.type == "VIEW_3D")


def snow_meshes():
    snow = bpy.data.collections.get("Snow")
    return [o for o in snow.objects if o.type == "MESH"] if snow else []


def start(max_side):
    with bpy.context.temp_override(window=window, area=area):
        return bpy.ops.snowmodel.add_snow("INVOKE_DEFAULT", depth=0.3, max_side=max_side,
                                          directions=16)


def first_run():
    result = start(512)
    check(result == {"RUNNING_MODAL"}, f"invoked in a window, the run goes on in the "
                                       f"background ({result})")
    bpy.app.timers.register(wait_first, first_interval=0.2)


def wait_first():
    seen["ticks"] += 1
    if not snow_meshes():
        if seen["ticks"] > 600:
            check(False, "the first run ends within 2 minutes")
            finish()
        return 0.2
    check(len(snow_meshes()) == 1, "the floor's snow was imported")
    seen["snow"] = [o.as_pointer() for o in snow_meshes()]
    # The second run, of a stand-in snowmodel that reports progress and then
    # works for a minute, is cancelled with Esc.
    slow = os.path.join(bpy.app.tempdir or "/tmp", "slow_snowmodel")
    with open(slow, "w") as f:
        f.write("#!/bin/sh\necho 'coverage: 50%'\nsleep 60\n")
    os.chmod(slow, 0o755)
    bpy.context.preferences.addons["snowmodel_addon"].preferences.binary = slow
    result = start(512)
    check(result == {"RUNNING_MODAL"}, "a second run started")
    bpy.app.timers.register(cancel, first_interval=1.0)
    return None


def cancel():
    window.event_simulate(type="ESC", value="PRESS")
    window.event_simulate(type="ESC", value="RELEASE")
    bpy.app.timers.register(after_cancel, first_interval=1.0)
    return None


def after_cancel():
    check([o.as_pointer() for o in snow_meshes()] == seen["snow"],
          "Esc cancelled the second run and left the first run's snow")
    finish()
    return None


bpy.app.timers.register(first_run, first_interval=1.0)
