"""Train and Preview in Blender's Python, headless (Blender 4.x as the `bpy` module, the rrskin
package on its path): exports a glb's rig through the add-on, trains in-process, previews the
model on a copy of the mesh, and prints one JSON line comparing, over the frames of the test
action, the preview with the model's own deformation and with the rig.

    python tools/tests/blender/train_preview.py -- GLB OUT_DIR POSES TEST_ACTION
"""

import json
import os

import bpy
import numpy as np

from headless import arguments, export_examples, setup

glb, out, poses, action = arguments(4)
try:
    arm, mesh = setup(glb)
    assert "FINISHED" in bpy.ops.export_scene.rrskin_examples(
        directory=os.path.abspath(out) + os.sep, poses=int(poses), test_action=action)
    assert "FINISHED" in bpy.ops.rrskin.train(learning_curve=False)
    summary = bpy.context.scene["rrskin_summary"]
    assert "FINISHED" in bpy.ops.rrskin.preview()
    preview = next(o for o in bpy.data.objects if o.name.endswith("(rrskin)"))
    model = export_examples.PREVIEWS[preview.name][0]
    bones = [arm.data.bones[b] for b in export_examples.PREVIEWS[preview.name][2]]
    arm.animation_data_create()
    arm.animation_data.action = bpy.data.actions[action]
    start, end = (int(round(f)) for f in bpy.data.actions[action].frame_range)
    to_model, to_rig = [], []
    for frame in range(start, end + 1, 4):
        bpy.context.scene.frame_set(frame)
        shown = np.empty(len(preview.data.vertices) * 3)
        preview.data.vertices.foreach_get("co", shown)
        shown = shown.reshape(-1, 3) + np.array(preview.location)
        q = export_examples.pose_transforms(bpy.context, arm, bones)
        expected = model.deform(q).astype(np.float64) @ export_examples.Y_UP
        rig = export_examples.evaluated_vertices(bpy.context, mesh)
        to_model.append(np.abs(shown - expected).max())
        to_rig.append(np.linalg.norm(shown - rig, axis=1).mean())
    size = np.ptp(export_examples.evaluated_vertices(bpy.context, mesh), axis=0).max()
    print(json.dumps({"summary": summary, "frames": len(to_model), "to_model": max(to_model),
                      "to_rig": float(np.mean(to_rig) / size)}), flush=True)
finally:
    export_examples.unregister()
