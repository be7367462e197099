"""Saves the black-box rig of rig.py, keeping the glb's own animations, as a .blend:

    blender -b --factory-startup --python tools/tests/blender/make_rig.py -- GLB OUT.blend [--controls ACTION]

With --controls the rig also has an IK pole and an attachment slot that deform nothing and move
in the glb's animation ACTION (rig.add_controls).
"""

import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rig  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
glb, out = args[:2]
arm, mesh = rig.build_rig(os.path.abspath(glb), keep_animations=True)
if "--controls" in args:
    rig.add_controls(arm, bpy.data.actions[args[args.index("--controls") + 1]])
if arm.animation_data:
    arm.animation_data.use_nla = True
bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(out))
print(f"make_rig: wrote {out}: {len(mesh.data.vertices)} vertices, modifiers "
      f"{[m.type for m in mesh.modifiers]}, actions {[a.name for a in bpy.data.actions]}")
