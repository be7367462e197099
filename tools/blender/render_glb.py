# Renders one frame of a glTF file (such as one `rrskin export` wrote) with Blender's own glTF
# importer and Cycles on the CPU (no GPU, no display needed): the picture in docs/export.md.
#
#   blender -b --factory-startup --python tools/blender/render_glb.py -- FILE.glb CLIP TIME OUT.png
#
# CLIP is the animation to play (the importer's action whose name starts with it), TIME the time
# in seconds (from the clip's first key). The camera frames the posed mesh from the front
# (glTF's +X, Blender's +X).
import sys

import bpy
import numpy
from mathutils import Vector

# Debian 12's Blender 3.4 importer still calls numpy.bool, which Debian's NumPy 1.24 removed.
if "bool" not in vars(numpy):
    numpy.bool = bool

path, clip, time, out = sys.argv[sys.argv.index("--") + 1 :]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path, merge_vertices=False)
scene = bpy.context.scene
mesh = next(o for o in scene.objects if o.type == "MESH")
armature = mesh.find_armature()
action = next(a for a in bpy.data.actions if a.name.startswith(clip))
armature.animation_data.action = action
fps = scene.render.fps / scene.render.fps_base
frame = action.frame_range[0] + float(time) * fps
scene.frame_set(int(frame), subframe=frame - int(frame))

depsgraph = bpy.context.evaluated_depsgraph_get()
evaluated = mesh.evaluated_get(depsgraph)
points = [evaluated.matrix_world @ v.co for v in evaluated.to_mesh().vertices]
lo = Vector([min(p[i] for p in points) for i in range(3)])
hi = Vector([max(p[i] for p in points) for i in range(3)])
centre, height = (lo + hi) / 2, hi.z - lo.z

camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
scene.collection.objects.link(camera)
camera.location = centre + Vector((2.2 * height, -0.6 * height, 0.15 * height))
camera.rotation_euler = (1.5708 - 0.06, 0.0, 1.5708 - 0.27)
camera.data.lens = 50
scene.camera = camera
sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", type="SUN"))
sun.data.energy = 3.0
sun.rotation_euler = (0.8, 0.2, -0.5)
scene.collection.objects.link(sun)
world = bpy.data.worlds.new("world")
world.color = (0.18, 0.2, 0.23)
world.use_nodes = True
world.node_tree.nodes["Background"].inputs[0].default_value = (0.18, 0.2, 0.23, 1.0)
world.node_tree.nodes["Background"].inputs[1].default_value = 0.8
scene.world = world

scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 48
scene.cycles.use_denoising = False  # Debian's Blender is built without OpenImageDenoise
scene.render.resolution_x, scene.render.resolution_y = 480, 640
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
print(f"rendered '{action.name}' at t = {time} s (frame {frame:.2f}) to {out}")
