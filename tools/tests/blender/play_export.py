# Plays a file `rrskin export` wrote in Blender, through Blender's own glTF importer: imports
# FILE.glb, sets the scene to each time of TIMES.txt (seconds, one per line, possibly between
# the file's keys: subframes), reads the evaluated (skinned) mesh, and writes the vertices in
# glTF's coordinates (Y up) as little-endian f32, time after time, to OUT.bin. The vertex order
# is the file's: the importer keeps each primitive's vertices in order (merge_vertices off),
# primitives one after the other; REST.bin (the file's rest positions, f32 xyz) is checked
# against the imported mesh to prove it. Morph targets (shape keys) play with the clip.
#
#   blender -b --factory-startup --python-exit-code 1 --python play_export.py -- \
#       FILE.glb CLIP TIMES.txt REST.bin OUT.bin
import struct
import sys

import bpy
import numpy

# Debian 12's Blender 3.4 importer still calls numpy.bool, which Debian's NumPy 1.24 removed
# (an alias of the builtin): give it back for the importer.
if "bool" not in vars(numpy):
    numpy.bool = bool

path, clip, times_path, rest_path, out_path = sys.argv[sys.argv.index("--") + 1 :]
times = [float(line) for line in open(times_path) if line.strip()]
rest_bytes = open(rest_path, "rb").read()
rest = list(struct.iter_unpack("<3f", rest_bytes))

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path, merge_vertices=False)
meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
if len(meshes) != 1:
    raise SystemExit(f"expected one mesh object, found {[(o.name, len(o.data.vertices)) for o in meshes]}")
mesh = meshes[0]
armature = mesh.find_armature()
if armature is None:
    raise SystemExit("the imported mesh has no armature")

# glTF (x, y, z) is Blender (x, -z, y).
def to_gltf(v):
    return (v[0], v[2], -v[1])

if len(mesh.data.vertices) != len(rest):
    raise SystemExit(f"{len(mesh.data.vertices)} vertices imported, the file has {len(rest)}")
worst = 0.0
for v, r in zip(mesh.data.vertices, rest):
    g = to_gltf(mesh.matrix_world @ v.co)
    worst = max(worst, max(abs(a - b) for a, b in zip(g, r)))
if worst > 1e-4:
    raise SystemExit(f"the imported rest mesh is not the file's in order (off by {worst})")

# The importer names actions after the animation, possibly with the object's name added; a
# clip's morph-target weights (a model's pose-space correctives) are an action of the mesh's
# shape keys (id_root KEY), which the importer only stashes: both are made active here.
def clip_action(root):
    named = [a for a in bpy.data.actions if a.id_root == root and a.name.startswith(clip)]
    return next((a for a in named if a.name == clip), named[0] if named else None)

action = clip_action("OBJECT")
if action is None:
    raise SystemExit(f"no action for animation '{clip}': {[a.name for a in bpy.data.actions]}")
armature.animation_data.action = action
keys = mesh.data.shape_keys
if keys is not None:
    weights = clip_action("KEY")
    if weights is None:
        raise SystemExit(f"the mesh has shape keys but '{clip}' does not animate them")
    if keys.animation_data is None:
        keys.animation_data_create()
    keys.animation_data.action = weights
    # Blender 3.4's importer widens a shape key's slider range from the clip's first key only
    # (io_scene_gltf2 gltf2_blender_animation_weight.py: min(coords[1:2])), so later weights
    # below 0 or above 1 would be clamped; glTF's weights are unbounded: the full range here.
    for block in keys.key_blocks:
        block.slider_min, block.slider_max = -10.0, 10.0
scene = bpy.context.scene
fps = scene.render.fps / scene.render.fps_base
start = action.frame_range[0]
first_time = min(times)

with open(out_path, "wb") as out:
    for t in times:
        frame = start + (t - first_time) * fps
        whole = int(frame // 1)
        scene.frame_set(whole, subframe=frame - whole)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = mesh.evaluated_get(depsgraph)
        data = evaluated.to_mesh()
        for v in data.vertices:
            out.write(struct.pack("<3f", *to_gltf(evaluated.matrix_world @ v.co)))
        evaluated.to_mesh_clear()
print(f"played {len(times)} times of '{action.name}' at {fps} fps from frame {start}")
