# Renders an exported .gltf with Blender: its own glTF importer (bpy.ops.import_scene.gltf, the io_scene_gltf2 add-on
# Blender ships) and Cycles; the peer renderer of tests/fidelity/test_gltf_blender.cpp, beside three.js
# (three_render.mjs).
#   blender --background --factory-startup --python blender_render.py -- JOB.json
# JOB: {"gltf": path, "width": W, "height": H, "samples": n, "out_dir": path,
#       "light": {"position": [x, y, z], "power_w": p, "colour": [r, g, b]},
#       "views": [{"camera_to_world": [16 numbers, row major], "fov_y_deg": f, "flip_green": false,
#                  "fresnel_free": false}, ...]}
# in Blender's frame (Z up, metres; the importer maps glTF's Y up to it). The light is a Cycles point light of radius
# 0. Each view is rendered (no denoising, box filter one pixel wide, Standard view transform, transparent film) and
# written as raw float32 RGBA, bottom row first, to out_dir/view_K.f32. Prints one JSON line of facts on stdout;
# exits 1 with the reason on a failure. Its functions also serve tests/fidelity/blender_roundtrip.py (which imports
# this file as a module: main runs only as Blender's script). This file is vdrig's own code.
import json
import math
import os
import sys
import time

import bpy
from mathutils import Matrix


def negate_green(material, on):
    """The normal map's green channel as 1 - g (the other tangent-space convention), as a control."""
    tree = material.node_tree
    normal = next((n for n in tree.nodes if n.type == "NORMAL_MAP"), None)
    if normal is None:
        return False
    link = normal.inputs["Color"].links[0] if normal.inputs["Color"].links else None
    if link is None:
        return False
    src = link.from_socket
    if src.node.name == "vdrig_combine":  # already rerouted: find the image's socket behind it
        src = tree.nodes["vdrig_separate"].inputs[0].links[0].from_socket
    tree.links.remove(link)
    if not on:
        tree.links.new(src, normal.inputs["Color"])
        return True
    sep = tree.nodes.get("vdrig_separate") or tree.nodes.new("ShaderNodeSeparateColor")
    sep.name = "vdrig_separate"
    inv = tree.nodes.get("vdrig_invert") or tree.nodes.new("ShaderNodeMath")
    inv.name = "vdrig_invert"
    inv.operation = "SUBTRACT"
    inv.inputs[0].default_value = 1.0
    comb = tree.nodes.get("vdrig_combine") or tree.nodes.new("ShaderNodeCombineColor")
    comb.name = "vdrig_combine"
    for l in list(sep.inputs[0].links):
        tree.links.remove(l)
    tree.links.new(src, sep.inputs[0])
    tree.links.new(sep.outputs[0], comb.inputs[0])
    tree.links.new(sep.outputs[1], inv.inputs[1])
    tree.links.new(inv.outputs[0], comb.inputs[1])
    tree.links.new(sep.outputs[2], comb.inputs[2])
    tree.links.new(comb.outputs[0], normal.inputs["Color"])
    return True


def fresnel_free(material, on):
    """The experiment of docs/results.md section 9: the Principled BSDF's output replaced by a Lambertian Diffuse BSDF
    of the base colour plus a GGX Glossy BSDF of constant colour 0.04 (glTF's dielectric F0, no Fresnel), same
    roughness and normal: Principled v1's Fresnel taken out."""
    tree = material.node_tree
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    principled = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    add = tree.nodes.get("vdrig_fresnel_free")
    if add is None:
        add = tree.nodes.new("ShaderNodeAddShader")
        add.name = "vdrig_fresnel_free"
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Roughness"].default_value = 0.0
        glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
        glossy.distribution = "GGX"
        glossy.inputs["Color"].default_value = (0.04, 0.04, 0.04, 1.0)
        for socket, targets in (("Base Color", [diffuse.inputs["Color"]]), ("Roughness", [glossy.inputs["Roughness"]]),
                                ("Normal", [diffuse.inputs["Normal"], glossy.inputs["Normal"]])):
            if principled.inputs[socket].links:
                for target in targets:
                    tree.links.new(principled.inputs[socket].links[0].from_socket, target)
        tree.links.new(diffuse.outputs[0], add.inputs[0])
        tree.links.new(glossy.outputs[0], add.inputs[1])
    tree.links.new((add if on else principled).outputs[0], out.inputs["Surface"])


def require_numpy():
    """The importer needs numpy (Debian's blender does not depend on python3-numpy): exits 3 with VDRIG_SKIP without
    it. Debian 12's blender 3.4.1 importer calls numpy.bool, an alias numpy 1.24 (Debian 12's) removed: restored."""
    try:
        import numpy
    except ImportError:
        print("VDRIG_SKIP Blender's Python has no numpy (scripts/setup installs python3-numpy)")
        sys.stdout.flush()
        os._exit(3)
    if not hasattr(numpy, "bool"):
        numpy.bool = bool


def import_gltf(gltf_file):
    """An empty scene holding the .gltf as Blender's own importer reads it, without lights or cameras (an export holds
    none; be sure). Returns the scene and the first mesh's material."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if not hasattr(bpy.ops.import_scene, "gltf"):
        raise RuntimeError("this Blender has no glTF importer (io_scene_gltf2)")
    bpy.ops.import_scene.gltf(filepath=gltf_file)
    for obj in list(scene.objects):
        if obj.type in ("LIGHT", "CAMERA"):
            bpy.data.objects.remove(obj)
    meshes = [o for o in scene.objects if o.type == "MESH"]
    if not meshes or not meshes[0].active_material:
        raise RuntimeError("the import holds no mesh with a material")
    return scene, meshes[0].active_material


def setup_cycles(scene, job, max_bounces):
    """Cycles on the CPU at job's samples a pixel, no adaptive sampling or denoising, seed 1, box filter one pixel
    wide, two threads, job's width x height, transparent film, float RGBA EXR, Standard view transform."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(job.get("samples", 16))
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = 1
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    scene.cycles.max_bounces = max_bounces
    scene.cycles.light_sampling_threshold = 0.0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.resolution_x = int(job["width"])
    scene.render.resolution_y = int(job["height"])
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.image_settings.color_depth = "32"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"


def render_f32(scene, out_dir, name):
    """Renders the scene's camera to out_dir/NAME.exr and writes its linear RGBA as raw float32, bottom row first, to
    out_dir/NAME.f32."""
    import numpy
    exr = os.path.join(out_dir, name + ".exr")
    scene.render.filepath = exr
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(exr)
    image.colorspace_settings.name = "Non-Color"  # the EXR's linear values as they are
    pixels = numpy.empty(len(image.pixels), dtype=numpy.float32)
    image.pixels.foreach_get(pixels)
    pixels.tofile(os.path.join(out_dir, name + ".f32"))
    bpy.data.images.remove(image)


def main():
    job = json.load(open(sys.argv[sys.argv.index("--") + 1]))
    require_numpy()
    scene, material = import_gltf(job["gltf"])
    principled = next((n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)

    light_data = bpy.data.lights.new("vdrig_light", "POINT")
    light_data.energy = job["light"]["power_w"]
    light_data.color = job["light"]["colour"]
    light_data.shadow_soft_size = 0.0
    light = bpy.data.objects.new("vdrig_light", light_data)
    light.location = job["light"]["position"]
    scene.collection.objects.link(light)
    cam_data = bpy.data.cameras.new("vdrig_camera")
    cam_data.sensor_fit = "VERTICAL"
    cam_data.clip_start = 0.01
    cam_data.clip_end = 100.0
    cam = bpy.data.objects.new("vdrig_camera", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.world = None  # no ambient light: the point light alone, as three.js's scene
    setup_cycles(scene, job, max_bounces=1)

    start = time.monotonic()
    for k, v in enumerate(job["views"]):
        m = v["camera_to_world"]
        cam.matrix_world = Matrix([m[0:4], m[4:8], m[8:12], m[12:16]])
        cam_data.angle = math.radians(v["fov_y_deg"])
        negate_green(material, bool(v.get("flip_green", False)))
        fresnel_free(material, bool(v.get("fresnel_free", False)))
        render_f32(scene, job["out_dir"], "view_%d" % k)
    facts = {"blender": bpy.app.version_string, "render_s": time.monotonic() - start,
             "material": material.name, "normal_map": any(n.type == "NORMAL_MAP" for n in material.node_tree.nodes)}
    if principled is not None:
        for name in ("Roughness", "Specular", "Metallic"):
            socket = principled.inputs[name]
            facts[name.lower()] = None if socket.links else socket.default_value
    print("VDRIG_RESULT " + json.dumps(facts))


def run(main, script):
    """Runs a script's main and ends Blender: exit 0, or 1 with the reason on stderr (the test shows it)."""
    try:
        main()
    except Exception as e:
        sys.stderr.write("%s: %s\n" % (script, e))
        sys.stdout.flush()
        os._exit(1)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":  # Blender's script, not blender_roundtrip.py's import
    run(main, "blender_render.py")
