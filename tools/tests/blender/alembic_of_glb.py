"""An Alembic cache of a glTF rig's clip, from Blender's own importer and exporter (4.x; the
`bpy` module): the glb imported (plain linear blend skinning), the clip made the armature's
action, the scene's range its frames at 24 fps, and `wm.alembic_export` at its defaults.

    python tools/tests/blender/alembic_of_glb.py -- GLB CLIP OUT.abc
"""

import os
import sys

import bpy
import numpy as np

glb, clip, out = sys.argv[sys.argv.index("--") + 1:][:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
if "bool" not in np.__dict__:
    np.bool = bool  # io_scene_gltf2 of 3.x still uses the alias numpy 1.24 removed
bpy.ops.import_scene.gltf(filepath=os.path.abspath(glb))
arm = next(o for o in bpy.data.objects if o.type == 'ARMATURE')
action = bpy.data.actions[clip]
arm.animation_data.action = action
scene = bpy.context.scene
scene.render.fps = 24
scene.frame_start, scene.frame_end = (int(round(f)) for f in action.frame_range)
bpy.ops.wm.alembic_export(filepath=os.path.abspath(out))
print(f"alembic_of_glb: wrote {out}: frames {scene.frame_start}..{scene.frame_end}", flush=True)
