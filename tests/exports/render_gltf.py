# Renders keyframe 0 of lightprobe's glTF export with Cycles, as a user would open it in
# Blender: through Blender's own glTF importer, with environment.hdr as the world by the
# mapping docs/formats.md states (Blender's Environment Texture, default mapping: the same
# picture). Used by tests/exports/blender_export_test.cpp.
#
#   blender -b -noaudio --factory-startup --python render_gltf.py -- DIR OUT_PREFIX SAMPLES SEED [SEED...]
#
# Two things the test sets that glTF cannot carry: the point lights' radius and the suns'
# angle (from the lights' extras, which the importer keeps as custom properties), and the
# material: glTF's metallic-roughness BSDF is not Lambertian, so the importer's Principled
# BSDF is swapped for a Diffuse BSDF fed by the same colour (the vertex colours), plus an
# Emission shader where the material glows. Blender 3.4's importer takes
# KHR_materials_emissive_strength (nits, cd/m^2, as the glTF extension defines it) as its
# own Emission Strength without the 683 lm/W it divides the lights' candela and lux by: the
# strength is divided by it here, as it is for the lights.
import math
import os
import sys

import bpy
import numpy

# Debian 12's Blender 3.4.1 glTF importer still uses numpy.bool, which NumPy 1.24 (Debian's)
# removed: give the alias back, as a user on Debian must (README, "Exports").
if not hasattr(numpy, "bool") or "bool" in getattr(numpy, "__former_attrs__", {}):
    numpy.bool = bool

WATTS_TO_LUMENS = 683.0

argv = sys.argv[sys.argv.index("--") + 1:]
directory, prefix, samples, seeds = argv[0], argv[1], int(argv[2]), [int(s) for s in argv[3:]]
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
bpy.ops.import_scene.gltf(filepath=os.path.join(directory, "scene.gltf"))
scene = bpy.context.scene

for light in bpy.data.lights:
    if light.type == "POINT":
        light.shadow_soft_size = light.get("radius", 0.0)
    elif light.type == "SUN":
        light.angle = 2 * light.get("angular_radius", 0.0)

for material in bpy.data.materials:
    if not material.use_nodes:
        continue
    tree = material.node_tree
    for node in list(tree.nodes):
        if node.type != "BSDF_PRINCIPLED":
            continue
        diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Roughness"].default_value = 0.0
        base = node.inputs["Base Color"]
        if base.links:
            tree.links.new(base.links[0].from_socket, diffuse.inputs["Color"])
        else:
            diffuse.inputs["Color"].default_value = base.default_value
        shader = diffuse.outputs["BSDF"]
        strength = node.inputs["Emission Strength"].default_value
        if strength > 0 and max(node.inputs["Emission"].default_value[:3]) > 0:
            emission = tree.nodes.new("ShaderNodeEmission")
            emission.inputs["Color"].default_value = node.inputs["Emission"].default_value
            emission.inputs["Strength"].default_value = strength / WATTS_TO_LUMENS
            add = tree.nodes.new("ShaderNodeAddShader")
            tree.links.new(shader, add.inputs[0])
            tree.links.new(emission.outputs["Emission"], add.inputs[1])
            shader = add.outputs["Shader"]
        for link in list(node.outputs["BSDF"].links):
            tree.links.new(shader, link.to_socket)
        tree.nodes.remove(node)

world = bpy.data.worlds.new("environment")
world.use_nodes = True
environment = os.path.join(directory, "environment.hdr")
if os.path.exists(environment):
    texture = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(environment)
    texture.interpolation = "Closest"
    world.node_tree.links.new(texture.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
else:
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
scene.world = world

camera = next(o for o in bpy.data.objects if o.type == "CAMERA" and o.data.name.startswith("keyframe_0"))
scene.camera = camera
scene.render.resolution_x = int(camera.data["width"])
scene.render.resolution_y = int(camera.data["height"])
scene.render.resolution_percentage = 100
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = samples
scene.cycles.use_adaptive_sampling = False
scene.cycles.use_denoising = False
scene.cycles.max_bounces = 12
scene.cycles.diffuse_bounces = 12
scene.cycles.pixel_filter_type = "BOX"
scene.cycles.filter_width = 1.0
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.image_settings.color_mode = "RGB"
for seed in seeds:
    scene.cycles.seed = seed
    scene.render.filepath = "%s%d.exr" % (prefix, seed)
    bpy.ops.render.render(write_still=True)
