# Renders tests/data/cycles/interreflection with Blender Cycles: independent truth for the
# path tracer's multi-bounce radiometry. A bright open box (albedo ~0.79: light bounces
# many times between the walls) with a coloured block inside, lit by a uniform white
# environment of radiance 1, seen by one 64x48 pinhole camera. Writes a scene bundle that
# lightprobe reads (mesh.ply, scene.json, view0.exr) and truth.json with the render settings.
#
#   blender -b -noaudio --factory-startup --python scripts/make-cycles-interreflection.py -- OUT_DIR [SPP]
#
# (apt-get install blender; Debian 12 has 3.4.1.) The mesh's colours are stored as sRGB
# bytes, so the Diffuse BSDF gets exactly the linear albedo lightprobe decodes from them.
# Every face has vertices of its own (flat shading in both renderers).
import json
import math
import os
import sys

import bpy
import mathutils

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
out_dir = os.path.abspath(argv[0] if argv else "tests/data/cycles/interreflection")
spp = int(argv[1]) if len(argv) > 1 else 4096
os.makedirs(out_dir, exist_ok=True)
W, H = 64, 48


def srgb_to_linear(c):
    c = c / 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


# Quads (4 corners, counter-clockwise seen from the side light comes from) and their sRGB colour.
WALL = (230, 230, 230)
BLOCK = (220, 150, 80)
quads = []


def quad(a, b, c, d, colour):
    quads.append(([a, b, c, d], colour))


# The open box: floor z = 0 over [-1, 1]^2, walls at x = -1, y = -1 and x = +1, 1 m high;
# open at y = +1 and at the top.
quad((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), WALL)
quad((-1, -1, 0), (-1, 1, 0), (-1, 1, 1), (-1, -1, 1), WALL)
quad((-1, -1, 0), (-1, -1, 1), (1, -1, 1), (1, -1, 0), WALL)
quad((1, -1, 0), (1, -1, 1), (1, 1, 1), (1, 1, 0), WALL)
# A block 0.6 x 0.6 x 0.5 inside (five faces; it stands on the floor).
x0, x1, y0, y1, z1 = -0.5, 0.1, -0.6, 0.0, 0.5
quad((x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1), BLOCK)
quad((x0, y0, 0), (x1, y0, 0), (x1, y0, z1), (x0, y0, z1), BLOCK)
quad((x1, y0, 0), (x1, y1, 0), (x1, y1, z1), (x1, y0, z1), BLOCK)
quad((x1, y1, 0), (x0, y1, 0), (x0, y1, z1), (x1, y1, z1), BLOCK)
quad((x0, y1, 0), (x0, y0, 0), (x0, y0, z1), (x0, y1, z1), BLOCK)

# --- the scene bundle's mesh (ASCII PLY, sRGB uchar colours) ---
with open(os.path.join(out_dir, "mesh.ply"), "w") as f:
    f.write("ply\nformat ascii 1.0\ncomment made by scripts/make-cycles-interreflection.py\n")
    f.write("element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % (4 * len(quads)))
    f.write("property uchar red\nproperty uchar green\nproperty uchar blue\n")
    f.write("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(quads))
    for corners, c in quads:
        for p in corners:
            f.write("%g %g %g %d %d %d\n" % (p[0], p[1], p[2], c[0], c[1], c[2]))
    for k in range(len(quads)):
        f.write("4 %d %d %d %d\n" % (4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3))

# --- the same in Blender ---
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
materials = {}
for colour in (WALL, BLOCK):
    m = bpy.data.materials.new("albedo_%d_%d_%d" % colour)
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = [srgb_to_linear(c) for c in colour] + [1.0]
    bsdf.inputs["Roughness"].default_value = 0.0  # Lambert
    out = nodes.new("ShaderNodeOutputMaterial")
    m.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    materials[colour] = m
verts, faces, face_colour = [], [], []
for corners, c in quads:
    faces.append([len(verts) + i for i in range(4)])
    verts.extend(corners)
    face_colour.append(c)
mesh = bpy.data.meshes.new("box")
mesh.from_pydata(verts, [], faces)
mesh.update()
obj = bpy.data.objects.new("box", mesh)
bpy.context.scene.collection.objects.link(obj)
order = [WALL, BLOCK]
for c in order:
    obj.data.materials.append(materials[c])
for poly, c in zip(mesh.polygons, face_colour):
    poly.material_index = order.index(c)
    poly.use_smooth = False

world = bpy.data.worlds.new("white")
world.use_nodes = True
bg = world.node_tree.nodes["Background"]
bg.inputs["Color"].default_value = (1, 1, 1, 1)
bg.inputs["Strength"].default_value = 1.0
bpy.context.scene.world = world

# Camera: OpenCV convention in scene.json (x right, y down, z forward), Blender's looks down
# its -z with +y up. Principal point at the image centre: (W - 1) / 2 with pixel centres at
# integers.
eye = mathutils.Vector((1.9, 2.3, 1.6))
target = mathutils.Vector((-0.2, -0.3, 0.3))
cam_data = bpy.data.cameras.new("cam")
cam_data.sensor_fit = "HORIZONTAL"
cam_data.sensor_width = 36.0
hfov = math.radians(60.0)
cam_data.lens = 0.5 * cam_data.sensor_width / math.tan(0.5 * hfov)
cam = bpy.data.objects.new("cam", cam_data)
cam.location = eye
cam.rotation_euler = (target - eye).to_track_quat("-Z", "Y").to_euler()
bpy.context.scene.collection.objects.link(cam)
bpy.context.scene.camera = cam
bpy.context.view_layer.update()

scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = spp
scene.cycles.use_adaptive_sampling = False
scene.cycles.use_denoising = False
scene.cycles.seed = 11
scene.cycles.max_bounces = 64
scene.cycles.diffuse_bounces = 64
scene.cycles.glossy_bounces = 0
scene.cycles.transmission_bounces = 0
scene.cycles.transparent_max_bounces = 0
scene.cycles.sample_clamp_direct = 0.0
scene.cycles.sample_clamp_indirect = 0.0
scene.cycles.light_sampling_threshold = 0.0
scene.cycles.pixel_filter_type = "BOX"
scene.cycles.filter_width = 1.0
scene.cycles.caustics_reflective = True
scene.cycles.caustics_refractive = True
scene.cycles.blur_glossy = 0.0
scene.render.film_transparent = False
scene.render.resolution_x = W
scene.render.resolution_y = H
scene.render.resolution_percentage = 100
scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.view_settings.exposure = 0.0
scene.view_settings.gamma = 1.0
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.exr_codec = "ZIP"
scene.render.filepath = os.path.join(out_dir, "view0.exr")
bpy.ops.render.render(write_still=True)

# --- scene.json and truth.json ---
m = cam.matrix_world
R = m.to_3x3() @ mathutils.Matrix(((1, 0, 0), (0, -1, 0), (0, 0, -1)))  # OpenCV axes
wfc = [[R[r][0], R[r][1], R[r][2], m[r][3]] for r in range(3)] + [[0, 0, 0, 1]]
fx = cam_data.lens / cam_data.sensor_width * W
view = {"image": "view0.exr", "width": W, "height": H, "fx": fx, "fy": fx, "cx": (W - 1) / 2, "cy": (H - 1) / 2,
        "world_from_camera": wfc}
with open(os.path.join(out_dir, "scene.json"), "w") as f:
    json.dump({"mesh": "mesh.ply", "up": [0, 0, 1], "views": [view]}, f, indent=2)
with open(os.path.join(out_dir, "truth.json"), "w") as f:
    json.dump({"scene": "interreflection", "blender_version": bpy.app.version_string, "spp": spp,
               "lights": [], "world": {"type": "uniform", "radiance": [1, 1, 1]},
               "render": {"engine": "CYCLES", "max_bounces": 64, "diffuse_bounces": 64, "pixel_filter": "BOX",
                          "filter_width_px": 1.0, "view_transform": "Standard", "denoising": False,
                          "adaptive_sampling": False, "seed": 11},
               "albedo_srgb": {"walls": WALL, "block": BLOCK},
               "albedo_linear": {"walls": [srgb_to_linear(c) for c in WALL],
                                 "block": [srgb_to_linear(c) for c in BLOCK]}}, f, indent=2)
print("wrote", out_dir)
