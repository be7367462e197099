"""Blender's own USD exporter, default settings, on the suite's black-box rig (rig.py, as
scenarios.py builds it: Preserve Volume, a driven corrective shape key, Corrective Smooth; its
action `rom`, frames 0..P at 24 fps): the test scenario of rrskin's USD route.

    python tools/tests/blender/usd_scenarios.py -- --out DIR [--glb GLB] [--poses 30]

writes, with `bpy.ops.wm.usd_export` (the `bpy` module, Blender 4.x) at its defaults but for
the two settings that choose what is written:

    rig.usd      the armature and its skinned mesh as UsdSkel (export_armatures=True,
                 export_animation=True; binary, as Blender writes .usd): SkelRoot, Skeleton,
                 the SkelAnimation `rom`, primvars:skel:jointIndices / jointWeights on the
                 mesh's base points, the shape key as a BlendShape; Z-up, metres
    cache.usdc   the evaluated mesh with its points time-sampled (export_armatures=False,
                 export_shapekeys=False, export_animation=True): every modifier, shape key and
                 driver; world transforms above it
    rig.usda, cache.usda   the same as text
    rig.fbx      the rig from Blender's FBX exporter at its defaults (a USD cache with an FBX rig)
    numpy/       the NumPy route of the same rig and frames (scenarios.numpy_reference)
"""

import os
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import scenarios  # noqa: E402


def main(argv):
    args = scenarios.arguments("usd_scenarios.py", argv)
    out = args.out
    t0 = time.time()
    arm, mesh, start = scenarios.build_scene(args, "start0")
    scene = bpy.context.scene
    end = scene.frame_end
    test_first = start + args.poses - args.test_poses + 1
    scenarios.numpy_reference(os.path.join(out, "numpy"), scene, arm, mesh, start, end, test_first)
    scene.frame_set(start)
    for rig, cache in (("rig.usd", "cache.usdc"), ("rig.usda", "cache.usda")):
        bpy.ops.wm.usd_export(filepath=os.path.join(out, rig), export_armatures=True,
                              export_animation=True)
        bpy.ops.wm.usd_export(filepath=os.path.join(out, cache), export_armatures=False,
                              export_shapekeys=False, export_animation=True)
    bpy.ops.export_scene.fbx(filepath=os.path.join(out, "rig.fbx"))
    print(f"usd_scenarios: wrote {out}: frames {start}..{end}, test frames {test_first}..{end}, "
          f"in {time.time() - t0:.1f} s", flush=True)


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
