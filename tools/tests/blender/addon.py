"""The exporter as an add-on, in a Blender run as the `bpy` module (4.x): registers it, imports a
glb, runs File > Export > rrskin example set's operator, and unregisters it (a bpy process with
an operator still registered does not exit).

    python tools/tests/blender/addon.py -- GLB OUT_DIR POSES TEST_ACTION
"""

import os
import sys

import bpy

from headless import arguments, export_examples, setup

glb, out, poses, action = arguments(4)
try:
    setup(glb)
    result = bpy.ops.export_scene.rrskin_examples(directory=os.path.abspath(out) + os.sep,
                                                  poses=int(poses), test_action=action)
    print(f"addon: {result}", flush=True)
finally:
    export_examples.unregister()
if "FINISHED" not in result:
    sys.exit(1)
