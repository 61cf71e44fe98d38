# vdrig's Blender driver: renders views of a vdrig scene with Cycles for the "blender" camera backend
# (sim/src/blender_camera.cpp, docs/blender.md). Started once per camera as
#     blender --background --factory-startup --python vdrig_blender.py -- --reply-fd N
# it reads one JSON command a line on stdin and answers each with one JSON line on file descriptor N (Blender's own
# stdout is left to Blender's messages). Commands:
#   {"cmd": "setup", "scene": <vdrig scene JSON> | null, "blend": "<file.blend>" | "", "markers": true,
#    "baked_kd": {"<patch index, -1 the background>": {"file": "<EXR>", "rect_mm": [x0, y0, x1, y1]}},
#    "camera": {"width", "height", "fx", "fy", "cx", "cy"}, "samples": 16, "seed": 1, "threads": 2}
#   {"cmd": "render", "camera_to_world": [16 numbers, row-major, metres, OpenCV camera axes], "lights": true,
#    "out": "<file.exr>"}                 -> writes linear scene radiance (float RGB OpenEXR) in vdrig's units
#   {"cmd": "quit"}
# Every answer is {"ok": true, ...} or {"ok": false, "error": "..."}.
#
# Units: vdrig's radiance is relative: a light of intensity I at d mm lights a white Lambertian surface facing it to
# I / d^2. Cycles' point light of power P W gives a white Lambertian surface at d m the radiance P / (4 pi^2 d^2), so
# P = 4 pi^2 I / 1e6 (mm -> m); an area light of intensity I along its normal (its radiance times its area) is
# P = pi^2 I / 1e6; a world of constant colour A adds kd A to a Lambertian surface, as vdrig's ambient does.
# This file is vdrig's own code (no Blender add-on code is copied).
import json
import math
import os
import sys
import time

import bpy

MM = 0.001  # metres per millimetre
LAYER_M = 1e-5  # height step between stacked patches (later patches lie above earlier ones, markers on top)


def reply(fd, obj):
    os.write(fd, (json.dumps(obj) + "\n").encode())


def clear_scene():
    for collection in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras,
                       bpy.data.images, bpy.data.worlds):
        for block in list(collection):
            collection.remove(block)


def rgb(v, default=(0.0, 0.0, 0.0)):
    v = v if v is not None else default
    return (float(v[0]), float(v[1]), float(v[2]), 1.0)


def link(tree, a, b):
    tree.links.new(a, b)


# vdrig's bump pattern (sim/src/scene.cpp, kBumpWaves): (a, b, w, phase) of three sinusoids; the shading normal is
# normalize(-slope hx, -slope hy, 1) with hx = sum a w cos(k (a x + b y) + phase), hy likewise with b, k = 2 pi /
# period, x and y in mm.
BUMP_WAVES = ((1.0, 0.31, 0.45, 0.3), (-0.27, 1.13, 0.35, 1.7), (0.71, -0.77, 0.20, 4.1))


def math_node(tree, op, a, b=None, c=None):
    node = tree.nodes.new("ShaderNodeMath")
    node.operation = op
    for i, v in enumerate((a, b, c)):
        if v is None:
            continue
        if isinstance(v, (int, float)):
            node.inputs[i].default_value = v
        else:
            tree.links.new(v, node.inputs[i])
    return node.outputs[0]


def bump_normal(tree, m):
    """The shading normal of vdrig's bump pattern from the shading point's position (world = surface frame)."""
    pos = tree.nodes.new("ShaderNodeNewGeometry")
    xyz = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(pos.outputs["Position"], xyz.inputs["Vector"])
    k = 2 * math.pi / float(m.get("bump_period_mm", 6.0)) / MM  # per metre
    slope = float(m.get("bump_slope", 0.0))
    hx = hy = None
    for a, b, w, phase in BUMP_WAVES:
        t = math_node(tree, "MULTIPLY_ADD", xyz.outputs["X"], k * a,
                      math_node(tree, "MULTIPLY_ADD", xyz.outputs["Y"], k * b, phase))
        c = math_node(tree, "COSINE", t)
        cx = math_node(tree, "MULTIPLY", c, -slope * a * w)
        cy = math_node(tree, "MULTIPLY", c, -slope * b * w)
        hx = cx if hx is None else math_node(tree, "ADD", hx, cx)
        hy = cy if hy is None else math_node(tree, "ADD", hy, cy)
    combine = tree.nodes.new("ShaderNodeCombineXYZ")
    tree.links.new(hx, combine.inputs["X"])
    tree.links.new(hy, combine.inputs["Y"])
    combine.inputs["Z"].default_value = 1.0
    norm = tree.nodes.new("ShaderNodeVectorMath")
    norm.operation = "NORMALIZE"
    tree.links.new(combine.outputs["Vector"], norm.inputs[0])
    return norm.outputs["Vector"]


def baked_kd(tree, baked):
    """kd from an image vdrig baked over rect_mm (the printed glyphs: exact cells, nearest texel), addressed by the
    shading point's position; the image's first row lies at the rectangle's largest y."""
    x0, y0, x1, y1 = baked["rect_mm"]
    pos = tree.nodes.new("ShaderNodeNewGeometry")
    xyz = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(pos.outputs["Position"], xyz.inputs["Vector"])
    u = math_node(tree, "MULTIPLY_ADD", xyz.outputs["X"], 1.0 / ((x1 - x0) * MM), -x0 / (x1 - x0))
    v = math_node(tree, "MULTIPLY_ADD", xyz.outputs["Y"], 1.0 / ((y1 - y0) * MM), -y0 / (y1 - y0))
    uv = tree.nodes.new("ShaderNodeCombineXYZ")
    tree.links.new(u, uv.inputs["X"])
    tree.links.new(v, uv.inputs["Y"])
    tex = tree.nodes.new("ShaderNodeTexImage")
    img = bpy.data.images.load(baked["file"])
    img.colorspace_settings.name = "Non-Color"
    tex.image = img
    tex.interpolation = "Closest"
    tex.extension = "EXTEND"
    tree.links.new(uv.outputs["Vector"], tex.inputs["Vector"])
    return tex.outputs["Color"]


def make_material(m, index, base_dir, baked=None):
    """A Blender material for a vdrig material: Diffuse BSDF (Lambert, exact) for kd, plus a GGX lobe: a Principled
    BSDF with metallic 1 (Schlick-like Fresnel from f0) for "ggx", a Glossy GGX of equal energy and width for a
    Phong lobe (an approximation: Phong's lobe is not a microfacet lobe). Bumped materials get vdrig's bump
    pattern as their shading normal; printed ones the kd vdrig baked (`baked`)."""
    mat = bpy.data.materials.new("vdrig_%d_%s" % (index, m.get("name", "")))
    mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert
    normal = bump_normal(tree, m) if float(m.get("bump_slope", 0.0)) > 0 else None
    if normal is not None:
        tree.links.new(normal, diffuse.inputs["Normal"])
    kd = rgb(m.get("kd"))
    if baked is not None:
        link(tree, baked_kd(tree, baked), diffuse.inputs["Color"])
    elif m.get("kd_image"):
        tex = tree.nodes.new("ShaderNodeTexImage")
        path = m["kd_image"]
        if not os.path.isabs(path):
            path = os.path.join(base_dir, path)
        img = bpy.data.images.load(path)
        # vdrig: an 8-bit PNG is sRGB, a 16-bit PNG or an EXR is linear.
        if img.file_format == "PNG" and img.depth <= 32 and not img.is_float:
            img.colorspace_settings.name = "sRGB"
        else:
            img.colorspace_settings.name = "Non-Color"
        tex.image = img
        tex.interpolation = "Linear"
        tex.extension = "EXTEND"
        link(tree, tex.outputs["Color"], diffuse.inputs["Color"])
    else:
        diffuse.inputs["Color"].default_value = kd
    shader = diffuse.outputs["BSDF"]
    kind = m.get("kind", "phong")
    lobe = None
    if kind == "ggx":
        ax = float(m.get("roughness", 0.3))
        ay = float(m.get("roughness_y", 0.0)) or ax
        lobe = tree.nodes.new("ShaderNodeBsdfPrincipled")
        lobe.distribution = "GGX"
        lobe.inputs["Base Color"].default_value = rgb(m.get("f0"), (0.04, 0.04, 0.04))
        lobe.inputs["Metallic"].default_value = 1.0
        # Cycles: alpha_x = r^2 / aspect, alpha_y = r^2 aspect, aspect = sqrt(1 - 0.9 anisotropic), along the
        # tangent (here the surface's x axis, from the UV map) turned by rotation * 360 deg.
        rotation = 0.0
        if ay > ax:
            ax, ay, rotation = ay, ax, 0.25
        r2 = math.sqrt(ax * ay)
        aspect = max(math.sqrt(0.1), math.sqrt(ay / ax))
        lobe.inputs["Roughness"].default_value = math.sqrt(r2)
        lobe.inputs["Anisotropic"].default_value = (1.0 - aspect * aspect) / 0.9
        lobe.inputs["Anisotropic Rotation"].default_value = rotation
        if ax != ay:
            tangent = tree.nodes.new("ShaderNodeTangent")
            tangent.direction_type = "UV_MAP"
            link(tree, tangent.outputs["Tangent"], lobe.inputs["Tangent"])
        lobe_out = lobe.outputs["BSDF"]
    else:
        ks = m.get("ks") or [0, 0, 0]
        if max(ks) > 0:
            shininess = float(m.get("shininess", 1.0))
            # vdrig's lobe E ks (v.r)^m is the BRDF ks (v.r)^m / pi = ks 2 / (m + 2) times a normalised Phong lobe,
            # which a Beckmann/GGX lobe of alpha^2 = 2 / (m + 2) approximates.
            scale = 2.0 / (shininess + 2.0)
            lobe = tree.nodes.new("ShaderNodeBsdfGlossy")
            lobe.distribution = "GGX"
            lobe.inputs["Color"].default_value = (ks[0] * scale, ks[1] * scale, ks[2] * scale, 1.0)
            lobe.inputs["Roughness"].default_value = math.sqrt(math.sqrt(2.0 / (shininess + 2.0)))
            lobe_out = lobe.outputs["BSDF"]
    if lobe is not None:
        if normal is not None:
            tree.links.new(normal, lobe.inputs["Normal"])
        add = tree.nodes.new("ShaderNodeAddShader")
        link(tree, shader, add.inputs[0])
        link(tree, lobe_out, add.inputs[1])
        shader = add.outputs["Shader"]
    link(tree, shader, out.inputs["Surface"])
    return mat


def add_quad(name, x0, y0, x1, y1, z, mat):
    mesh = bpy.data.meshes.new(name)
    verts = [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(mesh.loops, [(0, 0), (1, 0), (1, 1), (0, 1)]):
        uv.data[loop.index].uv = (u, v)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_disc(name, cx, cy, r, z, mat, segments=96):
    mesh = bpy.data.meshes.new(name)
    verts = [(cx + r * math.cos(2 * math.pi * k / segments), cy + r * math.sin(2 * math.pi * k / segments), z)
             for k in range(segments)]
    mesh.from_pydata(verts, [], [tuple(range(segments))])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, _ = verts[loop.vertex_index]
        uv.data[loop.index].uv = ((x - cx + r) / (2 * r), (y - cy + r) / (2 * r))
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_light(name, kind, power, colour, location, direction=None, size=None):
    light = bpy.data.lights.new(name, kind)
    light.energy = power
    light.color = colour
    light.shadow_soft_size = 0.0
    light.use_shadow = True
    if kind == "AREA":
        light.shape = "RECTANGLE"
        light.size, light.size_y = size
    obj = bpy.data.objects.new(name, light)
    obj.location = location
    if direction is not None:
        obj.matrix_world = direction
    bpy.context.scene.collection.objects.link(obj)
    obj.visible_camera = False
    return obj


def split_power(intensity, factor):
    """(power, colour) of an RGB intensity: Blender's light colour is in [0, 1], the power carries the scale."""
    peak = max(intensity)
    if peak <= 0:
        return 0.0, (0.0, 0.0, 0.0)
    return factor * peak, tuple(c / peak for c in intensity)


def build_vdrig_scene(scene, base_dir, markers=True, baked=None):
    """The vdrig scene (sim/scene_file.hpp's JSON) as Blender objects: the surface is the plane z = 0 of Blender's
    world (the surface frame, metres), each patch and marker a face stacked a hundredth of a millimetre above the
    previous one, so later patches cover earlier ones as in vdrig."""
    mats = [make_material(m, i, base_dir) for i, m in enumerate(scene["materials"])]

    def material(ref):
        if isinstance(ref, int):
            return mats[ref]
        for i, m in enumerate(scene["materials"]):
            if m.get("name") == ref:
                return mats[i]
        raise ValueError("no material is named %r" % ref)

    baked = baked or {}

    def material_of(patch, ref):
        """The patch's material; a printed one with the kd vdrig baked over this patch."""
        if str(patch) not in baked:
            return material(ref)
        index = ref if isinstance(ref, int) else [m.get("name") for m in scene["materials"]].index(ref)
        return make_material(scene["materials"][index], index, base_dir, baked[str(patch)])

    w, h = scene["width_mm"] * MM, scene["height_mm"] * MM
    add_quad("surface", -w / 2, -h / 2, w / 2, h / 2, 0.0, material_of(-1, 0))
    layer = 1
    for i, p in enumerate(scene.get("patches", [])):
        add_quad("patch_%d" % i, p["x0_mm"] * MM, p["y0_mm"] * MM, p["x1_mm"] * MM, p["y1_mm"] * MM, layer * LAYER_M,
                 material_of(i, p["material"]))
        layer += 1
    if markers:
        for i, d in enumerate(scene.get("markers", [])):
            c = d["centre_mm"]
            add_disc("marker_%d" % i, c[0] * MM, c[1] * MM, d.get("radius_mm", 30.0) * MM, layer * LAYER_M,
                     material(d.get("material", 0)))
    for i, light in enumerate(scene.get("lights", [])):
        power, colour = split_power(light.get("intensity", [1, 1, 1]), 4 * math.pi ** 2 / 1e6)
        p = light["position_mm"]
        add_light("light_%d" % i, "POINT", power, colour, (p[0] * MM, p[1] * MM, p[2] * MM))
    for i, a in enumerate(scene.get("area_lights", [])):
        from mathutils import Matrix, Vector
        u, v, c = Vector(a["edge_u_mm"]) * MM, Vector(a["edge_v_mm"]) * MM, Vector(a["centre_mm"]) * MM
        n = u.cross(v).normalized()
        # Blender's area light emits along its local -Z: local x = u, local y = -(n x u) keeps -Z = n.
        x = u.normalized()
        y = (-n).cross(x)
        basis = Matrix((x, y, -n)).transposed().to_4x4()
        basis.translation = c
        power, colour = split_power(a.get("intensity", [1, 1, 1]), math.pi ** 2 / 1e6)
        add_light("area_%d" % i, "AREA", power, colour, c, basis, (u.length, v.length))
    world = bpy.data.worlds.new("vdrig")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = rgb(scene.get("ambient"))
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    bpy.context.scene.world = world


def load_blend(path, markers, scene_markers):
    """A user's .blend: its object named "surface" is the sample (docs/blender.md); its own cameras are removed."""
    bpy.ops.wm.open_mainfile(filepath=path)
    surface = bpy.data.objects.get("surface")
    if surface is None or surface.type != "MESH":
        raise ValueError("%s has no mesh object named \"surface\" (the sample, docs/blender.md)" % path)
    for obj in list(bpy.data.objects):
        if obj.type == "CAMERA":
            bpy.data.objects.remove(obj)
    if markers and scene_markers:
        black = bpy.data.materials.new("vdrig_marker")
        black.use_nodes = True
        bsdf = black.node_tree.nodes.get("Principled BSDF")
        black.node_tree.nodes.remove(bsdf)
        diffuse = black.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.02, 0.02, 0.02, 1.0)
        black.node_tree.links.new(diffuse.outputs["BSDF"], black.node_tree.nodes["Material Output"].inputs["Surface"])
        for i, d in enumerate(scene_markers):
            c = d["centre_mm"]
            disc = add_disc("vdrig_marker_%d" % i, c[0] * MM, c[1] * MM, d.get("radius_mm", 30.0) * MM, 2e-4, black)
            disc.matrix_world = surface.matrix_world @ disc.matrix_world


def setup(cmd):
    sc = cmd.get("scene")
    blend = cmd.get("blend") or ""
    if blend:
        load_blend(blend, cmd.get("markers", True), (sc or {}).get("markers", []))
    else:
        clear_scene()
        build_vdrig_scene(sc, cmd.get("base_dir", "."), cmd.get("markers", True), cmd.get("baked_kd"))
    scene = bpy.context.scene
    cam = cmd["camera"]
    width, height = int(cam["width"]), int(cam["height"])
    if abs(cam["fx"] - cam["fy"]) > 1e-9 * cam["fx"]:
        raise ValueError("the Blender camera needs square pixels (fx = fy), got fx %g fy %g" % (cam["fx"], cam["fy"]))
    cam_data = bpy.data.cameras.new("vdrig_camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = 36.0
    cam_data.lens = cam["fx"] * 36.0 / width
    # Blender's shift moves the film by a fraction of its larger side; pixel centres are at integers in vdrig, so
    # the film's centre is at ((W - 1) / 2, (H - 1) / 2) and image y runs down.
    big = float(max(width, height))
    cam_data.shift_x = ((width - 1) / 2.0 - cam["cx"]) / big
    cam_data.shift_y = (cam["cy"] - (height - 1) / 2.0) / big
    cam_data.clip_start = 0.01
    cam_data.clip_end = 1000.0
    cam_obj = bpy.data.objects.new("vdrig_camera", cam_data)
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(cmd.get("samples", 16))
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = int(cmd.get("seed", 1))
    scene.cycles.use_animated_seed = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    scene.cycles.max_bounces = 4
    scene.cycles.caustics_reflective = False
    scene.cycles.caustics_refractive = False
    scene.cycles.light_sampling_threshold = 0.0
    scene.cycles.sample_clamp_direct = 0.0
    scene.cycles.sample_clamp_indirect = 0.0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = max(1, int(cmd.get("threads", 2)))
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0
    # Rays that miss everything are black, as in vdrig's renderer (an ambient world lights the surface, unseen).
    scene.render.film_transparent = True
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    return {"ok": True, "blender": bpy.app.version_string}


LIGHT_KINDS = ("LIGHT",)


def render(cmd):
    from mathutils import Matrix
    scene = bpy.context.scene
    m = cmd["camera_to_world"]
    pose = Matrix([m[0:4], m[4:8], m[8:12], m[12:16]])
    # OpenCV camera axes (x right, y down, z forward) to Blender's (x right, y up, looking down -z).
    flip = Matrix(((1, 0, 0, 0), (0, -1, 0, 0), (0, 0, -1, 0), (0, 0, 0, 1)))
    scene.camera.matrix_world = pose @ flip
    lights_on = bool(cmd.get("lights", True))
    for obj in scene.objects:
        if obj.type in LIGHT_KINDS:
            obj.hide_render = not lights_on
    if scene.world is not None:
        scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0 if lights_on else 0.0
    scene.render.filepath = cmd["out"]
    start = time.monotonic()
    bpy.ops.render.render(write_still=True)
    if not os.path.exists(cmd["out"]):
        raise RuntimeError("Cycles wrote no image to %s" % cmd["out"])
    return {"ok": True, "seconds": time.monotonic() - start}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    fd = int(argv[argv.index("--reply-fd") + 1])
    reply(fd, {"ok": True, "ready": True, "blender": bpy.app.version_string})
    for line in sys.stdin:
        line = line.strip()
        if not line:
            continue
        try:
            cmd = json.loads(line)
            what = cmd.get("cmd")
            if what == "quit":
                reply(fd, {"ok": True})
                break
            if what == "setup":
                reply(fd, setup(cmd))
            elif what == "render":
                reply(fd, render(cmd))
            elif what == "crash":  # tests: a Blender that dies mid-session
                os._exit(9)
            elif what == "hang":  # tests: a Blender that stops answering
                time.sleep(3600)
            else:
                reply(fd, {"ok": False, "error": "unknown command %r" % what})
        except Exception as e:  # every failure is an answer, never a silent exit
            reply(fd, {"ok": False, "error": "%s: %s" % (type(e).__name__, e)})
    sys.stdout.flush()
    # vdrig went away (or asked to quit): the work folder it made for this process goes with it.
    here = os.path.dirname(os.path.abspath(__file__))
    if os.path.basename(here).startswith("vdrig-blender-"):
        import shutil
        shutil.rmtree(here, ignore_errors=True)


main()
