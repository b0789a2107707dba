# Renders an RGB-D scan of a textured room with Blender Cycles: independent truth for the
# whole pipeline (frames -> reconstruction -> albedo from the colours seen -> lights; issue
# 41). A 3 x 3 m room (a plank floor, three 2.2 m walls, the -y side open, no ceiling) with a
# checker rug, a checker poster, a table, two boxes and a sphere, Lambertian everywhere, lit
# by KIND's lights; FRAMES frames along an arc in front of the open side at hand-held speed.
# Writes OUT_DIR in the Redwood layout that `lightprobe --headless` reads:
#   color/NNNNN.png  8-bit sRGB (Blender's Standard view transform, exposure 0: one image
#                    unit is one unit of Cycles radiance)
#   depth/NNNNN.png  16-bit millimetres, planar z, Kinect-like noise: sigma 1.5 mm x z^2,
#                    1 mm steps, 1.5 % dropouts, holes at depth edges
#   trajectory.log   world_from_camera (OpenCV axes), z up, metres; intrinsics.json
#   truth.json       the lights (a lamp's position, radius, radiant intensity in image
#                    units; a sun's direction and irradiance), the sky, scene_bbox, materials
#   gt_mesh.ply      the true geometry
#   holdout/         a view off the trajectory: holdout.exr (linear), mask.png (what the
#                    room covers), albedo.exr (Cycles' diffuse colour), depth.exr,
#                    holdout.json (its camera)
#
#   blender -b -noaudio --factory-startup --python scripts/make-cycles-scan.py -- OUT_DIR KIND [FRAMES] [SPP] [WIDTH]
#
# KIND: one-lamp, two-lamps (warm 140 W and cool 70 W), lamp-and-sun (a lamp and a sun
# through the open side), heavy-texture (one lamp, high-contrast checkers on every wall),
# dark-room (one lamp, no sky), frosted-window (no lamp: a 0.8 x 0.7 m pane in the back wall
# glowing at PANE_RADIANCE, brighter than the 8-bit frames hold, and the dim sky; issue 43),
# bulb-seen (one bare bulb at 1.35 m, in view of most frames: the camera sees its 5 cm sphere
# at its radiance, clipped, and, as a structured-light sensor blinded by it, no depth there;
# the held-out view's mask leaves it out; issue 43's seen lamps), glazed-window (no lamp: the
# frosted window's place in the back wall a hole, clear glass that Cycles does not render,
# and the world bright (CONE_RADIANCE) in a cone of CONE_DEG about CONE_AXIS behind it, the
# dim sky elsewhere, so a beam comes through; the depth frames see the glass as a pane, as a
# depth camera that returned depth on it; gt_mesh.ply has the pane; issue 43's windows),
# clear-window (the same, the glass returning no depth, as clear glass does to a depth
# camera: a hole in the scan).
# Defaults: 150 frames, 32 spp, 320 px wide (4:3).
# (apt-get install blender; Debian 12 has 3.4.1; numpy comes with it.)
import json
import math
import os
import struct
import sys
import zlib

import bpy
import mathutils
import numpy as np

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = os.path.abspath(argv[0] if argv else "out/scan")
KIND = argv[1] if len(argv) > 1 else "one-lamp"
FRAMES = int(argv[2]) if len(argv) > 2 else 150
SPP = int(argv[3]) if len(argv) > 3 else 32
W = int(argv[4]) if len(argv) > 4 else 320
H = W * 3 // 4
KINDS = ("one-lamp", "two-lamps", "lamp-and-sun", "heavy-texture", "dark-room", "frosted-window", "bulb-seen",
         "glazed-window", "clear-window")
if KIND not in KINDS:
    sys.exit("make-cycles-scan: KIND must be one of " + ", ".join(KINDS))
SEED = 1000 + KINDS.index(KIND)
rng = np.random.default_rng(SEED)
FOCAL = 525.0 * W / 640  # a Kinect's 525 px at 640


def srgb_to_linear(c):
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


# ---------------------------------------------------------------- geometry (also gt_mesh.ply)
parts = {}  # name -> (vertices, faces)


def add_part(name, verts, faces):
    parts[name] = ([tuple(map(float, v)) for v in verts], [tuple(f) for f in faces])


def quad_part(name, a, b, c, d):
    add_part(name, [a, b, c, d], [(0, 1, 2, 3)])


def box_part(name, x0, x1, y0, y1, z0, z1):
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    f = [(4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7), (0, 3, 2, 1)]
    add_part(name, v, f)


def sphere_part(name, centre, r, rings=24, segments=48):
    v, f = [], []
    for i in range(rings + 1):
        th = math.pi * i / rings
        for j in range(segments):
            ph = 2 * math.pi * j / segments
            v.append((centre[0] + r * math.sin(th) * math.cos(ph), centre[1] + r * math.sin(th) * math.sin(ph),
                      centre[2] + r * math.cos(th)))
    for i in range(rings):
        for j in range(segments):
            a, b = i * segments + j, i * segments + (j + 1) % segments
            f.append((a, a + segments, b + segments, b))  # outward
    add_part(name, v, f)


HALF, WALL_H = 1.5, 2.2
quad_part("floor", (-HALF, -HALF, 0), (HALF, -HALF, 0), (HALF, HALF, 0), (-HALF, HALF, 0))
quad_part("wall_left", (-HALF, -HALF, 0), (-HALF, -HALF, WALL_H), (-HALF, HALF, WALL_H), (-HALF, HALF, 0))
PANE = (0.45, 1.25, 1.0, 1.7)  # frosted-window: x0, x1, z0, z1 on the back wall, 4 mm in front of it
if KIND in ("glazed-window", "clear-window"):  # the back wall around a hole at PANE (four quads)
    wall_quads = [(-HALF, HALF, 0, PANE[2]), (-HALF, HALF, PANE[3], WALL_H), (-HALF, PANE[0], PANE[2], PANE[3]),
                  (PANE[1], HALF, PANE[2], PANE[3])]
    add_part("wall_back", [(x, HALF, z) for x0, x1, z0, z1 in wall_quads for x, z in ((x0, z0), (x0, z1), (x1, z1), (x1, z0))],
             [(4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3) for k in range(4)])
else:
    quad_part("wall_back", (-HALF, HALF, 0), (-HALF, HALF, WALL_H), (HALF, HALF, WALL_H), (HALF, HALF, 0))
quad_part("wall_right", (HALF, HALF, 0), (HALF, HALF, WALL_H), (HALF, -HALF, WALL_H), (HALF, -HALF, 0))
quad_part("rug", (-0.9, -0.5, 0.004), (0.1, -0.5, 0.004), (0.1, 0.4, 0.004), (-0.9, 0.4, 0.004))
quad_part("poster", (-0.5, HALF - 0.004, 0.9), (-0.5, HALF - 0.004, 1.7), (0.3, HALF - 0.004, 1.7),
          (0.3, HALF - 0.004, 0.9))
box_part("table", 0.45, 1.25, 0.35, 1.05, 0.0, 0.72)
box_part("box_red", -1.2, -0.75, 0.75, 1.2, 0.0, 0.45)
box_part("box_blue", 0.75, 1.1, -0.9, -0.55, 0.0, 0.6)
sphere_part("sphere", (-0.35, 0.9, 0.3), 0.3)
PANE_RADIANCE = (1.6, 1.5, 1.35)
if KIND == "frosted-window":
    quad_part("pane", (PANE[0], HALF - 0.004, PANE[2]), (PANE[0], HALF - 0.004, PANE[3]),
              (PANE[1], HALF - 0.004, PANE[3]), (PANE[1], HALF - 0.004, PANE[2]))

# ---------------------------------------------------------------- materials (linear albedo)
HEAVY = KIND == "heavy-texture"
MATERIALS = {
    "floor": ("bricks", (0.30, 0.18, 0.09), (0.42, 0.27, 0.14)),
    "wall_left": ("checker", (0.72, 0.70, 0.66), (0.08, 0.08, 0.09)) if HEAVY else ("flat", (0.72, 0.70, 0.66)),
    "wall_back": ("checker", (0.70, 0.70, 0.72), (0.10, 0.12, 0.20)) if HEAVY else ("flat", (0.70, 0.70, 0.72)),
    "wall_right": ("checker", (0.68, 0.64, 0.55), (0.15, 0.06, 0.05)) if HEAVY else ("flat", (0.68, 0.64, 0.55)),
    "rug": ("checker", (0.55, 0.12, 0.10), (0.75, 0.70, 0.55)),
    "poster": ("checker", (0.75, 0.65, 0.10), (0.05, 0.20, 0.55)),
    "table": ("flat", (0.45, 0.30, 0.17)),
    "box_red": ("flat", (0.50, 0.10, 0.07)),
    "box_blue": ("flat", (0.08, 0.20, 0.45)),
    "sphere": ("flat", (0.75, 0.75, 0.75)),
    "pane": ("glow", (0.70, 0.70, 0.72), PANE_RADIANCE),  # the wall's albedo and its own light
}


def make_material(name, spec):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Roughness"].default_value = 0.0  # Lambert
    out = nodes.new("ShaderNodeOutputMaterial")
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    kind = spec[0]
    if kind == "flat":
        bsdf.inputs["Color"].default_value = list(spec[1]) + [1.0]
        return m
    if kind == "glow":  # diffuse reflection plus a diffuse emitter of radiance spec[2]
        bsdf.inputs["Color"].default_value = list(spec[1]) + [1.0]
        emit, add = nodes.new("ShaderNodeEmission"), nodes.new("ShaderNodeAddShader")
        emit.inputs["Color"].default_value = list(spec[2]) + [1.0]
        emit.inputs["Strength"].default_value = 1.0
        links.new(bsdf.outputs["BSDF"], add.inputs[0])
        links.new(emit.outputs["Emission"], add.inputs[1])
        links.new(add.outputs["Shader"], out.inputs["Surface"])
        return m
    coords = nodes.new("ShaderNodeTexCoord")
    if kind == "checker":
        tex = nodes.new("ShaderNodeTexChecker")
        tex.inputs["Scale"].default_value = 4.0 if name in ("rug", "poster") else 3.0
    else:  # planks
        tex = nodes.new("ShaderNodeTexBrick")
        tex.inputs["Mortar"].default_value = (0.1, 0.06, 0.035, 1)
        tex.inputs["Scale"].default_value = 1.0
        tex.inputs["Mortar Size"].default_value = 0.004
        tex.inputs["Brick Width"].default_value = 0.9
        tex.inputs["Row Height"].default_value = 0.145
    tex.inputs["Color1"].default_value = list(spec[1]) + [1.0]
    tex.inputs["Color2"].default_value = list(spec[2]) + [1.0]
    links.new(coords.outputs["Object"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    return m


for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
for name, (verts, faces) in parts.items():
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.data.materials.append(make_material(name, MATERIALS[name]))
    for poly in mesh.polygons:
        poly.use_smooth = name == "sphere"

# ---------------------------------------------------------------- lights
CENTRE = (0.0, 0.0, WALL_H / 2)
LAMPS = {
    "one-lamp": [("lamp", (0.5, 0.45, 2.45), 37.7, (1.0, 0.93, 0.82))],
    "heavy-texture": [("lamp", (0.5, 0.45, 2.45), 37.7, (1.0, 0.93, 0.82))],
    "dark-room": [("lamp", (-0.6, 0.2, 2.3), 30.0, (1.0, 0.9, 0.75))],
    "two-lamps": [("warm", (0.8, 0.7, 2.4), 140.0 / 4, (1.0, 0.8, 0.6)),
                  ("cool", (-0.9, -0.2, 2.2), 70.0 / 4, (0.6, 0.75, 1.0))],
    "lamp-and-sun": [("lamp", (-0.6, 0.6, 2.35), 25.0, (1.0, 0.9, 0.78))],
    "frosted-window": [],
    "glazed-window": [],
    "clear-window": [],
    "bulb-seen": [("bulb", (-0.5, 0.5, 1.35), 30.0, (1.0, 0.9, 0.75))],
}[KIND]
BULB_SEEN = KIND == "bulb-seen"
SUN = (mathutils.Vector((0.35, -0.75, 0.55)).normalized(), 2.0, 0.53) if KIND == "lamp-and-sun" else None
truth_lights = []
for name, pos, power, colour in LAMPS:
    data = bpy.data.lights.new(name, type="POINT")
    data.energy = power
    data.color = colour
    data.shadow_soft_size = 0.05
    obj = bpy.data.objects.new(name, data)
    obj.location = pos
    obj.visible_camera = BULB_SEEN
    bpy.context.scene.collection.objects.link(obj)
    intensity = [power * c / (4 * math.pi) for c in colour]  # W/sr: Cycles' point light
    d = math.dist(pos, CENTRE)
    truth_lights.append({"name": name, "type": "point", "position": list(pos), "radius": 0.05, "power_W": power,
                         "color": list(colour), "radiant_intensity_rgb_W_per_sr": intensity,
                         "intensity_image_units": intensity, "distance_from_bbox_centre": d})
if SUN:
    direction, irradiance, angle = SUN
    data = bpy.data.lights.new("sun", type="SUN")
    data.energy = irradiance
    data.angle = math.radians(angle)
    obj = bpy.data.objects.new("sun", data)
    obj.rotation_euler = direction.to_track_quat("Z", "Y").to_euler()  # shines along its -z
    bpy.context.scene.collection.objects.link(obj)
    truth_lights.append({"name": "sun", "type": "sun", "direction": list(direction), "rgb": [irradiance] * 3,
                         "irradiance_rgb_W_per_m2": [irradiance] * 3, "angular_diameter_deg": angle})
SKY = (0.0, 0.0, 0.0) if KIND == "dark-room" else (0.0176, 0.0199, 0.0234)
world = bpy.data.worlds.new("sky")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = list(SKY) + [1]
world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
GLAZED = KIND == "glazed-window"  # (the glass in the depth frames and gt_mesh.ply)
WINDOW = KIND in ("glazed-window", "clear-window")  # (the hole and the cone of world behind it)
CONE_AXIS, CONE_DEG, CONE_RADIANCE = mathutils.Vector((0.0, 1.0, 0.45)).normalized(), 30.0, 8.0
if WINDOW:  # CONE_RADIANCE (white) within CONE_DEG of CONE_AXIS, SKY elsewhere
    nodes, links = world.node_tree.nodes, world.node_tree.links
    coord, dot, inside = nodes.new("ShaderNodeTexCoord"), nodes.new("ShaderNodeVectorMath"), nodes.new("ShaderNodeMath")
    mix = nodes.new("ShaderNodeMixRGB")
    dot.operation = "DOT_PRODUCT"
    dot.inputs[1].default_value = tuple(CONE_AXIS)
    inside.operation = "GREATER_THAN"
    inside.inputs[1].default_value = math.cos(math.radians(CONE_DEG))
    links.new(coord.outputs["Generated"], dot.inputs[0])
    links.new(dot.outputs["Value"], inside.inputs[0])
    links.new(inside.outputs["Value"], mix.inputs["Fac"])
    mix.inputs["Color1"].default_value = list(SKY) + [1]
    mix.inputs["Color2"].default_value = [CONE_RADIANCE] * 3 + [1]
    links.new(mix.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
bpy.context.scene.world = world

# ---------------------------------------------------------------- render settings
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = SPP
scene.cycles.use_adaptive_sampling = False
scene.cycles.use_denoising = False
scene.cycles.max_bounces = 8
scene.cycles.diffuse_bounces = 4
scene.cycles.glossy_bounces = 0
scene.cycles.transmission_bounces = 0
scene.cycles.sample_clamp_direct = 0.0
scene.cycles.sample_clamp_indirect = 0.0
scene.cycles.light_sampling_threshold = 0.0
scene.cycles.pixel_filter_type = "BOX"
scene.cycles.filter_width = 1.0
scene.render.film_transparent = False
scene.render.dither_intensity = 0.0  # (8-bit frames exactly the sRGB curve of the radiance)
scene.render.resolution_x, scene.render.resolution_y = W, H
scene.render.resolution_percentage = 100
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.view_settings.exposure = 0.0
scene.view_settings.gamma = 1.0
layer = scene.view_layers[0]
layer.use_pass_z = True
layer.use_pass_diffuse_color = True
scene.use_nodes = True
tree = scene.node_tree
tree.nodes.clear()
rl = tree.nodes.new("CompositorNodeRLayers")
composite = tree.nodes.new("CompositorNodeComposite")
tree.links.new(rl.outputs["Image"], composite.inputs["Image"])
# The passes as float EXRs beside the composite (a Viewer node is not filled without a UI).
PASS_DIR = os.path.join(OUT, ".passes")
passes = tree.nodes.new("CompositorNodeOutputFile")
passes.base_path = PASS_DIR
passes.format.file_format = "OPEN_EXR"
passes.format.color_depth = "32"
passes.format.color_mode = "RGB"
passes.file_slots.clear()
for name in ("Depth", "DiffCol"):
    passes.file_slots.new(name)
    tree.links.new(rl.outputs[name], passes.inputs[name])
cam_data = bpy.data.cameras.new("cam")
cam_data.sensor_fit = "HORIZONTAL"
cam_data.sensor_width = 36.0
cam_data.lens = FOCAL / W * cam_data.sensor_width
cam_data.clip_start = 0.05
cam = bpy.data.objects.new("cam", cam_data)
scene.collection.objects.link(cam)
scene.camera = cam


def look(eye, target, roll_deg=0.0):
    eye, target = mathutils.Vector(eye), mathutils.Vector(target)
    q = (target - eye).to_track_quat("-Z", "Y")
    q = q @ mathutils.Quaternion((0, 0, 1), math.radians(roll_deg))
    cam.location = eye
    cam.rotation_euler = q.to_euler()
    bpy.context.view_layer.update()
    m = cam.matrix_world
    R = m.to_3x3() @ mathutils.Matrix(((1, 0, 0), (0, -1, 0), (0, 0, -1)))  # OpenCV axes
    return [[R[r][0], R[r][1], R[r][2], m[r][3]] for r in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def render_passes():
    """Renders (the composite to scene.render.filepath) and returns the Depth and DiffCol
    passes (H x W x 4 each, top row first)."""
    bpy.ops.render.render(write_still=True)
    out = {}
    for name in ("Depth", "DiffCol"):
        path = os.path.join(PASS_DIR, "%s%04d.exr" % (name, scene.frame_current))
        img = bpy.data.images.load(path)
        a = np.array(img.pixels[:], dtype=np.float32).reshape(img.size[1], img.size[0], 4)
        bpy.data.images.remove(img)
        os.remove(path)
        out[name] = a[::-1]
    return out


def write_png(path, array, bits):
    """A grey (2-D) or RGB (3-D) PNG of 8 or 16 bits, top row first (zlib; no PIL)."""
    h, w = array.shape[:2]
    channels = 1 if array.ndim == 2 else array.shape[2]
    dtype = ">u2" if bits == 16 else "u1"
    rows = array.astype(dtype).reshape(h, w * channels)
    raw = b"".join(b"\x00" + rows[y].tobytes() for y in range(h))
    colour_type = 0 if channels == 1 else 2

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bits, colour_type, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def write_exr(path, rgb):
    img = bpy.data.images.new("out", rgb.shape[1], rgb.shape[0], alpha=True, float_buffer=True)
    rgba = np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,), np.float32)], axis=2)[::-1]
    img.pixels = rgba.ravel()
    img.filepath_raw = path
    img.file_format = "OPEN_EXR"
    img.save()
    bpy.data.images.remove(img)


def kinect_depth(z):
    """Planar depth (m, huge where nothing) as a Kinect gives it: millimetres with noise."""
    valid = (z > 0.45) & (z < 4.5)
    noisy = z + rng.normal(0.0, 1.0, z.shape) * 0.0015 * z * z
    mm = np.where(valid, np.round(noisy * 1000.0), 0)
    mm[rng.random(z.shape) < 0.015] = 0
    zz = np.where(valid, z, 0)
    edge = np.zeros(z.shape, bool)
    for dy, dx in ((0, 1), (1, 0), (0, -1), (-1, 0)):
        n = np.roll(np.roll(zz, dy, 0), dx, 1)
        edge |= (np.abs(n - zz) > np.maximum(0.04, 0.04 * zz)) | (n == 0)
    mm[edge & (rng.random(z.shape) < 0.6)] = 0
    return np.clip(mm, 0, 65535).astype(np.uint16)


def glass_depth(z, wfc):
    """glazed-window: the planar depth z with the glass in the back wall's hole where a ray
    meets it before the surface behind (a depth camera that returned depth on the glass)."""
    if not GLAZED:
        return z
    R = np.array([row[:3] for row in wfc[:3]])
    t = np.array([row[3] for row in wfc[:3]])
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    rays = np.stack([(u - (W - 1) / 2) / FOCAL, (v - (H - 1) / 2) / FOCAL, np.ones_like(u)], axis=2)  # planar z = 1
    world_rays = rays @ R.T
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (HALF - t[1]) / world_rays[:, :, 1]  # the plane y = HALF, at planar depth s
    x, zz = t[0] + s * world_rays[:, :, 0], t[2] + s * world_rays[:, :, 2]
    on = (s > 0) & (x > PANE[0]) & (x < PANE[1]) & (zz > PANE[2]) & (zz < PANE[3]) & (s < z)
    return np.where(on, s, z).astype(z.dtype)


def bulb_pixels(z, wfc):
    """The pixels whose ray passes within a lamp's radius of its centre before the surface
    behind (where the camera sees the bulb; none unless bulb-seen)."""
    seen = np.zeros(z.shape, bool)
    if not BULB_SEEN:
        return seen
    R = np.array([row[:3] for row in wfc[:3]])
    t = np.array([row[3] for row in wfc[:3]])
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    rays = np.stack([(u - (W - 1) / 2) / FOCAL, (v - (H - 1) / 2) / FOCAL, np.ones_like(u)], axis=2)
    rays /= np.linalg.norm(rays, axis=2, keepdims=True)
    for _, pos, _, _ in LAMPS:
        p = R.T @ (np.array(pos) - t)  # the lamp in the camera's frame
        along = rays @ p
        miss = np.linalg.norm(p[None, None, :] - along[:, :, None] * rays, axis=2)
        seen |= (along > 0) & (miss < 0.05) & (p[2] < z)
    return seen


# ---------------------------------------------------------------- the scan
os.makedirs(os.path.join(OUT, "color"), exist_ok=True)
os.makedirs(os.path.join(OUT, "depth"), exist_ok=True)
os.makedirs(os.path.join(OUT, "holdout"), exist_ok=True)
scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.color_depth = "8"
log = []
for k in range(FRAMES):
    t = k / max(1, FRAMES - 1)
    az = math.radians(-122 + 64 * t)
    eye = (1.95 * math.cos(az), 0.25 + 1.95 * math.sin(az), 1.48 + 0.17 * math.sin(2 * math.pi * t * 1.3))
    target = (0.25 * math.sin(2 * math.pi * t), 0.5 + 0.2 * math.cos(2 * math.pi * t), 0.75)
    wfc = look(eye, target, roll_deg=4.2 * math.sin(2 * math.pi * t * 2.1))
    scene.render.filepath = os.path.join(OUT, "color", "%05d.png" % k)
    scene.cycles.seed = SEED * 1000 + k
    z = glass_depth(render_passes()["Depth"][:, :, 0], wfc)
    write_png(os.path.join(OUT, "depth", "%05d.png" % k), np.where(bulb_pixels(z, wfc), 0, kinect_depth(z)), 16)
    log.append("%d %d %d" % (k, k, k + 1))
    log.extend(" ".join("%.10f" % v for v in row) for row in wfc)
    print("frame %d of %d" % (k + 1, FRAMES), flush=True)
with open(os.path.join(OUT, "trajectory.log"), "w") as f:
    f.write("\n".join(log) + "\n")
with open(os.path.join(OUT, "intrinsics.json"), "w") as f:
    json.dump({"width": W, "height": H, "fx": FOCAL, "fy": FOCAL, "cx": (W - 1) / 2, "cy": (H - 1) / 2}, f, indent=2)

# ---------------------------------------------------------------- the held-out view
wfc = look((1.25, 0.05, 1.6), (-1.0, 0.3, 0.45))
scene.cycles.samples = 8 * SPP
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.color_depth = "32"
scene.render.filepath = os.path.join(OUT, "holdout", "holdout.exr")
scene.cycles.seed = SEED * 1000 + 999
held = render_passes()
z = held["Depth"][:, :, 0]
# (a bulb in view is not the room, and no image of the estimate shows it: left out with a
# margin of 2 pixels, which the box filter's partly covered pixels are within)
bulb = bulb_pixels(z, wfc)
for _ in range(2):
    bulb = bulb | np.roll(bulb, 1, 0) | np.roll(bulb, -1, 0) | np.roll(bulb, 1, 1) | np.roll(bulb, -1, 1)
write_png(os.path.join(OUT, "holdout", "mask.png"), np.where((z < 100) & ~bulb, 255, 0).astype(np.uint8), 8)
write_exr(os.path.join(OUT, "holdout", "depth.exr"), np.repeat(z[:, :, None], 3, axis=2))
write_exr(os.path.join(OUT, "holdout", "albedo.exr"), held["DiffCol"][:, :, :3])
os.rmdir(PASS_DIR)
with open(os.path.join(OUT, "holdout", "holdout.json"), "w") as f:
    json.dump({"image": "holdout.exr", "mask": "mask.png", "albedo": "albedo.exr", "depth": "depth.exr", "width": W,
               "height": H, "fx": FOCAL, "fy": FOCAL, "cx": (W - 1) / 2, "cy": (H - 1) / 2, "world_from_camera": wfc,
               "spp": 8 * SPP}, f, indent=2)

# ---------------------------------------------------------------- gt_mesh.ply and truth.json
verts, faces = [], []
if GLAZED:  # the glass, as the depth camera saw it
    add_part("glass", [(PANE[0], HALF, PANE[2]), (PANE[0], HALF, PANE[3]), (PANE[1], HALF, PANE[3]),
                       (PANE[1], HALF, PANE[2])], [(0, 1, 2, 3)])
for name, (v, f) in parts.items():
    base = len(verts)
    verts.extend(v)
    faces.extend(tuple(base + i for i in face) for face in f)
with open(os.path.join(OUT, "gt_mesh.ply"), "w") as f:
    f.write("ply\nformat ascii 1.0\ncomment made by scripts/make-cycles-scan.py\n")
    f.write("element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % len(verts))
    f.write("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(faces))
    f.writelines("%g %g %g\n" % v for v in verts)
    f.writelines("%d %s\n" % (len(face), " ".join(map(str, face))) for face in faces)
truth = {
    "scene": "scan_" + KIND.replace("-", "_"), "blender_version": bpy.app.version_string,
    "scene_bbox": {"min": [-HALF, -HALF, 0.0], "max": [HALF, HALF, WALL_H], "centre": list(CENTRE)},
    "lights": truth_lights,
    "emitters": [] if "pane" not in parts else [
        {"name": "pane", "corners": [list(p) for p in parts["pane"][0]], "normal": [0, -1, 0],
         "radiance": list(PANE_RADIANCE), "area": (PANE[1] - PANE[0]) * (PANE[3] - PANE[2]),
         "power": [math.pi * r * (PANE[1] - PANE[0]) * (PANE[3] - PANE[2]) for r in PANE_RADIANCE]}],
    "world": {"type": "uniform", "radiance_rgb": list(SKY)} if not WINDOW else
             {"type": "cone", "radiance_rgb": list(SKY), "cone_radiance_rgb": [CONE_RADIANCE] * 3,
              "cone_axis": list(CONE_AXIS), "cone_half_angle_deg": CONE_DEG},
    "openings": [] if not WINDOW else [
        {"name": "glass", "area": (PANE[1] - PANE[0]) * (PANE[3] - PANE[2]),
         "corners": [[PANE[0], HALF, PANE[2]], [PANE[0], HALF, PANE[3]], [PANE[1], HALF, PANE[3]], [PANE[1], HALF, PANE[2]]],
         "note": "clear glass: not rendered; " + ("the depth frames and gt_mesh.ply have it" if GLAZED else
                                                  "no depth on it: a hole in the scan")}],
    "camera": {"width": W, "height": H, "fx": FOCAL, "fy": FOCAL, "cx": (W - 1) / 2, "cy": (H - 1) / 2,
               "convention": "OpenCV; trajectory.log = world_from_camera, world z up, metres"},
    "trajectory": {"frames": FRAMES, "arc_centre_xy": [0.0, 0.25], "arc_radius_m": 1.95,
                   "arc_azimuth_deg": [-122.0, -58.0], "step_m": 1.95 * math.radians(64) / max(1, FRAMES - 1)},
    "noise": {"depth_sigma_m": "0.0015 z^2", "quantisation_mm": 1, "range_m": [0.45, 4.5], "dropout": 0.015,
              "edge_holes": "a pixel with a 4-neighbour over max(4 cm, 4 %) away or without depth: 0 with p 0.6",
              "bulb": "0 where a ray passes within the lamp's radius of its centre" if BULB_SEEN else "not seen"},
    "materials": {name: {"kind": spec[0], "albedo_linear": [list(c) for c in spec[1:2 if spec[0] == "glow" else None]]}
                  for name, spec in MATERIALS.items() if name in parts},
    "render": {"engine": "CYCLES", "samples_per_pixel": SPP, "holdout_spp": 8 * SPP, "max_bounces": 8,
               "diffuse_bounces": 4, "pixel_filter": "BOX", "view_transform": "Standard", "denoising": False,
               "seed": SEED},
    "exposure": {"image_units_per_cycles_radiance": 1.0,
                 "encoding": "8-bit PNG = round(255 * srgb_oetf(clip(radiance, 0, 1)))"},
    "made_with": "scripts/make-cycles-scan.py " + " ".join(argv[1:]),
}
with open(os.path.join(OUT, "truth.json"), "w") as f:
    json.dump(truth, f, indent=2)
print("wrote", OUT)
