# The Blender half of the glTF round trip (tests/fidelity/test_blender_roundtrip.cpp): renders views of the ORIGINAL
# .blend sample and of vdrig's glTF export of its fit, imported with Blender's own glTF importer
# (bpy.ops.import_scene.gltf), with the same camera, light and Cycles settings.
#   blender --background --factory-startup --python blender_roundtrip.py -- JOB.json
# JOB: {"blend": path, "gltf": path, "out_dir": path, "width": W, "height": H, "fx": f, "cx": cx, "cy": cy,
#       "samples": n, "views": [[16 numbers: camera to surface frame, row major, metres, OpenCV camera axes], ...]}
# The camera is vdrig_blender.py's pinhole (square pixels, pixel centres at integers). The .blend's lights are copied
# into the imported scene (the export holds none); the world is black in both. Writes, per view K, raw float32 RGBA,
# bottom row first: out_dir/original_K.f32, out_dir/gltf_K.f32, out_dir/control_K.f32, the import with the
# roughness texture squared on its way into the Principled BSDF (as if the exporter had written alpha where glTF
# wants sqrt(alpha)): a negative control; and, when the export carries KHR_materials_specular, out_dir/corrected_K.f32:
# the import with its specular conversion replaced by the extension's definition (spec_specular). Prints one line
# "VDRIG_RESULT {json}"; exits 3 with VDRIG_SKIP when Blender's Python has no numpy (the importer needs it), 1 with
# the reason on a failure. The import, Cycles settings and render-to-float32 are tests/gltf/blender_render.py's (the
# glTF peer render), imported from there. vdrig's own code.
import json
import math
import os
import sys
import time

import bpy
from mathutils import Matrix

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "gltf"))
import blender_render  # noqa: E402 (tests/gltf/blender_render.py: found through the path above)


def setup_render(scene, job):
    """vdrig_blender.py's settings: blender_render.py's Cycles settings (CPU, no denoising, box filter of one pixel,
    linear EXR) with four bounces, no caustics and no clamping."""
    blender_render.setup_cycles(scene, job, max_bounces=4)
    scene.cycles.use_animated_seed = False
    scene.cycles.caustics_reflective = False
    scene.cycles.caustics_refractive = False
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


def add_camera(scene, job):
    width, height = int(job["width"]), int(job["height"])
    data = bpy.data.cameras.new("vdrig_camera")
    data.type = "PERSP"
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = 36.0
    data.lens = job["fx"] * 36.0 / width
    big = float(max(width, height))
    data.shift_x = ((width - 1) / 2.0 - job["cx"]) / big
    data.shift_y = (job["cy"] - (height - 1) / 2.0) / big
    data.clip_start = 0.01
    data.clip_end = 1000.0
    cam = bpy.data.objects.new("vdrig_camera", data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def render_views(scene, cam, job, prefix):
    flip = Matrix(((1, 0, 0, 0), (0, -1, 0, 0), (0, 0, -1, 0), (0, 0, 0, 1)))  # OpenCV axes to Blender's
    for k, m in enumerate(job["views"]):
        cam.matrix_world = Matrix([m[0:4], m[4:8], m[8:12], m[12:16]]) @ flip
        blender_render.render_f32(scene, job["out_dir"], "%s_%d" % (prefix, k))


def square_roughness(material):
    """Inserts roughness^2 between the importer's roughness (the texture's G) and the Principled BSDF."""
    tree = material.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    socket = bsdf.inputs["Roughness"]
    if not socket.links:
        raise RuntimeError("the imported Principled BSDF's roughness is not textured")
    src = socket.links[0].from_socket
    tree.links.remove(socket.links[0])
    power = tree.nodes.new("ShaderNodeMath")
    power.operation = "POWER"
    power.inputs[1].default_value = 2.0
    tree.links.new(src, power.inputs[0])
    tree.links.new(power.outputs[0], socket)


def spec_specular(material, gltf_file):
    """Replaces the importer's KHR_materials_specular conversion by glTF's definition: Principled BSDF (v1, Blender 3.x)
    has F0 = 0.08 Specular, tinted towards the base colour by Specular Tint; the extension's dielectric F0 is
    0.04 specularColorFactor specularColorTexture (the texture sRGB-decoded: Blender's shader decodes the image node,
    whose colour space the importer set to sRGB). So Specular = luminance(0.04 factor texture) / 0.08, Tint 0 (F0's
    colour is lost: Principled v1 cannot hold it). Returns False when the material has no specular colour texture."""
    tree = material.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    tex = next((n for n in tree.nodes if n.type == "TEX_IMAGE" and n.label == "SPECULAR COLOR"), None)
    if tex is None:
        return False
    ext = json.load(open(gltf_file))["materials"][0]["extensions"]["KHR_materials_specular"]
    factor = ext.get("specularColorFactor", [1.0, 1.0, 1.0])
    scale = tree.nodes.new("ShaderNodeMixRGB")
    scale.blend_type = "MULTIPLY"
    scale.inputs[0].default_value = 1.0
    scale.inputs[2].default_value = (factor[0], factor[1], factor[2], 1.0)
    tree.links.new(tex.outputs["Color"], scale.inputs[1])
    grey = tree.nodes.new("ShaderNodeRGBToBW")
    tree.links.new(scale.outputs[0], grey.inputs[0])
    specular = tree.nodes.new("ShaderNodeMath")
    specular.operation = "MULTIPLY"
    specular.inputs[1].default_value = 0.04 / 0.08 * ext.get("specularFactor", 1.0)
    tree.links.new(grey.outputs[0], specular.inputs[0])
    for name in ("Specular", "Specular Tint"):
        for l in list(bsdf.inputs[name].links):
            tree.links.remove(l)
    tree.links.new(specular.outputs[0], bsdf.inputs["Specular"])
    bsdf.inputs["Specular Tint"].default_value = 0.0
    return True


def square_roughness_undo(material):
    """Takes square_roughness's node out again."""
    tree = material.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    power = bsdf.inputs["Roughness"].links[0].from_node
    src = power.inputs[0].links[0].from_socket
    tree.nodes.remove(power)
    tree.links.new(src, bsdf.inputs["Roughness"])


def main():
    job = json.load(open(sys.argv[sys.argv.index("--") + 1]))
    blender_render.require_numpy()
    start = time.monotonic()
    # The original: the .blend as the blender camera renders it (its lights and world, its cameras removed).
    bpy.ops.wm.open_mainfile(filepath=job["blend"])
    scene = bpy.context.scene
    for obj in list(bpy.data.objects):
        if obj.type == "CAMERA":
            bpy.data.objects.remove(obj)
    lights = [{"type": o.data.type, "matrix": [list(r) for r in o.matrix_world], "energy": o.data.energy,
               "colour": list(o.data.color), "radius": o.data.shadow_soft_size}
              for o in scene.objects if o.type == "LIGHT"]
    setup_render(scene, job)
    render_views(scene, add_camera(scene, job), job, "original")

    # The export, through Blender's own importer, under the same lights and camera.
    scene, material = blender_render.import_gltf(job["gltf"])
    for i, l in enumerate(lights):
        data = bpy.data.lights.new("light_%d" % i, l["type"])
        data.energy = l["energy"]
        data.color = l["colour"]
        data.shadow_soft_size = l["radius"]
        obj = bpy.data.objects.new("light_%d" % i, data)
        obj.matrix_world = Matrix(l["matrix"])
        scene.collection.objects.link(obj)
    scene.world = None
    setup_render(scene, job)
    cam = add_camera(scene, job)
    render_views(scene, cam, job, "gltf")
    square_roughness(material)
    render_views(scene, cam, job, "control")
    # The experiment of docs/blender.md: the same import with its specular conversion replaced by glTF's definition
    # (roughness as imported).
    square_roughness_undo(material)
    corrected = spec_specular(material, job["gltf"])
    if corrected:
        render_views(scene, cam, job, "corrected")
    print("VDRIG_RESULT " + json.dumps({"blender": bpy.app.version_string, "seconds": time.monotonic() - start,
                                        "lights": len(lights), "corrected": corrected}))


blender_render.run(main, "blender_roundtrip.py")
