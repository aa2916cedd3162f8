# snowmodel for Blender: snows the selected mesh objects with the snowmodel
# command-line tool and imports the snow as closed meshes into a "Snow"
# collection (the repository's README, "Blender add-on").
#
# The objects go out as a temporary GLB in Blender's world frame (the glTF
# exporter turns Blender's Z up into glTF's Y up, the importer turns it
# back), so the snow lands exactly on them.
bl_info = {
    "name": "snowmodel",
    "author": "snowmodel developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Snow",
    "description": "Physically plausible fallen snow on the selected objects (runs snowmodel)",
    "category": "Object",
}

if "bpy" in locals():  # reloaded by Blender (F3 > Reload Scripts)
    import importlib

    importlib.reload(runner)  # noqa: F821
    importlib.reload(material)  # noqa: F821
    importlib.reload(operators)  # noqa: F821
    importlib.reload(ui)  # noqa: F821

import bpy

from . import material, operators, runner, ui

_classes = ui.classes + operators.classes


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.snowmodel = bpy.props.PointerProperty(type=ui.SnowmodelSettings)


def unregister():
    del bpy.types.Scene.snowmodel
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
