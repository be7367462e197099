"""Saves the black-box rig of rig.py, keeping the glb's own animations, as a .blend:

    blender -b --factory-startup --python tools/tests/blender/make_rig.py -- GLB OUT.blend
"""

import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rig  # noqa: E402

glb, out = sys.argv[sys.argv.index("--") + 1:][:2]
arm, mesh = rig.build_rig(os.path.abspath(glb), keep_animations=True)
if arm.animation_data:
    arm.animation_data.use_nla = True
bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(out))
print(f"make_rig: wrote {out}: {len(mesh.data.vertices)} vertices, modifiers "
      f"{[m.type for m in mesh.modifiers]}, actions {[a.name for a in bpy.data.actions]}")
