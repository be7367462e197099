"""The add-on in a Blender run as the `bpy` module (4.x), on an empty scene with a glb imported:
shared by the headless scripts beside this file."""

import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "blender"))
import export_examples  # noqa: E402


def arguments(count):
    """The script's first `count` arguments after `--`."""
    return sys.argv[sys.argv.index("--") + 1:][:count]


def setup(glb):
    """Registers the add-on (the caller unregisters it: a bpy process with an operator still
    registered does not exit), imports `glb` and makes its armature active: (armature, mesh)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    export_examples.register()
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(glb))
    arm = next(o for o in bpy.data.objects if o.type == 'ARMATURE')
    mesh = next(o for o in bpy.data.objects if o.type == 'MESH')
    bpy.context.view_layer.objects.active = arm
    return arm, mesh
