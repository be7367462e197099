"""Train as a user clicks it: in a Blender window (Debian's Blender under a virtual X server),
the operator invoked, so that it trains on a thread while the window's event loop runs, then
reports. Exports a glb's rig through the add-on first; prints "trained: SUMMARY" and quits, or
exits with status 1 when training fails or takes over a minute.

    xvfb-run -a blender --factory-startup --python tools/tests/blender/train_modal.py -- GLB OUT_DIR
"""

import os
import sys
import time
import traceback

import bpy
import numpy as np

# Blender's own --python does not put the script's folder on the path.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from headless import arguments, export_examples  # noqa: E402


def start(glb, out):
    """Exports `glb`'s rig into `out` and invokes Train as the window would."""
    if "bool" not in np.__dict__:
        np.bool = bool  # io_scene_gltf2 3.4 still uses the alias numpy 1.24 removed
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    export_examples.register()
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(glb))
    arm = next(o for o in bpy.data.objects if o.type == 'ARMATURE')
    bpy.context.view_layer.objects.active = arm
    exported = bpy.ops.export_scene.rrskin_examples(directory=os.path.abspath(out) + os.sep,
                                                    poses=20)
    assert "FINISHED" in exported
    window = bpy.context.window_manager.windows[0]
    with bpy.context.temp_override(window=window, area=window.screen.areas[0]):
        assert "RUNNING_MODAL" in bpy.ops.rrskin.train('INVOKE_DEFAULT')


# A script that fails leaves a Blender window open: exit instead.
try:
    start(*arguments(2))
except Exception:
    traceback.print_exc()
    os._exit(1)
started = time.monotonic()


def finished():
    summary = bpy.context.scene.get("rrskin_summary")
    if summary:
        print(f"trained: {summary}", flush=True)
        bpy.ops.wm.quit_blender()
        return None
    if time.monotonic() - started > 60:
        print("train_modal: no model after 60 s", flush=True)
        os._exit(1)
    return 0.25


bpy.app.timers.register(finished, first_interval=0.25)
