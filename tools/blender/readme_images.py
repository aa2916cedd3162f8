# The README's Blender pictures (docs/images/blender_*.png), made with the
# add-on on the bundled courtyard:
#   blender -b --factory-startup --python tools/blender/readme_images.py -- ROOT SNOWMODEL
#     renders the snowed courtyard with Cycles (docs/images/blender_render.jpg);
#   xvfb-run -a -s "-screen 0 1280x800x24" blender --factory-startup \
#     --enable-event-simulate --python tools/blender/readme_images.py -- ROOT SNOWMODEL
#     screenshots the 3D view with the Snow tab open (docs/images/blender_panel.png).
import math
import os
import sys

import addon_utils
import bpy

root, snowmodel = sys.argv[sys.argv.index("--") + 1:]
sys.path.insert(0, os.path.join(root, "tools", "blender"))
addon_utils.enable("snowmodel_addon", default_set=True)
bpy.context.preferences.addons["snowmodel_addon"].preferences.binary = snowmodel

for o in list(bpy.data.objects):
    bpy.data.objects.remove(o, do_unlink=True)
sys.modules["snowmodel_addon.runner"].restore_numpy_bool()  # Blender 3.4's glTF importer
bpy.ops.import_scene.gltf(filepath=os.path.join(root, "assets", "scenes", "courtyard.glb"))
bpy.ops.object.select_all(action="DESELECT")
settings = bpy.context.scene.snowmodel
settings.depth = 0.3
settings.wind_speed = 0.0
bpy.ops.snowmodel.add_snow()

scene = bpy.context.scene
bpy.ops.object.camera_add(location=(17.0, -17.0, 12.0))
camera = bpy.context.active_object
direction = -camera.location
camera.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
camera.data.lens = 38
scene.camera = camera
bpy.ops.object.light_add(type="SUN", rotation=(math.radians(50), 0, math.radians(30)))
bpy.context.active_object.data.energy = 2.5
world = bpy.data.worlds.new("Sky") if scene.world is None else scene.world
scene.world = world
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.55, 0.65, 0.8, 1.0)
world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.35
scene.view_settings.look = "Medium High Contrast"
scene.view_settings.exposure = -0.7

images = os.path.join(root, "docs", "images")
if bpy.app.background:
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 32
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
    scene.render.resolution_x, scene.render.resolution_y = 800, 500
    scene.render.image_settings.file_format = "JPEG"
    scene.render.image_settings.quality = 85
    scene.render.filepath = os.path.join(images, "blender_render.jpg")
    bpy.ops.render.render(write_still=True)
else:
    # The window (Blender started with --enable-event-simulate): the splash
    # dismissed and the sidebar's Snow tab clicked (Blender 3.4 cannot switch
    # tabs from Python), then a screenshot once it has been drawn.
    window = bpy.context.window
    view3d = next(a for a in bpy.context.screen.areas if a.type == "VIEW_3D")
    view3d.spaces.active.show_region_ui = True

    def click_tab():
        window.event_simulate(type="ESC", value="PRESS")
        window.event_simulate(type="ESC", value="RELEASE")
        sidebar = next(r for r in view3d.regions if r.type == "UI")
        # The tabs run down the sidebar's right edge: Item, Tool, View, Snow.
        x = sidebar.x + sidebar.width - 10
        y = sidebar.y + sidebar.height - 165
        window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=x, y=y)
        window.event_simulate(type="LEFTMOUSE", value="PRESS", x=x, y=y)
        window.event_simulate(type="LEFTMOUSE", value="RELEASE", x=x, y=y)
        window.event_simulate(type="MOUSEMOVE", value="NOTHING", x=view3d.x + 100, y=view3d.y + 100)
        return None

    def shoot():
        try:
            with bpy.context.temp_override(window=window, area=view3d):
                bpy.ops.screen.screenshot_area(filepath=os.path.join(images, "blender_panel.png"))
        finally:
            bpy.ops.wm.quit_blender()

    bpy.app.timers.register(click_tab, first_interval=2.0)
    bpy.app.timers.register(shoot, first_interval=4.0)
