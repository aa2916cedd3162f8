# The snow's Blender material: a Principled BSDF with subsurface scattering
# (light goes a few centimetres into snow) and a fine noise bump (its grain).
import bpy

MATERIAL_NAME = "snowmodel Snow"
SNOW_COLOR = (0.92, 0.94, 0.97, 1.0)       # linear albedo of fresh snow
SUBSURFACE_RADIUS = (0.06, 0.08, 0.10)      # metres, red, green, blue (blue goes deepest)
SUBSURFACE_3X = 0.3  # Blender 3.x's subsurface mix factor
ROUGHNESS = 0.55
NOISE_SCALE = 400.0  # grain of about 2.5 mm on a metre-sized object
BUMP_STRENGTH = 0.15


def _set_input(node, names, value):
    """Sets the first input of `node` among `names` (the names differ
    between Blender 3.x and 4.x)."""
    for name in names:
        if name in node.inputs:
            node.inputs[name].default_value = value
            return True
    return False


def snow_material():
    """The snow material, made once per file."""
    mat = bpy.data.materials.get(MATERIAL_NAME)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(MATERIAL_NAME)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes.get("Principled BSDF") or nodes.new("ShaderNodeBsdfPrincipled")
    _set_input(bsdf, ["Base Color"], SNOW_COLOR)
    _set_input(bsdf, ["Roughness"], ROUGHNESS)
    if "Subsurface Weight" in bsdf.inputs:  # Blender 4.x: radius times scale
        _set_input(bsdf, ["Subsurface Weight"], 1.0)
        _set_input(bsdf, ["Subsurface Scale"], 1.0)
    else:  # Blender 3.x: a mix factor
        _set_input(bsdf, ["Subsurface"], SUBSURFACE_3X)
        _set_input(bsdf, ["Subsurface Color"], SNOW_COLOR)
    _set_input(bsdf, ["Subsurface Radius"], SUBSURFACE_RADIUS)
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = NOISE_SCALE
    noise.inputs["Detail"].default_value = 4.0
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = BUMP_STRENGTH
    links.new(noise.outputs["Fac"], bump.inputs["Height"])
    links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    noise.location = (bsdf.location.x - 500, bsdf.location.y - 300)
    bump.location = (bsdf.location.x - 250, bsdf.location.y - 300)
    mat.diffuse_color = SNOW_COLOR  # the viewport's solid mode
    return mat
