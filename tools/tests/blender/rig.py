"""A small black-box rig built in Blender from the bundled CesiumMan glb (for the tests).

Imported with seam vertices merged (a welded mesh, as riggers have it), deformed by the
Armature modifier with Preserve Volume (dual-quaternion skinning), a corrective shape key on
the left knee driven by the knee's bend, and a Corrective Smooth modifier after the Armature
modifier. The file's own animations are removed. Used by scenarios.py and make_rig.py.
"""

import math
import os
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "blender"))
import export_examples  # noqa: E402  (the first-party exporter: its random poses)


def import_glb(path, merge_vertices=True):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if "bool" not in np.__dict__:
        np.bool = bool  # io_scene_gltf2 3.4 still uses the alias numpy 1.24 removed
    bpy.ops.import_scene.gltf(filepath=path, merge_vertices=merge_vertices)


def build_rig(glb, corrective_key=True, keep_animations=False):
    """Imports `glb` and makes it a black box; returns (armature, mesh)."""
    import_glb(glb)
    arm = next(o for o in bpy.data.objects if o.type == 'ARMATURE')
    mesh = export_examples.deformed_meshes(bpy.data.objects, arm)[0]
    if not keep_animations:
        arm.animation_data_clear()
        for a in list(bpy.data.actions):
            bpy.data.actions.remove(a)
    elif arm.animation_data:
        arm.animation_data.action = None  # the key's rest angle is measured at the bind pose
        arm.animation_data.use_nla = False
    skin = next(m for m in mesh.modifiers if m.type == 'ARMATURE')
    skin.use_deform_preserve_volume = True
    if corrective_key:
        add_knee_key(arm, mesh)
    second_material(mesh)
    smooth = mesh.modifiers.new("CorrectiveSmooth", 'CORRECTIVE_SMOOTH')
    smooth.iterations = 10
    smooth.factor = 0.5
    return arm, mesh


def add_controls(arm, action):
    """Adds what rigs carry beside the deforming bones, each with Blender's default Deform on
    and no vertex group: `IKPole` (a root) and `HelmetSlot` (an attachment slot, a child of the
    armature's last leaf bone), and keys both moving in `action` (the held-out animation)."""
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    bones = arm.data.edit_bones
    leaf = [b for b in bones if not b.children][-1]
    pole = bones.new("IKPole")
    pole.head, pole.tail = (0.3, -0.5, 0.5), (0.3, -0.5, 0.6)
    slot = bones.new("HelmetSlot")
    slot.parent = leaf
    slot.head = leaf.tail
    slot.tail = leaf.tail + (leaf.tail - leaf.head).normalized() * 0.1
    bpy.ops.object.mode_set(mode='OBJECT')
    kept = arm.animation_data.action
    arm.animation_data.action = action
    start, end = (int(round(f)) for f in action.frame_range)
    for frame in range(start, end + 1, 4):
        t = 0.2 * (frame - start)
        pb = arm.pose.bones["IKPole"]
        pb.location = (0.2 * math.sin(t), 0.1 * math.cos(t), 0.0)
        pb.keyframe_insert("location", frame=frame)
        pb = arm.pose.bones["HelmetSlot"]
        pb.rotation_mode = 'QUATERNION'
        pb.rotation_quaternion = (math.cos(t), math.sin(t), 0.0, 0.0)
        pb.keyframe_insert("rotation_quaternion", frame=frame)
    arm.animation_data.action = kept


def second_material(mesh):
    """The mesh's right half (x < 0) in a second material: its glTF then has two primitives,
    each holding the vertices of its faces (the seam between them duplicated)."""
    if len(mesh.data.materials) == 0:
        mesh.data.materials.append(bpy.data.materials.new("left"))
    mesh.data.materials.append(bpy.data.materials.new("right"))
    right = len(mesh.data.materials) - 1
    for poly in mesh.data.polygons:
        if poly.center.x < 0.0:
            poly.material_index = right


def add_knee_key(arm, mesh, knee="leg_joint_L_2", upper="leg_joint_L_1", lower="leg_joint_L_3"):
    """A shape key pushing the left knee's skin out along the normals, driven by the angle
    between the thigh and the shin (0 at rest, 1 at 90 degrees)."""
    group = mesh.vertex_groups.get(knee)
    if group is None:
        return
    mesh.shape_key_add(name="Basis", from_mix=False)
    key = mesh.shape_key_add(name="knee_L", from_mix=False)
    me = mesh.data
    for v in me.vertices:
        w = 0.0
        for g in v.groups:
            if g.group == group.index:
                w = g.weight
        if w > 0.0:
            key.data[v.index].co = v.co + v.normal * (0.02 * w)
    fc = key.driver_add("value")
    drv = fc.driver
    drv.type = 'SCRIPTED'
    var = drv.variables.new()
    var.name = "bend"
    var.type = 'ROTATION_DIFF'
    var.targets[0].id = arm
    var.targets[0].bone_target = upper
    var.targets[1].id = arm
    var.targets[1].bone_target = lower
    # Zero at the bind pose (the bones are not aligned there): the rest mesh stays the mesh.
    drv.expression = "0"
    bpy.context.view_layer.update()
    rest_bend = rest_angle(arm, upper, lower)
    drv.expression = f"max(bend - {rest_bend:.6f}, 0) / {math.pi / 2:.6f}"


def rest_angle(arm, a, b):
    qa = arm.pose.bones[a].matrix.to_quaternion()
    qb = arm.pose.bones[b].matrix.to_quaternion()
    return qa.rotation_difference(qb).angle


def rom_action(arm, count, seed=0, swing=40.0, twist=60.0, start=0, name="rom"):
    """An action: frame `start` the bind pose, then `count` random poses on consecutive
    frames, a key on every bone's location and rotation at each frame. Sets the scene's range."""
    bones, parents = export_examples.deform_bones(arm)
    rng = np.random.default_rng(seed)
    rotations = export_examples.random_rotations(rng, count, bones, parents, swing, twist)
    column = {b.name: j for j, b in enumerate(bones)}
    arm.animation_data_create()
    action = bpy.data.actions.new(name)
    arm.animation_data.action = action
    for pb in arm.pose.bones:
        pb.rotation_mode = 'QUATERNION'
    for k in range(count + 1):
        frame = start + k
        for pb in arm.pose.bones:
            j = column.get(pb.name)
            pb.location = (0.0, 0.0, 0.0)
            pb.scale = (1.0, 1.0, 1.0)
            pb.rotation_quaternion = (1.0, 0.0, 0.0, 0.0) if k == 0 or j is None else rotations[k - 1, j]
            pb.keyframe_insert("location", frame=frame)
            pb.keyframe_insert("rotation_quaternion", frame=frame)
    scene = bpy.context.scene
    scene.render.fps = 24
    scene.render.fps_base = 1.0
    scene.frame_start = start
    scene.frame_end = start + count
    scene.frame_set(start)
    return action
