# Writes the .blend sample files of the Blender fidelity table (docs/blender.md, docs/results.md): each holds the mesh
# "surface" (1 x 1 m in its local XY plane, facing +Z, with UVs) of one Principled BSDF material on a white board
# (the central 0.8 x 0.8 m is the sample) and the point light
# of vdrig's built-in scenes (1.5, 1.5, 2.0 m, irradiance 1 at the centre in vdrig's units), world black.
#   blender --background --factory-startup --python scripts/blender_scenes.py -- OUT_DIR [NAME ...]
# vdrig's own code.
import math
import os
import sys

import bpy

# vdrig's patchwork light: intensity 12390772.8 (mm units) -> Cycles power 4 pi^2 I / 1e6 W (sim/blender).
LIGHT_W = 4 * math.pi ** 2 * 12390772.8 / 1e6


def principled(tree):
    return tree.nodes["Principled BSDF"]


def textured(tree, bsdf, colour_a, colour_b, scale, kind):
    """Base colour from a procedural texture on the UVs, between two colours."""
    coords = tree.nodes.new("ShaderNodeTexCoord")
    if kind == "print":
        # Text-like print: dark bricks (glyph strokes) in rows on white paper.
        tex = tree.nodes.new("ShaderNodeTexBrick")
        tex.inputs["Color1"].default_value = colour_b
        tex.inputs["Color2"].default_value = colour_b
        tex.inputs["Mortar"].default_value = colour_a
        tex.inputs["Scale"].default_value = scale
        tex.inputs["Mortar Size"].default_value = 0.02
        tex.inputs["Brick Width"].default_value = 0.6
        tex.inputs["Row Height"].default_value = 0.5
        tree.links.new(coords.outputs["UV"], tex.inputs["Vector"])
        tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
        return
    tex = tree.nodes.new("ShaderNodeTexNoise")
    tex.inputs["Scale"].default_value = scale
    tex.inputs["Detail"].default_value = 2.0
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = colour_a
    ramp.color_ramp.elements[1].color = colour_b
    tree.links.new(coords.outputs["UV"], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])


def set_inputs(bsdf, **values):
    for key, value in values.items():
        bsdf.inputs[key.replace("_", " ").title().replace("Ior", "IOR")].default_value = value


MATERIALS = {
    "glossy_plastic": dict(base=(0.08, 0.2, 0.55, 1), Roughness=0.15, Specular=0.5),
    "rough_metal": dict(base=(0.9, 0.62, 0.42, 1), Metallic=1.0, Roughness=0.45),
    "brushed_metal": dict(base=(0.8, 0.8, 0.82, 1), Metallic=1.0, Roughness=0.3, Anisotropic=0.8, tangent=True),
    "clearcoat_paint": dict(base=(0.55, 0.04, 0.04, 1), Roughness=0.5, Clearcoat=1.0, Clearcoat_Roughness=0.03),
    "printed_paper": dict(texture=("print", (0.8, 0.78, 0.72, 1), (0.04, 0.04, 0.05, 1), 60.0), Roughness=0.7,
                          Specular=0.3),
    "fabric_sheen": dict(base=(0.45, 0.08, 0.25, 1), Roughness=0.9, Sheen=1.0, Sheen_Tint=0.5, Specular=0.2),
    "textured_clearcoat_plastic": dict(texture=("noise", (0.7, 0.45, 0.1, 1), (0.1, 0.3, 0.6, 1), 8.0),
                                       Roughness=0.4, Clearcoat=1.0, Clearcoat_Roughness=0.05),
    # The glTF round trip's sample (tests/fidelity/test_blender_roundtrip.cpp): what ggx:iso+n can hold, a textured
    # dielectric with a shading normal from a bump map (UV noise of scale 4 as the height, Bump distance 0.04 m).
    "bumped_textured_plastic": dict(texture=("noise", (0.7, 0.45, 0.1, 1), (0.1, 0.3, 0.6, 1), 8.0),
                                    bump=(4.0, 0.04), Roughness=0.4, Specular=0.5),
}


def make(name, spec, path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    # The sample mounted on a board: 1 x 1 m in all (UVs over [0, 1]^2, normal +Z), the material over the central
    # 0.8 x 0.8 m and white paper around it, where vdrig's black corner markers go (on a dark metal they would
    # not stand out: the extrinsics need their contrast, on a real rig too).
    edges = (-0.5, -0.4, 0.4, 0.5)
    verts = [(x, y, 0.0) for y in edges for x in edges]
    faces = [(j * 4 + i, j * 4 + i + 1, (j + 1) * 4 + i + 1, (j + 1) * 4 + i) for j in range(3) for i in range(3)]
    mesh = bpy.data.meshes.new("surface")
    mesh.from_pydata(verts, [], faces)
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, _ = verts[loop.vertex_index]
        uv.data[loop.index].uv = (x + 0.5, y + 0.5)
    surface = bpy.data.objects.new("surface", mesh)
    scene.collection.objects.link(surface)
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    tree = mat.node_tree
    bsdf = principled(tree)
    bsdf.distribution = "GGX"
    spec = dict(spec)
    if "base" in spec:
        bsdf.inputs["Base Color"].default_value = spec.pop("base")
    if "texture" in spec:
        kind, a, b, scale = spec.pop("texture")
        textured(tree, bsdf, a, b, scale, kind)
    if spec.pop("tangent", False):
        tangent = tree.nodes.new("ShaderNodeTangent")
        tangent.direction_type = "UV_MAP"
        tree.links.new(tangent.outputs["Tangent"], bsdf.inputs["Tangent"])
    if "bump" in spec:
        # A bump map: Cycles' shading normal from the height's screen-space derivatives (Bump node).
        scale, distance = spec.pop("bump")
        coords = tree.nodes.new("ShaderNodeTexCoord")
        height = tree.nodes.new("ShaderNodeTexNoise")
        height.inputs["Scale"].default_value = scale
        height.inputs["Detail"].default_value = 0.0
        bump = tree.nodes.new("ShaderNodeBump")
        bump.inputs["Distance"].default_value = distance
        tree.links.new(coords.outputs["UV"], height.inputs["Vector"])
        tree.links.new(height.outputs["Fac"], bump.inputs["Height"])
        tree.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    set_inputs(bsdf, **spec)
    paper = bpy.data.materials.new("board")
    paper.use_nodes = True
    paper.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.75, 0.74, 0.7, 1)
    paper.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.9
    paper.node_tree.nodes["Principled BSDF"].inputs["Specular"].default_value = 0.2
    mesh.materials.append(mat)
    mesh.materials.append(paper)
    for k, poly in enumerate(mesh.polygons):
        poly.material_index = 0 if k == 4 else 1
    light = bpy.data.lights.new("light", "POINT")
    light.energy = LIGHT_W
    light.shadow_soft_size = 0.0
    light_obj = bpy.data.objects.new("light", light)
    light_obj.location = (1.5, 1.5, 2.0)
    scene.collection.objects.link(light_obj)
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    scene.world = world
    bpy.ops.wm.save_as_mainfile(filepath=path)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    out = argv[0] if argv else "."
    names = argv[1:] or list(MATERIALS)
    os.makedirs(out, exist_ok=True)
    for name in names:
        make(name, MATERIALS[name], os.path.join(os.path.abspath(out), name + ".blend"))
        print("wrote", os.path.join(out, name + ".blend"))


main()
