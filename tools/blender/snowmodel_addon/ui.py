# The add-on's settings (per scene), preferences and the "Snow" sidebar tab.
import bpy

from . import operators

# One definition of the snow settings, shared by the scene's settings (the
# panel) and the operator's arguments (bpy.ops.snowmodel.add_snow(...)).
SnowmodelSettings = type("SnowmodelSettings", (bpy.types.PropertyGroup,),
                         {"__annotations__": operators.snow_properties()})


class SnowmodelPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    binary: bpy.props.StringProperty(
        name="snowmodel binary", subtype="FILE_PATH",
        description="The snowmodel executable (empty: $SNOWMODEL_BIN, then PATH)")

    def draw(self, context):
        self.layout.prop(self, "binary")


class SNOWMODEL_OT_use_selected(bpy.types.Operator):
    """Put the selected objects' names into a name list of the snow settings"""
    bl_idname = "snowmodel.use_selected"
    bl_label = "Use Selected"
    bl_options = {"INTERNAL"}

    field: bpy.props.StringProperty()

    def execute(self, context):
        names = [o.name for o in context.selected_objects]
        setattr(context.scene.snowmodel, self.field, ", ".join(names))
        return {"FINISHED"}


class SNOWMODEL_PT_snow(bpy.types.Panel):
    bl_label = "snowmodel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Snow"

    def draw(self, context):
        s = context.scene.snowmodel
        col = self.layout.column()
        col.prop(s, "depth")
        col.prop(s, "snow")
        col.separator()
        col.prop(s, "wind_speed")
        col.prop(s, "wind_heading")
        col.separator()
        col.prop(s, "texel")
        sub = col.column()
        sub.enabled = s.texel <= 0.0
        sub.prop(s, "max_side")
        col.prop(s, "directions")
        col.separator()
        for field, label in (("no_snow_on", "No snow on:"), ("ignore", "Ignore:")):
            col.label(text=label)
            row = col.row(align=True)
            row.prop(s, field, text="")
            row.operator(SNOWMODEL_OT_use_selected.bl_idname, text="",
                         icon="RESTRICT_SELECT_OFF").field = field
        col.separator()
        selected = [o for o in context.selected_objects if o.type == "MESH"]
        col.label(text=f"Snows {len(selected)} selected" if selected
                  else "Snows all visible meshes")
        col.operator(operators.SNOWMODEL_OT_add_snow.bl_idname, icon="FREEZE")


classes = [SnowmodelSettings, SnowmodelPreferences, SNOWMODEL_OT_use_selected, SNOWMODEL_PT_snow]
