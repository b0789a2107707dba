# Renders tests/data/cycles/sun with Blender Cycles: independent truth for directional lights
# (issue 21). A room corner (a 3 x 3 m floor and two 1.6 m walls, light grey) with a box and
# a tall block on the floor, lit by a sun lamp of 0.53 degrees (Blender's "Sun", its
# strength the irradiance in W/m^2 on a surface facing it) and a uniform sky whose
# irradiance on an open floor is 1/1000 of the sun's, seen by one 160x120 pinhole camera
# (and a held-out second view from elsewhere). Writes scene bundles that lightprobe reads
# (OUT_DIR: view 0, OUT_DIR_holdout: view 1; mesh.ply, scene.json, view0.exr, truth.json
# with the render settings and the sun's direction and irradiance).
# The same corner under extended light (issue 42; KIND, default sun):
#   sky       a uniform white sky whose irradiance on an open floor is 1, nothing else;
#   lamp-sky  a 5 cm lamp (Blender's point light, radiant intensity power / 4 pi W/sr) about
#             1.4 m from the scene's centre (1.5, 1.5, 0.5) and a uniform sky whose
#             irradiance on an open floor is 1/20 of the lamp's at that centre;
#   two-lamps a warm lamp (140 W, 1.73 m from the centre) and a cool one half as strong (70 W,
#             1.65 m) on either side of the corner, 5 cm each, no sky (issue 42's valley);
#   glow      a frosted window: a 0.8 x 0.8 m pane in the wall x = 0 that glows (a diffuse
#             emitter of radiance GLOW_RADIANCE, reflecting like the wall too), no other
#             light and no sky (issue 43: a glowing surface the cameras see);
#   screen    a screen: a dark 0.8 x 0.45 m panel in the wall y = 0 glowing bluish, no other
#             light and no sky;
#   open-window  an open window: a 0.8 x 0.8 m hole in the wall x = 0 and a world that is
#             bright (radiance WINDOW_SKY) only behind that wall (directions with x < -0.3),
#             dark elsewhere, so the room is lit through the hole; each view's mask0.png keeps
#             the pixels whose ray hits the room (a scan has no depth through a window);
#   glazed-window  the open window's room, its world bright (radiance 4) only in a cone of
#             37 degrees about -x, whose light comes through the hole as a beam onto the floor,
#             rendered without glass (clear glass); the
#             bundle's mesh has a pane in the hole (a depth camera that saw the glass), and
#             each view's mask0.png keeps the pixels whose ray hits that mesh (the pane's
#             included): the data must choose the opening (issue 43);
#   shade     a lamp in a lamp shade: a 16-sided open band (radius 0.15 m, 0.25 m tall, a
#             Translucent BSDF of colour SHADE_TRANSMISSION, reflecting nothing) around a
#             40 W warm point light hidden from the camera; the shade glows with the light it
#             lets through (its power SHADE_TRANSMISSION x the lamp's intensity x the solid
#             angle the band subtends), the rest leaves through its open top and bottom; no sky;
#   hdr       Poly Haven's studio_small_03 (assets/hdri, CC0) as the world, as lightprobe
#             reads an equirect map (`lightprobe render --envmap` of the same file is its truth);
#             each view's mask0.png keeps the pixels whose ray hits the room.
#
#   blender -b -noaudio --factory-startup --python scripts/make-cycles-sun.py -- OUT_DIR [SPP] [KIND]
#
# (apt-get install blender; Debian 12 has 3.4.1.) Colours as in make-cycles-interreflection.py.
import json
import math
import os
import sys

import bpy
import mathutils

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
out_dir = os.path.abspath(argv[0] if argv else "tests/data/cycles/sun")
spp = int(argv[1]) if len(argv) > 1 else 1024
KIND = argv[2] if len(argv) > 2 else "sun"
KINDS = ("sun", "sky", "lamp-sky", "two-lamps", "hdr", "glow", "screen", "shade", "open-window", "glazed-window")
if KIND not in KINDS:
    raise SystemExit("KIND is one of %s, not %s" % (", ".join(KINDS), KIND))
HDR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "assets", "hdri", "studio_small_03_1k.hdr")
W, H = 160, 120
SUN_DIRECTION = mathutils.Vector((0.55, 0.35, 0.76)).normalized()  # towards the sun
SUN_IRRADIANCE = 3.0  # W/m^2 on a surface facing it
SUN_ANGLE_DEG = 0.53  # the sun's angular diameter
SKY_RADIANCE = SUN_IRRADIANCE / 1000 / math.pi  # an open floor receives pi x this
CENTRE = mathutils.Vector((1.5, 1.5, 0.5))  # lamp-sky: distances and the lamp's irradiance from here
LAMP_POSITION = mathutils.Vector((2.1, 1.2, 1.75))
LAMP_POWER = 60.0  # W
LAMP_RADIUS = 0.05
LAMP_INTENSITY = LAMP_POWER / (4 * math.pi)  # W/sr
if KIND == "sky":
    SKY_RADIANCE = 1.0 / math.pi
elif KIND == "lamp-sky":
    SKY_RADIANCE = LAMP_INTENSITY / (LAMP_POSITION - CENTRE).length_squared / 20 / math.pi
elif KIND in ("two-lamps", "glow", "screen", "shade", "open-window", "glazed-window"):
    SKY_RADIANCE = 0.0
WINDOW_SKY, WINDOW_SKY_X = 2.0, -0.3  # open-window: the world's radiance where direction.x < WINDOW_SKY_X
OPENING = KIND in ("open-window", "glazed-window")  # the frosted window's place in the wall x = 0, open
if KIND == "glazed-window":  # a narrower bright sky behind the wall (a cone of 37 degrees about -x)
    WINDOW_SKY, WINDOW_SKY_X = 4.0, -0.8
# glow, screen: the pane's wall (the axis it lies across, 0 = x, 1 = y), its ranges along the
# wall and up, its albedo (sRGB) and the radiance it emits (W/(m^2 sr), linear RGB).
PANES = {"glow": (0, (1.2, 2.0), (0.5, 1.3), (200, 200, 200), (3.0, 2.7, 2.25)),
         "screen": (1, (1.7, 2.5), (0.55, 1.0), (20, 20, 24), (1.0, 1.3, 1.8))}
# shade: the band's axis (x, y), radius, bottom and top, sides, what its Translucent BSDF lets through.
SHADE_AXIS, SHADE_RADIUS, SHADE_Z, SHADE_SIDES = (2.35, 0.95), 0.15, (1.05, 1.30), 16
SHADE_TRANSMISSION = (0.7, 0.65, 0.55)
# (name, position, power in W, colour): the lamps of KIND lamp-sky and two-lamps.
LAMPS = {"lamp-sky": [("lamp", LAMP_POSITION, LAMP_POWER, (1.0, 1.0, 1.0))],
         "two-lamps": [("warm", mathutils.Vector((2.3, 1.0, 1.95)), 140.0, (1.0, 0.8, 0.6)),
                       ("cool", mathutils.Vector((0.6, 2.2, 1.7)), 70.0, (0.6, 0.8, 1.0))],
         "shade": [("bulb", mathutils.Vector((SHADE_AXIS[0], SHADE_AXIS[1], sum(SHADE_Z) / 2)), 40.0,
                    (1.0, 0.85, 0.65))]}.get(KIND, [])


def srgb_to_linear(c):
    c = c / 255.0
    return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4


WALL = (200, 200, 200)
BOX = (200, 120, 70)
BLOCK = (90, 140, 200)
quads = []


def quad(a, b, c, d, colour):
    quads.append(([a, b, c, d], colour))


def box(x0, x1, y0, y1, z1, colour):
    quad((x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1), colour)
    quad((x0, y0, 0), (x1, y0, 0), (x1, y0, z1), (x0, y0, z1), colour)
    quad((x1, y0, 0), (x1, y1, 0), (x1, y1, z1), (x1, y0, z1), colour)
    quad((x1, y1, 0), (x0, y1, 0), (x0, y1, z1), (x1, y1, z1), colour)
    quad((x0, y1, 0), (x0, y0, 0), (x0, y0, z1), (x0, y1, z1), colour)


# The corner: floor z = 0 over [0, 3]^2, walls at x = 0 and y = 0, 1.6 m high; the sun comes
# from +x +y above, so both walls are lit and the objects cast shadows towards them.
def wall(axis, pane=None):
    """The wall across `axis` (0: x = 0, running along y; 1: y = 0, running along x), 1.6 m
    high, 3 m long; with `pane` ((u0, u1), (z0, z1), albedo), the wall around it and then
    the pane as its own quad, whose index is returned."""
    at = (lambda u, z: (0, u, z)) if axis == 0 else (lambda u, z: (u, 0, z))
    # (the winding the scenes rendered before had: y = 0's corners the other way round)
    quad = (lambda a, b, c, d, col: quads.append(([a, b, c, d], col))) if axis == 0 else \
        (lambda a, b, c, d, col: quads.append(([a, d, c, b], col)))
    if pane is None:
        quad(at(0, 0), at(3, 0), at(3, 1.6), at(0, 1.6), WALL)
        return -1
    (u0, u1), (z0, z1), albedo = pane
    quad(at(0, 0), at(3, 0), at(3, z0), at(0, z0), WALL)
    quad(at(0, z1), at(3, z1), at(3, 1.6), at(0, 1.6), WALL)
    quad(at(0, z0), at(u0, z0), at(u0, z1), at(0, z1), WALL)
    quad(at(u1, z0), at(3, z0), at(3, z1), at(u1, z1), WALL)
    if albedo is None:  # a hole
        return -1
    quad(at(u0, z0), at(u1, z0), at(u1, z1), at(u0, z1), albedo)
    return len(quads) - 1


# The floor, then the walls (the pane in its wall for glow and screen), then the shade's band.
quad((0, 0, 0), (3, 0, 0), (3, 3, 0), (0, 3, 0), WALL)
PANE_SPEC = PANES.get(KIND)
PANE = -1
for axis in (0, 1):
    on_this = PANE_SPEC is not None and PANE_SPEC[0] == axis
    if OPENING and axis == 0:  # the frosted window's place, open
        wall(axis, (PANES["glow"][1], PANES["glow"][2], None))
        continue
    k = wall(axis, (PANE_SPEC[1], PANE_SPEC[2], PANE_SPEC[3]) if on_this else None)
    PANE = k if on_this else PANE
SHADE = []  # the band's quads, each with its outward normal
if KIND == "shade":
    for i in range(SHADE_SIDES):
        a0, a1 = 2 * math.pi * i / SHADE_SIDES, 2 * math.pi * (i + 1) / SHADE_SIDES
        p0 = (SHADE_AXIS[0] + SHADE_RADIUS * math.cos(a0), SHADE_AXIS[1] + SHADE_RADIUS * math.sin(a0))
        p1 = (SHADE_AXIS[0] + SHADE_RADIUS * math.cos(a1), SHADE_AXIS[1] + SHADE_RADIUS * math.sin(a1))
        SHADE.append((len(quads), (math.cos((a0 + a1) / 2), math.sin((a0 + a1) / 2), 0.0)))
        quad((p0[0], p0[1], SHADE_Z[0]), (p1[0], p1[1], SHADE_Z[0]), (p1[0], p1[1], SHADE_Z[1]),
             (p0[0], p0[1], SHADE_Z[1]), (0, 0, 0))
box(0.9, 1.5, 0.8, 1.4, 0.5, BOX)
box(1.9, 2.2, 1.7, 2.0, 1.1, BLOCK)
# --- the scene bundle's mesh (ASCII PLY, sRGB uchar colours) ---
bundle_quads = list(quads)
if KIND == "glazed-window":  # the glass as the depth camera saw it: a pane in the hole (not rendered)
    (u0, u1), (z0, z1) = PANES["glow"][1], PANES["glow"][2]
    bundle_quads.append((((0, u0, z0), (0, u1, z0), (0, u1, z1), (0, u0, z1)), WALL))
os.makedirs(out_dir, exist_ok=True)
with open(os.path.join(out_dir, "mesh.ply"), "w") as f:
    f.write("ply\nformat ascii 1.0\ncomment made by scripts/make-cycles-sun.py\n")
    f.write("element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % (4 * len(bundle_quads)))
    f.write("property uchar red\nproperty uchar green\nproperty uchar blue\n")
    f.write("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(bundle_quads))
    for corners, c in bundle_quads:
        for p in corners:
            f.write("%g %g %g %d %d %d\n" % (p[0], p[1], p[2], c[0], c[1], c[2]))
    for k in range(len(bundle_quads)):
        f.write("4 %d %d %d %d\n" % (4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3))

# --- the same in Blender ---
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
materials = {}
for colour in (WALL, BOX, BLOCK):
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
mesh = bpy.data.meshes.new("corner")
mesh.from_pydata(verts, [], faces)
mesh.update()
obj = bpy.data.objects.new("corner", mesh)
bpy.context.scene.collection.objects.link(obj)
order = [WALL, BOX, BLOCK]
for c in order:
    obj.data.materials.append(materials[c])
if PANE >= 0:  # the pane: its diffuse reflection plus its own light
    m = bpy.data.materials.new("pane")
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    bsdf, emit, add = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeEmission"), nodes.new("ShaderNodeAddShader")
    bsdf.inputs["Color"].default_value = [srgb_to_linear(c) for c in PANE_SPEC[3]] + [1.0]
    bsdf.inputs["Roughness"].default_value = 0.0
    emit.inputs["Color"].default_value = list(PANE_SPEC[4]) + [1.0]
    emit.inputs["Strength"].default_value = 1.0  # radiance = colour x strength
    out = nodes.new("ShaderNodeOutputMaterial")
    m.node_tree.links.new(bsdf.outputs["BSDF"], add.inputs[0])
    m.node_tree.links.new(emit.outputs["Emission"], add.inputs[1])
    m.node_tree.links.new(add.outputs["Shader"], out.inputs["Surface"])
    obj.data.materials.append(m)
if SHADE:  # the shade: what reaches it passes through, diffusely, tinted; nothing reflected
    m = bpy.data.materials.new("shade")
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfTranslucent")
    bsdf.inputs["Color"].default_value = list(SHADE_TRANSMISSION) + [1.0]
    out = nodes.new("ShaderNodeOutputMaterial")
    m.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    obj.data.materials.append(m)
shade_quads = [k for k, _ in SHADE]
for k, (poly, c) in enumerate(zip(mesh.polygons, face_colour)):
    poly.material_index = len(order) if k in [PANE] + shade_quads else order.index(c)
    poly.use_smooth = False

world = bpy.data.worlds.new("sky")
world.use_nodes = True
bg = world.node_tree.nodes["Background"]
bg.inputs["Color"].default_value = (1, 1, 1, 1)
bg.inputs["Strength"].default_value = SKY_RADIANCE
if KIND == "hdr":
    # The HDR as lightprobe reads it (docs/formats.md: column x at azimuth (x + 0.5) / W * 2 pi
    # from +x towards +y, up = +z): Blender's equirect has u = 0.5 - atan2(y, x) / 2 pi, so x is mirrored.
    nodes, links = world.node_tree.nodes, world.node_tree.links
    coord, mapping, tex = nodes.new("ShaderNodeTexCoord"), nodes.new("ShaderNodeMapping"), nodes.new("ShaderNodeTexEnvironment")
    mapping.inputs["Scale"].default_value = (-1.0, 1.0, 1.0)
    tex.image = bpy.data.images.load(os.path.abspath(HDR))
    links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.0
if OPENING:  # WINDOW_SKY where the direction's x < WINDOW_SKY_X, else black
    nodes, links = world.node_tree.nodes, world.node_tree.links
    coord, split, below = nodes.new("ShaderNodeTexCoord"), nodes.new("ShaderNodeSeparateXYZ"), nodes.new("ShaderNodeMath")
    below.operation = "LESS_THAN"
    below.inputs[1].default_value = WINDOW_SKY_X
    links.new(coord.outputs["Generated"], split.inputs["Vector"])
    links.new(split.outputs["X"], below.inputs[0])
    links.new(below.outputs["Value"], bg.inputs["Strength"])
    bg.inputs["Color"].default_value = (WINDOW_SKY, WINDOW_SKY, WINDOW_SKY, 1)
bpy.context.scene.world = world
truth_lights = []
if KIND == "sun":
    sun_data = bpy.data.lights.new("sun", type="SUN")
    sun_data.energy = SUN_IRRADIANCE
    sun_data.angle = math.radians(SUN_ANGLE_DEG)
    sun = bpy.data.objects.new("sun", sun_data)
    sun.rotation_euler = SUN_DIRECTION.to_track_quat("Z", "Y").to_euler()  # a sun shines along its -z
    bpy.context.scene.collection.objects.link(sun)
    truth_lights.append({"type": "sun", "direction": list(SUN_DIRECTION), "rgb": [SUN_IRRADIANCE] * 3,
                         "irradiance_rgb_W_per_m2": [SUN_IRRADIANCE] * 3, "angular_diameter_deg": SUN_ANGLE_DEG})
for name, position, power, colour in LAMPS:
    lamp_data = bpy.data.lights.new(name, type="POINT")
    lamp_data.energy = power
    lamp_data.color = colour
    lamp_data.shadow_soft_size = LAMP_RADIUS
    lamp = bpy.data.objects.new(name, lamp_data)
    lamp.location = position
    lamp.visible_camera = False  # (the shade's bulb is not seen through its open top)
    bpy.context.scene.collection.objects.link(lamp)
    intensity = [power * c / (4 * math.pi) for c in colour]  # W/sr per channel
    truth_lights.append({"name": name, "type": "point", "blender_type": "POINT", "position": list(position),
                         "radius": LAMP_RADIUS, "color": list(colour), "power_W": power,
                         "radiant_intensity_rgb_W_per_sr": intensity, "intensity_image_units": intensity,
                         "distance_from_centre": (position - CENTRE).length})

def solid_angle(o, corners):
    """The solid angle of the planar polygon `corners` seen from `o` (its triangles by Van
    Oosterom and Strackee's formula)."""
    total = 0.0
    for i in range(1, len(corners) - 1):
        a, b, c = (mathutils.Vector(corners[0]) - o, mathutils.Vector(corners[i]) - o, mathutils.Vector(corners[i + 1]) - o)
        la, lb, lc = a.length, b.length, c.length
        total += abs(2 * math.atan2(a.dot(b.cross(c)), la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la))
    return total


truth_emitters = []
if PANE >= 0:
    area = (PANE_SPEC[1][1] - PANE_SPEC[1][0]) * (PANE_SPEC[2][1] - PANE_SPEC[2][0])
    truth_emitters = [{"name": KIND == "glow" and "pane" or "screen", "corners": [list(p) for p in quads[PANE][0]],
                       "normal": [1, 0, 0] if PANE_SPEC[0] == 0 else [0, 1, 0],
                       "radiance": list(PANE_SPEC[4]), "area": area,
                       "power": [math.pi * r * area for r in PANE_SPEC[4]]}]
if SHADE:
    # What the band lets through: its transmission x the bulb's intensity x the band's solid
    # angle from the bulb (the 5 cm bulb taken as a point), spread over its outside.
    bulb = LAMPS[0]
    intensity = [bulb[2] * c / (4 * math.pi) for c in bulb[3]]
    omega = sum(solid_angle(bulb[1], quads[k][0]) for k, _ in SHADE)
    power = [t * i * omega for t, i in zip(SHADE_TRANSMISSION, intensity)]
    area = sum((mathutils.Vector(quads[k][0][1]) - mathutils.Vector(quads[k][0][0])).length *
               (SHADE_Z[1] - SHADE_Z[0]) for k, _ in SHADE)
    truth_emitters = [{"name": "shade", "quads": [{"corners": [list(p) for p in quads[k][0]], "normal": list(n)}
                                                  for k, n in SHADE],
                       "solid_angle_sr": omega, "radiance": [p / (math.pi * area) for p in power], "area": area,
                       "power": power}]


def write_room_mask(path, eye, R, fx, width, height):
    """mask0.png: 255 where the pixel centre's ray (OpenCV camera, R its world-from-camera
    rotation) hits one of the bundle's quads (glazed-window: the pane too), else 0."""
    from mathutils.geometry import intersect_ray_tri
    tris = [(c[0], c[1], c[2]) for c, _ in bundle_quads] + [(c[0], c[2], c[3]) for c, _ in bundle_quads]
    tris = [tuple(mathutils.Vector(p) for p in t) for t in tris]
    img = bpy.data.images.new("mask", width, height, alpha=False)
    pixels = [0.0] * (4 * width * height)
    for v in range(height):
        for u in range(width):
            d = R @ mathutils.Vector(((u - (width - 1) / 2) / fx, (v - (height - 1) / 2) / fx, 1.0))
            hit = any(intersect_ray_tri(a, b, c, d, eye, True) is not None for a, b, c in tris)
            i = 4 * ((height - 1 - v) * width + u)  # Blender's rows run bottom up
            pixels[i:i + 4] = [1.0 if hit else 0.0] * 3 + [1.0]
    img.pixels = pixels
    img.filepath_raw = path
    img.file_format = "PNG"
    img.save()


# Cameras: OpenCV convention in scene.json (x right, y down, z forward), Blender's looks down
# its -z with +y up. Principal point at the image centre: (W - 1) / 2 with pixel centres at
# integers. View 0 is fitted, view 1 held out.
VIEWS = [((4.2, 3.6, 2.2), (1.0, 1.0, 0.35)), ((3.4, 0.9, 1.9), (0.8, 1.6, 0.4))]
if KIND == "shade":  # a second fitted view from between the walls and the shade: its far side, as a scan would see it
    VIEWS.append(((0.9, 0.35, 1.7), (2.6, 1.15, 1.0)))
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
cam_data = bpy.data.cameras.new("cam")
cam_data.sensor_fit = "HORIZONTAL"
cam_data.sensor_width = 36.0
hfov = math.radians(60.0)
cam_data.lens = 0.5 * cam_data.sensor_width / math.tan(0.5 * hfov)
cam = bpy.data.objects.new("cam", cam_data)
bpy.context.scene.collection.objects.link(cam)
scene.camera = cam
truth = {"scene": "cycles-" + KIND, "blender_version": bpy.app.version_string, "spp": spp,
         "lights": truth_lights,
         "emitters": truth_emitters,
         "world": {"type": "uniform", "radiance": [SKY_RADIANCE] * 3} if not OPENING else
                  {"type": "step", "radiance": [WINDOW_SKY] * 3, "where": "direction x < %g" % WINDOW_SKY_X},
         "render": {"engine": "CYCLES", "max_bounces": 64, "diffuse_bounces": 64, "pixel_filter": "BOX",
                    "filter_width_px": 1.0, "view_transform": "Standard", "denoising": False,
                    "adaptive_sampling": False, "seed": 11},
         "albedo_srgb": {"walls": WALL, "box": BOX, "block": BLOCK}}
bundle_views = {}  # each bundle's views (the fitted one's: views 0 and 2)
for k, (eye, target) in enumerate(VIEWS):
    d = out_dir if k != 1 else out_dir + "_holdout"
    os.makedirs(d, exist_ok=True)
    if k == 1:
        with open(os.path.join(out_dir, "mesh.ply")) as src, open(os.path.join(d, "mesh.ply"), "w") as dst:
            dst.write(src.read())
    eye, target = mathutils.Vector(eye), mathutils.Vector(target)
    cam.location = eye
    cam.rotation_euler = (target - eye).to_track_quat("-Z", "Y").to_euler()
    bpy.context.view_layer.update()
    image = "view%d.exr" % len(bundle_views.get(d, []))
    scene.render.filepath = os.path.join(d, image)
    bpy.ops.render.render(write_still=True)
    m = cam.matrix_world
    R = m.to_3x3() @ mathutils.Matrix(((1, 0, 0), (0, -1, 0), (0, 0, -1)))  # OpenCV axes
    wfc = [[R[r][0], R[r][1], R[r][2], m[r][3]] for r in range(3)] + [[0, 0, 0, 1]]
    fx = cam_data.lens / cam_data.sensor_width * W
    view = {"image": image, "width": W, "height": H, "fx": fx, "fy": fx, "cx": (W - 1) / 2,
            "cy": (H - 1) / 2, "world_from_camera": wfc}
    if KIND in ("hdr", "open-window", "glazed-window"):
        # A scan has no depth past the room: only the pixels whose ray hits the mesh are used
        # (mask0.png, 255 there; unmasked, the softboxes seen directly dominate the fit).
        mask = "mask%d.png" % len(bundle_views.get(d, []))
        write_room_mask(os.path.join(d, mask), eye, R, fx, W, H)
        view["mask"] = mask
    bundle_views.setdefault(d, []).append(view)
    with open(os.path.join(d, "scene.json"), "w") as f:
        json.dump({"mesh": "mesh.ply", "up": [0, 0, 1], "views": bundle_views[d]}, f, indent=2)
    with open(os.path.join(d, "truth.json"), "w") as f:
        json.dump(dict(truth, view="held out" if k == 1 else "fitted"), f, indent=2)
print("wrote", out_dir)
