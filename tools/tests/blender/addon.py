"""The exporter as an add-on, in a Blender run as the `bpy` module (4.x): registers it, imports a
glb, runs File > Export > rrskin example set's operator, and unregisters it (a bpy process with
an operator still registered does not exit).

    python tools/tests/blender/addon.py -- GLB OUT_DIR POSES TEST_ACTION
"""

import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "blender"))
import export_examples  # noqa: E402

glb, out, poses, action = sys.argv[sys.argv.index("--") + 1:][:4]
bpy.ops.wm.read_factory_settings(use_empty=True)
export_examples.register()
try:
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(glb))
    arm = next(o for o in bpy.data.objects if o.type == 'ARMATURE')
    bpy.context.view_layer.objects.active = arm
    result = bpy.ops.export_scene.rrskin_examples(directory=os.path.abspath(out) + os.sep,
                                                  poses=int(poses), test_action=action)
    print(f"addon: {result}", flush=True)
finally:
    export_examples.unregister()
if "FINISHED" not in result:
    sys.exit(1)
