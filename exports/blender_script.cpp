// The fixed part of the Blender export's scene.py (after the data block blender.cpp writes).
// Blender 3.4 (Debian 12) and later; tested with Debian's 3.4.1 only.
#include "exports/blender.h"

namespace lp {

const char* const kBlenderSceneScript = R"PY(import math
import os
import sys

import bpy
import mathutils
import numpy as np


def script_folder():
    """This script's folder, where mesh.ply and world.exr are: beside __file__ when run by
    --python; run from Blender's text editor (Scripting > Open > Run Script) __file__ is the
    text block's name under the .blend's folder, so the text block's own file path is used."""
    here = os.path.dirname(os.path.abspath(__file__))
    if os.path.exists(os.path.join(here, MESH)):
        return here
    for text in bpy.data.texts:
        path = bpy.path.abspath(text.filepath) if text.filepath else ""
        if path and os.path.exists(os.path.join(os.path.dirname(path), MESH)):
            return os.path.dirname(os.path.abspath(path))
    sys.exit("scene.py: %s is not beside this script (looked in %s and beside the open text files)" % (MESH, here))


HERE = script_folder()


def parse_args(argv):
    argv = argv[argv.index("--") + 1:] if "--" in argv else []
    args = {"save": None, "render": None, "camera": 0, "samples": 128, "seed": 0}
    i = 0
    while i < len(argv):
        key = argv[i][2:] if argv[i].startswith("--") else None
        if key not in args or i + 1 >= len(argv):
            sys.exit("scene.py: unknown or incomplete argument %r (--save FILE.blend, --render FILE.exr, "
                     "--camera K, --samples N, --seed N)" % argv[i])
        args[key] = argv[i + 1] if key in ("save", "render") else int(argv[i + 1])
        i += 2
    return args


def read_ply(path):
    """The binary little-endian PLY lightprobe writes: x y z nx ny nz, sRGB uchar colours, triangles."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        sys.exit("scene.py: %s: not a PLY file" % path)
    end += len(b"end_header\n")
    header = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        sys.exit("scene.py: %s: expected a binary little-endian PLY" % path)
    types = {"float": "<f4", "uchar": "u1", "int": "<i4"}
    props, counts, element = [], {}, None
    for line in header:
        words = line.split()
        if words[:1] == ["element"]:
            element = words[1]
            counts[element] = int(words[2])
        elif words[:1] == ["property"] and element == "vertex":
            props.append((words[2], types[words[1]]))
    vertex = np.frombuffer(data, dtype=np.dtype(props), count=counts["vertex"], offset=end)
    face = np.frombuffer(data, dtype=np.dtype([("n", "u1"), ("i", "<i4", (3,))]), count=counts["face"],
                         offset=end + vertex.nbytes)
    if np.any(face["n"] != 3):
        sys.exit("scene.py: %s: expected triangles" % path)
    return vertex, face["i"]


def srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    for collection in (bpy.data.meshes, bpy.data.lights, bpy.data.cameras, bpy.data.materials):
        for block in list(collection):
            collection.remove(block)


def add_mesh(scene):
    vertex, triangles = read_ply(os.path.join(HERE, MESH))
    n, t = len(vertex), len(triangles)
    me = bpy.data.meshes.new("lightprobe")
    me.vertices.add(n)
    me.vertices.foreach_set("co", np.column_stack([vertex["x"], vertex["y"], vertex["z"]]).astype(np.float32).ravel())
    me.loops.add(3 * t)
    me.loops.foreach_set("vertex_index", triangles.astype(np.int32).ravel())
    me.polygons.add(t)
    me.polygons.foreach_set("loop_start", np.arange(0, 3 * t, 3, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(t, 3, dtype=np.int32))
    me.polygons.foreach_set("use_smooth", np.ones(t, dtype=bool))
    me.update()
    if "nx" in vertex.dtype.names:  # the renderer's interpolated normals
        if hasattr(me, "use_auto_smooth"):  # needed for custom normals before Blender 4.1, gone since
            me.use_auto_smooth = True
        me.normals_split_custom_set_from_vertices(np.column_stack([vertex["nx"], vertex["ny"], vertex["nz"]]).tolist())
    rgb = srgb_to_linear(np.column_stack([vertex["red"], vertex["green"], vertex["blue"]]) / 255.0)
    rgba = np.column_stack([rgb, np.ones(n)]).astype(np.float32)
    albedo = me.color_attributes.new("albedo", "FLOAT_COLOR", "POINT")
    albedo.data.foreach_set("color", rgba.ravel())
    material = bpy.data.materials.new("albedo")
    material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    attribute = nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "albedo"
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Roughness"].default_value = 0.0  # Lambert, as lightprobe's renderer
    output = nodes.new("ShaderNodeOutputMaterial")
    material.node_tree.links.new(attribute.outputs["Color"], bsdf.inputs["Color"])
    material.node_tree.links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    me.materials.append(material)
    obj = bpy.data.objects.new("lightprobe_mesh", me)
    obj.matrix_world = mathutils.Matrix(BLENDER_FROM_WORLD).to_4x4()
    scene.collection.objects.link(obj)


def set_world(scene):
    world = bpy.data.worlds.new("lightprobe")
    world.use_nodes = True
    nodes = world.node_tree.nodes
    background = nodes["Background"]
    background.inputs["Strength"].default_value = 1.0
    if WORLD is None:
        background.inputs["Color"].default_value = (0, 0, 0, 1)
    else:
        image = bpy.data.images.load(os.path.join(HERE, WORLD))
        for name in ("Linear", "Linear Rec.709"):  # Blender 3.x, 4.x
            try:
                image.colorspace_settings.name = name
                break
            except TypeError:
                pass
        texture = nodes.new("ShaderNodeTexEnvironment")
        texture.image = image
        texture.interpolation = "Closest"  # the map's cells stay sharp
        world.node_tree.links.new(texture.outputs["Color"], background.inputs["Color"])
    scene.world = world


def add_lights(scene):
    for k, p in enumerate(POINT_LIGHTS):
        data = bpy.data.lights.new("point_light_%d" % k, type="POINT")
        data.color, data.energy, data.shadow_soft_size = p["color"], p["power"], p["radius"]
        obj = bpy.data.objects.new(data.name, data)
        obj.location = p["location"]
        scene.collection.objects.link(obj)
    for k, s in enumerate(SUNS):
        data = bpy.data.lights.new("sun_%d" % k, type="SUN")
        data.color, data.energy, data.angle = s["color"], s["strength"], s["angle"]
        obj = bpy.data.objects.new(data.name, data)
        obj.rotation_euler = mathutils.Vector(s["direction"]).to_track_quat("Z", "Y").to_euler()  # shines along -Z
        scene.collection.objects.link(obj)


def add_emitters(scene):
    # Each glowing surface a mesh just off the surface it glows on: on its emitting side its
    # light added to what shows through it (the surface's own reflection), its back see-through.
    for k, e in enumerate(EMITTERS):
        corners = np.array(e["triangles"], dtype=np.float32).reshape(-1, 3)
        t = len(corners) // 3
        order = np.arange(3 * t, dtype=np.int32).reshape(-1, 3)
        flip = np.array(e["normal_side"]) == 0  # wound so that the face's normal is the side that emits
        order[flip] = order[flip][:, [0, 2, 1]]
        me = bpy.data.meshes.new("emitter_%d" % k)
        me.vertices.add(3 * t)
        me.vertices.foreach_set("co", corners.ravel())
        me.loops.add(3 * t)
        me.loops.foreach_set("vertex_index", order.ravel())
        me.polygons.add(t)
        me.polygons.foreach_set("loop_start", np.arange(0, 3 * t, 3, dtype=np.int32))
        me.polygons.foreach_set("loop_total", np.full(t, 3, dtype=np.int32))
        me.update()
        material = bpy.data.materials.new("emitter_%d" % k)
        material.use_nodes = True
        nodes, links = material.node_tree.nodes, material.node_tree.links
        nodes.clear()
        emission, through, back = nodes.new("ShaderNodeEmission"), nodes.new("ShaderNodeBsdfTransparent"), nodes.new("ShaderNodeBsdfTransparent")
        emission.inputs["Color"].default_value = list(e["color"]) + [1.0]
        emission.inputs["Strength"].default_value = e["strength"]
        front, side = nodes.new("ShaderNodeAddShader"), nodes.new("ShaderNodeMixShader")
        geometry, output = nodes.new("ShaderNodeNewGeometry"), nodes.new("ShaderNodeOutputMaterial")
        links.new(emission.outputs["Emission"], front.inputs[0])
        links.new(through.outputs["BSDF"], front.inputs[1])
        links.new(geometry.outputs["Backfacing"], side.inputs["Fac"])
        links.new(front.outputs["Shader"], side.inputs[1])
        links.new(back.outputs["BSDF"], side.inputs[2])
        links.new(side.outputs["Shader"], output.inputs["Surface"])
        me.materials.append(material)
        obj = bpy.data.objects.new(me.name, me)
        scene.collection.objects.link(obj)


def add_cameras(scene):
    objects = []
    for k, c in enumerate(CAMERAS):
        data = bpy.data.cameras.new("keyframe_%d" % k)
        data.sensor_fit = "HORIZONTAL"
        data.sensor_width, data.lens = c["sensor_width"], c["lens"]
        data.shift_x, data.shift_y = c["shift_x"], c["shift_y"]
        obj = bpy.data.objects.new(data.name, data)
        obj.matrix_world = mathutils.Matrix(c["matrix_world"])
        scene.collection.objects.link(obj)
        objects.append(obj)
    return objects


def set_camera(scene, cameras, k):
    if not cameras:
        return
    if not 0 <= k < len(cameras):
        sys.exit("scene.py: --camera %d: there are %d keyframes" % (k, len(cameras)))
    c = CAMERAS[k]
    scene.camera = cameras[k]
    scene.render.resolution_x, scene.render.resolution_y = c["width"], c["height"]
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = c["pixel_aspect_x"], c["pixel_aspect_y"]


def set_render(scene, samples, seed):
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = seed
    scene.cycles.max_bounces = 12
    scene.cycles.diffuse_bounces = 12
    scene.cycles.pixel_filter_type = "BOX"  # one pixel, as lightprobe's renders
    scene.cycles.filter_width = 1.0
    scene.render.film_transparent = False
    scene.view_settings.view_transform = "Standard"  # the EXR holds the radiance itself
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGB"


def main():
    args = parse_args(sys.argv)
    scene = bpy.context.scene
    clear_scene()
    add_mesh(scene)
    set_world(scene)
    add_lights(scene)
    add_emitters(scene)
    cameras = add_cameras(scene)
    set_camera(scene, cameras, args["camera"])
    set_render(scene, args["samples"], args["seed"])
    if args["save"]:
        for image in bpy.data.images:  # the .blend stands alone
            if image.source == "FILE" and not image.packed_file:
                image.pack()
        path = os.path.abspath(args["save"])
        os.makedirs(os.path.dirname(path), exist_ok=True)
        bpy.ops.wm.save_as_mainfile(filepath=path)
        print("scene.py: saved", os.path.abspath(args["save"]))
    if args["render"]:
        scene.render.filepath = os.path.abspath(args["render"])
        bpy.ops.render.render(write_still=True)
        print("scene.py: rendered keyframe", args["camera"], "to", scene.render.filepath)


main()
)PY";

}  // namespace lp
