"""rrskin example set exporter for Blender (3.4 and later).

Writes, from an armature and the mesh it deforms, the NumPy example-set layout that
`rrskin train DIR` and `rrskin eval DIR` read (see data/README.md):

    rest_vertices.npy    (V,3)     f4  the evaluated mesh at pose 0 (the bind/rest pose)
    faces.npy            (T,3)     i4  the evaluated mesh's triangles (loop_triangles)
    bone_parents.npy     (J,)      i4  nearest written ancestor, -1 for a root
    bone_names.json      [J]           the deform bones the mesh's skin weights (its vertex
                                       groups; every deform bone where none has weight), in the
                                       armature's bone order
    pose_transforms.npy  (N,J,3,4) f4  per deform bone posed_world @ inv(rest_world), top 3 rows,
                                       world = armature.matrix_world @ bone matrix
    pose_vertices.npy    (N,V,3)   f4  the evaluated mesh (every modifier, shape key and driver)
                                       in world space, in each pose
    split.npy            (N,)      i4  0 = training pose, 1 = held-out test pose
    skin_weights.npy     (V,J)     f4  the mesh's vertex-group weights of the deform bones, rows
                                       normalised to 1 (a vertex with none goes to the root)

Poses: 0 = the rest pose; 1..P = random range-of-motion poses (per deform bone, written or not
(a deform bone the skin does not weight still moves the rig), except the
roots, a swing of up to --swing degrees about a random axis perpendicular to the bone's Y
axis, times a twist of up to +-twist degrees about it; numpy Generator seeded by --seed);
then, with --test-action NAME, every frame of that action as held-out poses (split 1).

How many: --poses auto exports in rounds. It starts from 40 random poses (or --budget, if
fewer), asks training's learning curve (the rrskin Python package where Blender's Python has it,
else `rrskin train --learning-curve` of the binary --rrskin, default `rrskin` on PATH) whether
more would help (docs/method.md §22), and exports again with the count it advises, at
most twice the last and at most --budget (320), until the curve is saturated, advises no more,
or the budget is reached. The random poses of a count are the first of every larger count of
the same seed, so each round extends the last. The learning curve measures held-out error on
range-of-motion poses like these: what more of them buy, not how well the rig's animations
will do (docs/experiments.md, "How many poses, and which").

Axes: everything is converted from Blender's Z-up world to glTF's Y-up, (x, y, z) ->
(x, z, -y), the convention of Blender's glTF exporter (export_yup, on by default), so that a
model trained from this folder matches a glTF export of the same rig and its vertices.

Use it as an add-on (File > Export > rrskin example set) or headless:

    blender -b RIG.blend --python export_examples.py -- --out DIR [--poses 40 | --poses auto
        [--budget 320] [--rrskin PATH]] [--seed S] [--test-action NAME] [--swing DEG]
        [--twist DEG] [--armature NAME] [--mesh NAME]
    blender -b --factory-startup --python export_examples.py -- --input FILE.glb --out DIR ...

Headless, every stage prints one line, the last line says what was written, and a user
mistake (no armature, no mesh, a bad action name, an unwritable --out) is one "error:" line
on stderr and exit status 1.
"""

bl_info = {
    "name": "rrskin example set",
    "author": "rrskin",
    "version": (1, 0, 0),
    "blender": (3, 4, 0),
    "location": "File > Export > rrskin example set",
    "description": "Export range-of-motion example poses of a rig for rrskin training",
    "category": "Import-Export",
}

import json
import math
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Matrix, Quaternion, Vector

# Blender Z-up world -> glTF Y-up: (x, y, z) -> (x, z, -y).
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

LAYOUT_FILES = (
    "rest_vertices.npy", "faces.npy", "bone_parents.npy", "bone_names.json",
    "pose_transforms.npy", "pose_vertices.npy", "split.npy", "skin_weights.npy",
)


class UserError(Exception):
    """A mistake in the scene or the arguments: reported as one line, never a traceback."""


def say(log, text):
    if log is not None:
        log(text)


# ---------------------------------------------------------------------------------------------
# Choosing the rig


def deformed_meshes(scene_objects, arm):
    """Meshes with an Armature modifier on `arm`, then meshes deformed through a cage: a Mesh
    Deform, Surface Deform or Lattice modifier whose object has an Armature modifier on `arm`."""
    def direct(obj):
        return obj is not None and any(m.type == 'ARMATURE' and m.object == arm
                                       for m in obj.modifiers)

    def cage(m):
        return {'MESH_DEFORM': 'object', 'SURFACE_DEFORM': 'target', 'LATTICE': 'object'}.get(m.type)

    found = [o for o in scene_objects if o.type == 'MESH' and direct(o)]
    for obj in scene_objects:
        if obj.type == 'MESH' and obj not in found and any(
                cage(m) and direct(getattr(m, cage(m))) for m in obj.modifiers):
            found.append(obj)
    return found


def choose_rig(context, armature_name=None, mesh_name=None):
    objects = list(context.scene.objects)
    if armature_name:
        arm = bpy.data.objects.get(armature_name)
        if arm is None or arm.type != 'ARMATURE':
            names = [o.name for o in objects if o.type == 'ARMATURE']
            raise UserError(f"no armature named {armature_name!r} (armatures: {names or 'none'})")
    else:
        arms = [o for o in objects if o.type == 'ARMATURE']
        active = context.view_layer.objects.active if context.view_layer else None
        selected = [o for o in arms if o.select_get()]
        if active is not None and active.type == 'MESH':
            # The active mesh's armature, if it has exactly one.
            mods = [m.object for m in active.modifiers if m.type == 'ARMATURE' and m.object]
            if len(mods) == 1:
                selected = [mods[0]]
        if active is not None and active.type == 'ARMATURE':
            selected = [active]
        if len(selected) == 1:
            arm = selected[0]
        elif len(arms) == 1:
            arm = arms[0]
        elif not arms:
            raise UserError("the scene has no armature")
        else:
            raise UserError(
                f"the scene has {len(arms)} armatures ({', '.join(o.name for o in arms)}): "
                "select one or pass --armature NAME")
    meshes = deformed_meshes(objects, arm)
    if mesh_name:
        mesh = bpy.data.objects.get(mesh_name)
        if mesh is None or mesh.type != 'MESH':
            raise UserError(f"no mesh object named {mesh_name!r} "
                            f"(meshes deformed by {arm.name}: {[m.name for m in meshes] or 'none'})")
        if mesh not in meshes:
            raise UserError(f"mesh {mesh_name!r} has no Armature modifier on {arm.name!r} "
                            "(nor a cage or lattice deformed by it)")
    elif not meshes:
        raise UserError(f"no mesh has an Armature modifier on armature {arm.name!r}")
    elif len(meshes) > 1:
        raise UserError(f"{len(meshes)} meshes are deformed by {arm.name!r} "
                        f"({', '.join(m.name for m in meshes)}): pass --mesh NAME")
    else:
        mesh = meshes[0]
    return arm, mesh


def find_action(name, arm):
    """The action `name`, or the one Blender's glTF importer made of animation `name`."""
    action = bpy.data.actions.get(name) or bpy.data.actions.get(f"{name}_{arm.name}")
    if action is None:
        names = ", ".join(a.name for a in bpy.data.actions) or "none"
        raise UserError(f"no action named {name!r} (actions: {names})")
    return action


# ---------------------------------------------------------------------------------------------
# Poses


def deform_bones(arm):
    """Deform bones in the armature's order (the bones the random poses turn), and each one's
    nearest deform ancestor."""
    bones = [b for b in arm.data.bones if b.use_deform]
    if not bones:
        raise UserError(f"armature {arm.name!r} has no deform bones")
    return bones, nearest_parents(bones)


def nearest_parents(bones):
    """Each bone's nearest ancestor among `bones` (index), -1 for none."""
    index = {b.name: i for i, b in enumerate(bones)}
    parents = []
    for b in bones:
        p = b.parent
        while p is not None and p.name not in index:
            p = p.parent
        parents.append(-1 if p is None else index[p.name])
    return parents


def skinning_bones(mesh_obj, bones):
    """The bones of `bones` that the mesh's own skin uses: a vertex group of that name gives some
    vertex weight (all of `bones` where none does, as for a mesh deformed through a cage). A
    deform bone without weight (an IK pole, a foot control, an attachment slot left with
    Blender's default Deform on) deforms nothing: written, it is only a bone the model must
    learn to ignore."""
    names = {g.index: g.name for g in mesh_obj.vertex_groups}
    weighted = {names[g.group] for v in mesh_obj.data.vertices for g in v.groups
                if g.weight > 0.0 and g.group in names}
    chosen = [b for b in bones if b.name in weighted]
    return chosen or bones


def random_rotations(rng, count, bones, parents, swing_deg, twist_deg):
    """count x J quaternions (w, x, y, z) in bone space; roots stay at identity."""
    out = np.zeros((count, len(bones), 4))
    out[:, :, 0] = 1.0
    swing, twist = math.radians(swing_deg), math.radians(twist_deg)
    for i in range(count):
        for j in range(len(bones)):
            if parents[j] < 0:
                continue
            # Swing about a random axis perpendicular to the bone's Y axis, then twist about Y.
            phi = rng.uniform(0.0, 2.0 * math.pi)
            axis = Vector((math.cos(phi), 0.0, math.sin(phi)))
            q_swing = Quaternion(axis, rng.uniform(0.0, swing))
            q_twist = Quaternion((0.0, 1.0, 0.0), rng.uniform(-twist, twist))
            q = q_swing @ q_twist
            out[i, j] = (q.w, q.x, q.y, q.z)
    return out


class PoseState:
    """Saves what the export changes on the armature (action, NLA, pose) and restores it."""

    def __init__(self, scene, arm):
        self.scene, self.arm = scene, arm
        self.frame = scene.frame_current
        self.pose_position = arm.data.pose_position
        ad = arm.animation_data
        self.action = ad.action if ad else None
        self.use_nla = ad.use_nla if ad else None
        self.bones = {pb.name: (pb.rotation_mode, pb.location.copy(), pb.rotation_quaternion.copy(),
                                pb.rotation_euler.copy(), pb.rotation_axis_angle[:], pb.scale.copy())
                      for pb in arm.pose.bones}

    def restore(self):
        arm = self.arm
        arm.data.pose_position = self.pose_position
        if arm.animation_data:
            arm.animation_data.action = self.action
            arm.animation_data.use_nla = True if self.use_nla is None else self.use_nla
        for pb in arm.pose.bones:
            mode, loc, quat, euler, axis_angle, scale = self.bones[pb.name]
            pb.rotation_mode = mode
            pb.location, pb.rotation_quaternion, pb.rotation_euler = loc, quat, euler
            pb.rotation_axis_angle, pb.scale = axis_angle, scale
        self.scene.frame_set(self.frame)


def clear_animation(arm):
    arm.data.pose_position = 'POSE'
    if arm.animation_data:
        arm.animation_data.action = None
        arm.animation_data.use_nla = False


def reset_pose(arm):
    for pb in arm.pose.bones:
        pb.rotation_mode = 'QUATERNION'
        pb.location = (0.0, 0.0, 0.0)
        pb.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
        pb.scale = (1.0, 1.0, 1.0)


# ---------------------------------------------------------------------------------------------
# Reading the evaluated scene


def evaluated_vertices(context, mesh_obj):
    """World-space (Z-up) vertex positions of the evaluated mesh, float64 (V, 3)."""
    dg = context.evaluated_depsgraph_get()
    ev = mesh_obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        mw = np.array(ev.matrix_world)
        return co @ mw[:3, :3].T + mw[:3, 3]
    finally:
        ev.to_mesh_clear()


def evaluated_faces(context, mesh_obj):
    dg = context.evaluated_depsgraph_get()
    ev = mesh_obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        me.calc_loop_triangles()
        tris = np.empty(len(me.loop_triangles) * 3, dtype=np.int32)
        me.loop_triangles.foreach_get("vertices", tris)
        return tris.reshape(-1, 3)
    finally:
        ev.to_mesh_clear()


def bone_worlds(context, arm, bones):
    """(J, 4, 4) posed world matrices (Z-up) of the deform bones, and their rest worlds."""
    dg = context.evaluated_depsgraph_get()
    ev = arm.evaluated_get(dg)
    mw = np.array(ev.matrix_world)
    posed = np.array([mw @ np.array(ev.pose.bones[b.name].matrix) for b in bones])
    rest = np.array([mw @ np.array(b.matrix_local) for b in bones])
    return posed, rest


def pose_transforms(context, arm, bones):
    """(J, 3, 4): each bone's transform relative to its rest, in glTF's Y-up frame (what
    pose_transforms.npy holds)."""
    posed, rest = bone_worlds(context, arm, bones)
    to_y = np.eye(4)
    to_y[:3, :3] = Y_UP
    return (to_y @ posed @ np.linalg.inv(rest) @ np.linalg.inv(to_y))[:, :3, :]


def skin_weights(mesh_obj, bones, parents, vertex_count):
    """(V, J) vertex-group weights of the deform bones, rows normalised; None if unavailable."""
    me = mesh_obj.data
    if len(me.vertices) != vertex_count:
        return None
    column = {b.name: j for j, b in enumerate(bones)}
    group_column = {g.index: column[g.name] for g in mesh_obj.vertex_groups if g.name in column}
    w = np.zeros((vertex_count, len(bones)))
    for v in me.vertices:
        for g in v.groups:
            j = group_column.get(g.group)
            if j is not None and g.weight > 0.0:
                w[v.index, j] += g.weight
    sums = w.sum(axis=1)
    root = parents.index(-1)
    w[sums <= 0.0, root] = 1.0
    sums[sums <= 0.0] = 1.0
    return w / sums[:, None]


def topology_culprit(context, mesh_obj, set_pose_a, set_pose_b):
    """The first modifier after which poses a and b give different vertex counts, or None."""
    mods = list(mesh_obj.modifiers)
    shown = [m.show_viewport for m in mods]

    def count(set_pose):
        set_pose()
        dg = context.evaluated_depsgraph_get()
        ev = mesh_obj.evaluated_get(dg)
        me = ev.to_mesh()
        n = len(me.vertices)
        ev.to_mesh_clear()
        return n

    try:
        for k in range(len(mods)):
            for i, m in enumerate(mods):
                m.show_viewport = shown[i] and i <= k
            if count(set_pose_a) != count(set_pose_b):
                return mods[k]
        return None
    finally:
        for m, s in zip(mods, shown):
            m.show_viewport = s


# ---------------------------------------------------------------------------------------------
# The export


def check_out_dir(out):
    if not out:
        raise UserError("--out DIR is required")
    if os.path.exists(out) and not os.path.isdir(out):
        raise UserError(f"--out {out}: exists and is not a folder")
    try:
        os.makedirs(out, exist_ok=True)
        probe = os.path.join(out, ".rrskin-write-test")
        with open(probe, "w") as f:
            f.write("")
        os.remove(probe)
    except OSError as e:
        raise UserError(f"--out {out}: cannot write there ({e.strerror or e})")


def export_examples(context, out, poses=40, seed=0, test_action=None, swing=40.0, twist=60.0,
                    armature=None, mesh=None, log=print):
    """Writes the example set into `out`; returns a one-line summary. Raises UserError."""
    if poses < 0:
        raise UserError(f"--poses {poses}: must be at least 0")
    if not (0.0 <= swing <= 180.0) or not (0.0 <= twist <= 180.0):
        raise UserError("--swing and --twist must lie in 0..180 degrees")
    check_out_dir(out)
    scene = context.scene
    arm, mesh_obj = choose_rig(context, armature, mesh)
    action = find_action(test_action, arm) if test_action else None
    posed, posed_parents = deform_bones(arm)
    bones = skinning_bones(mesh_obj, posed)
    parents = nearest_parents(bones)
    say(log, f"rig: armature {arm.name!r} ({len(posed)} deform bones posed, the {len(bones)} that "
             f"the mesh's skin weights written), mesh {mesh_obj.name!r}")

    rng = np.random.default_rng(seed)
    rotations = random_rotations(rng, poses, posed, posed_parents, swing, twist)
    test_frames = []
    if action is not None:
        start, end = action.frame_range
        test_frames = list(range(int(round(start)), int(round(end)) + 1))

    # The poses, as functions that put the armature there.
    def rest_pose():
        clear_animation(arm)
        reset_pose(arm)
        context.view_layer.update()

    def random_pose(i):
        def set_pose():
            clear_animation(arm)
            reset_pose(arm)
            for j, b in enumerate(posed):
                arm.pose.bones[b.name].rotation_quaternion = rotations[i, j]
            context.view_layer.update()
        return set_pose

    def action_pose(frame):
        def set_pose():
            clear_animation(arm)
            reset_pose(arm)
            if arm.animation_data is None:
                arm.animation_data_create()
            arm.animation_data.action = action
            scene.frame_set(frame)
        return set_pose

    setters = [rest_pose] + [random_pose(i) for i in range(poses)] + [action_pose(f) for f in test_frames]
    split = np.array([0] * (1 + poses) + [1] * len(test_frames), dtype=np.int32)
    n = len(setters)
    say(log, f"poses: 1 rest + {poses} random (swing <= {swing:g} deg, twist <= +-{twist:g} deg, "
             f"seed {seed})" + (f" + {len(test_frames)} test frames of action {action.name!r} "
                                f"({test_frames[0]}..{test_frames[-1]})" if test_frames else ""))

    state = PoseState(scene, arm)
    t0 = time.time()
    try:
        rest_pose()
        rest_co = evaluated_vertices(context, mesh_obj)
        faces = evaluated_faces(context, mesh_obj)
        v = len(rest_co)
        if v == 0 or len(faces) == 0:
            raise UserError(f"mesh {mesh_obj.name!r} evaluates to no vertices or no triangles")
        transforms = np.empty((n, len(bones), 3, 4))
        vertices = np.empty((n, v, 3))
        for i, set_pose in enumerate(setters):
            set_pose()
            co = evaluated_vertices(context, mesh_obj)
            if len(co) != v:
                culprit = topology_culprit(context, mesh_obj, rest_pose, set_pose)
                where = (f"modifier {culprit.name!r} ({culprit.type}) changes it"
                         if culprit is not None else "a modifier or a driver changes it")
                raise UserError(f"mesh {mesh_obj.name!r} has {v} evaluated vertices in the rest "
                                f"pose but {len(co)} in pose {i}: {where}; the vertex count must "
                                "not depend on the pose")
            transforms[i] = pose_transforms(context, arm, bones)
            vertices[i] = co @ Y_UP.T
        say(log, f"evaluated {n} poses of {v} vertices in {time.time() - t0:.1f} s")
    finally:
        state.restore()

    weights = skin_weights(mesh_obj, bones, parents, v)
    for name in LAYOUT_FILES:
        path = os.path.join(out, name)
        if os.path.isfile(path):
            os.remove(path)
    f4 = np.dtype("<f4")
    i4 = np.dtype("<i4")
    np.save(os.path.join(out, "rest_vertices.npy"), np.ascontiguousarray(rest_co @ Y_UP.T, dtype=f4))
    np.save(os.path.join(out, "faces.npy"), np.ascontiguousarray(faces, dtype=i4))
    np.save(os.path.join(out, "bone_parents.npy"), np.array(parents, dtype=i4))
    with open(os.path.join(out, "bone_names.json"), "w") as f:
        json.dump([b.name for b in bones], f)
    np.save(os.path.join(out, "pose_transforms.npy"), np.ascontiguousarray(transforms, dtype=f4))
    np.save(os.path.join(out, "pose_vertices.npy"), np.ascontiguousarray(vertices, dtype=f4))
    np.save(os.path.join(out, "split.npy"), split.astype(i4))
    written = ["rest_vertices", "faces", "bone_parents", "bone_names", "pose_transforms",
               "pose_vertices", "split"]
    if weights is not None:
        np.save(os.path.join(out, "skin_weights.npy"), np.ascontiguousarray(weights, dtype=f4))
        written.append("skin_weights")
    else:
        say(log, "skin_weights.npy not written: the evaluated mesh's vertex count differs from "
                 "the mesh's own, so its vertex groups do not apply")
    return (f"wrote {out}: {v} vertices, {len(faces)} triangles, {len(bones)} bones, {n} poses "
            f"({int((split == 0).sum())} train, {int((split == 1).sum())} test); "
            + ", ".join(written))


# ---------------------------------------------------------------------------------------------
# How many poses: rounds advised by the learning curve

AUTO_START = 40


def package():
    """The rrskin Python package, where Blender's Python has it (`pip install ./python`), or None."""
    try:
        import rrskin
    except ImportError:
        return None
    return rrskin


def train_in_process(out, learning_curve=False, progress=None):
    """The model `rrskin.train` makes of the set in `out`, in this Python. Raises UserError."""
    rrskin = package()
    if rrskin is None:
        raise UserError("the rrskin Python package is not in Blender's Python: install it with "
                        "Blender's own pip (`BLENDER_PYTHON -m pip install ./python` from a "
                        "clone of rrskin)")
    try:
        return rrskin.train(rrskin.load_set(out), learning_curve=learning_curve, progress=progress)
    except rrskin.Error as e:
        raise UserError(f"training {out}: {e}")


def learning_curve(rrskin, out):
    """The learning curve and advice of training the set in `out` (the model is discarded): by
    the rrskin package in this Python where `rrskin` (a binary) is None and the package is here,
    else by `rrskin train OUT --learning-curve --json` of that binary (default `rrskin`)."""
    import subprocess
    import tempfile

    if rrskin is None and package() is not None:
        report = train_in_process(out, learning_curve=True).report
        return report["learning_curve"], report["learning_curve_advice"]
    rrskin = rrskin or "rrskin"
    with tempfile.TemporaryDirectory() as scratch:
        try:
            run = subprocess.run([rrskin, "train", out, "-o", os.path.join(scratch, "m.rrs"),
                                  "--learning-curve", "--json"], capture_output=True, text=True)
        except OSError as e:
            raise UserError(f"--rrskin {rrskin}: cannot run it ({e.strerror}); or install the "
                            "rrskin Python package in Blender's Python")
    if run.returncode != 0:
        lines = run.stderr.strip().splitlines() or ["no message"]
        raise UserError(f"rrskin train {out} failed: {lines[-1]}")
    report = json.loads(run.stdout)
    return report["learning_curve"], report["learning_curve_advice"]


def next_count(poses, advice, budget):
    """The next round's random poses after `poses`, or None to stop (and why)."""
    if poses >= budget:
        return None, f"the budget of {budget} poses"
    if advice is None or advice["saturated"] is None:
        return None, "too few poses for a learning curve"
    if advice["saturated"]:
        return None, "the learning curve is saturated"
    # The advice counts training poses, the rest pose among them.
    advised = advice["poses"] - 1 if advice["poses"] is not None else budget
    if advised <= poses:
        return None, f"the learning curve advises {advised} random poses"
    return min(advised, 2 * poses, budget), None


def export_auto(context, out, budget=320, rrskin=None, log=print, **options):
    """Rounds of export_examples until the learning curve stops them; returns the last summary."""
    if budget < 1:
        raise UserError(f"--budget {budget}: must be at least 1")
    poses = min(AUTO_START, budget)
    while True:
        summary = export_examples(context, out, poses=poses, log=log, **options)
        curve, advice = learning_curve(rrskin, out)
        points = ", ".join(f"{p['ee']:.2f} at {p['poses']}" for p in curve or [])
        say(log, f"round of {poses} random poses: learning curve {points or 'none'}"
                 + (f"; {advice['sentence']}" if advice else ""))
        following, why = next_count(poses, advice, budget)
        if following is None:
            return f"{summary}; stopped at {poses} random poses: {why}"
        poses = following


# ---------------------------------------------------------------------------------------------
# Headless use


def import_input(path, log):
    if not os.path.isfile(path):
        raise UserError(f"--input {path}: no such file")
    ext = os.path.splitext(path)[1].lower()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if ext in (".glb", ".gltf"):
        if "bool" not in np.__dict__:
            np.bool = bool  # io_scene_gltf2 3.4 still uses the alias numpy 1.24 removed
        op = bpy.ops.import_scene.gltf
    elif ext == ".fbx":
        op = bpy.ops.import_scene.fbx
    elif ext == ".blend":
        bpy.ops.wm.open_mainfile(filepath=path)
        say(log, f"opened {path}")
        return
    else:
        raise UserError(f"--input {path}: not a .glb, .gltf, .fbx or .blend file")
    try:
        result = op(filepath=path)
    except RuntimeError as e:
        raise UserError(f"--input {path}: the importer failed: {str(e).strip().splitlines()[-1]}")
    if "FINISHED" not in result:
        raise UserError(f"--input {path}: the importer failed")
    say(log, f"imported {path}")


def parse_args(argv):
    import argparse

    class Parser(argparse.ArgumentParser):
        def error(self, message):
            raise UserError(message)

    p = Parser(prog="blender -b [RIG.blend] --python export_examples.py --",
               description="Export an rrskin example set (NumPy layout) from a rig.")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--input", help="import this .glb/.gltf/.fbx/.blend first (empty scene)")
    p.add_argument("--poses", default="40",
                   help="random range-of-motion poses (40), or auto: rounds the learning curve advises")
    p.add_argument("--budget", type=int, default=320, help="--poses auto: at most this many (320)")
    p.add_argument("--rrskin", help="--poses auto: train with this rrskin binary (default: the "
                   "rrskin Python package where Blender's Python has it, else rrskin on PATH)")
    p.add_argument("--seed", type=int, default=0, help="random seed (0)")
    p.add_argument("--test-action", help="append this action's frames as held-out poses")
    p.add_argument("--swing", type=float, default=40.0, help="largest swing, degrees (40)")
    p.add_argument("--twist", type=float, default=60.0, help="largest twist, degrees (60)")
    p.add_argument("--armature", help="the armature object (default: the selected or only one)")
    p.add_argument("--mesh", help="the deformed mesh object (needed when several)")
    args = p.parse_args(argv)
    if args.poses != "auto":
        try:
            args.poses = int(args.poses)
        except ValueError:
            raise UserError(f"--poses {args.poses}: a count or auto")
    return args


def main(argv):
    def log(text):
        print(f"rrskin export: {text}", flush=True)

    try:
        args = parse_args(argv)
        if args.input:
            import_input(args.input, log)
        options = dict(seed=args.seed, test_action=args.test_action, swing=args.swing,
                       twist=args.twist, armature=args.armature, mesh=args.mesh)
        if args.poses == "auto":
            summary = export_auto(bpy.context, args.out, budget=args.budget, rrskin=args.rrskin,
                                  log=log, **options)
        else:
            summary = export_examples(bpy.context, args.out, poses=args.poses, log=log, **options)
    except UserError as e:
        print(f"rrskin export: error: {e}", file=sys.stderr, flush=True)
        return 1
    log(summary)
    return 0


# ---------------------------------------------------------------------------------------------
# The add-on


class EXPORT_OT_rrskin_examples(bpy.types.Operator):
    """Export range-of-motion example poses of the selected armature for rrskin"""
    bl_idname = "export_scene.rrskin_examples"
    bl_label = "Export rrskin example set"
    bl_options = {'REGISTER'}

    directory: bpy.props.StringProperty(subtype='DIR_PATH')
    poses: bpy.props.IntProperty(name="Random poses", default=40, min=0)
    seed: bpy.props.IntProperty(name="Seed", default=0, min=0)
    swing: bpy.props.FloatProperty(name="Swing (deg)", default=40.0, min=0.0, max=180.0)
    twist: bpy.props.FloatProperty(name="Twist (deg)", default=60.0, min=0.0, max=180.0)
    test_action: bpy.props.StringProperty(name="Test action",
                                          description="Append this action's frames as test poses")
    mesh: bpy.props.StringProperty(name="Mesh", description="Needed when several meshes are deformed")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        try:
            summary = export_examples(context, bpy.path.abspath(self.directory), poses=self.poses,
                                      seed=self.seed, test_action=self.test_action or None,
                                      swing=self.swing, twist=self.twist, mesh=self.mesh or None,
                                      log=lambda t: print(f"rrskin export: {t}"))
        except UserError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        context.scene["rrskin_set"] = bpy.path.abspath(self.directory)
        self.report({'INFO'}, summary)
        return {'FINISHED'}


# ---------------------------------------------------------------------------------------------
# Train and Preview: the rrskin package in Blender's Python


def trained_summary(model):
    """The held-out error against SSD's (the training error where the set holds no test poses),
    the predicted cost, and the learning curve's advice."""
    r = model.report
    split = "test" if r["rr_reduced"]["test"] is not None else "train"
    which = "held-out" if split == "test" else "training (no test poses: export a test action)"
    ratio = model.info["cost"]["targets"]["transformed_normals"]["ratio"]
    line = (f"rrskin: {model.info['proxies']} proxies, {which} EE {r['rr_reduced'][split]:.2f} % "
            f"(SSD {r['ssd'][split]:.2f} %), {ratio:.2f} x the engine's skinning")
    advice = r.get("learning_curve_advice")
    return line + (f"; {advice['sentence']}" if advice else "")


class RRSKIN_OT_train(bpy.types.Operator):
    """Train an rrskin model from the example set exported last, in Blender's Python"""
    bl_idname = "rrskin.train"
    bl_label = "Train rrskin model"
    bl_options = {'REGISTER'}

    directory: bpy.props.StringProperty(name="Example set", subtype='DIR_PATH',
                                        description="Default: the set exported last")
    learning_curve: bpy.props.BoolProperty(name="Learning curve", default=True,
                                           description="Also say whether more poses would help")

    def folder(self, context):
        folder = bpy.path.abspath(self.directory) if self.directory else context.scene.get("rrskin_set")
        if not folder:
            raise UserError("no example set: export one first (File > Export > rrskin example set)")
        return folder

    def finish(self, context, folder, model):
        path = os.path.join(folder, "model.rrs")
        model.save(path)
        context.scene["rrskin_model"] = path
        summary = trained_summary(model)
        context.scene["rrskin_summary"] = summary
        self.report({'INFO'}, f"{summary}; wrote {path}")
        return {'FINISHED'}

    def execute(self, context):
        """Trains before returning (scripts, headless)."""
        try:
            folder = self.folder(context)
            model = train_in_process(folder, self.learning_curve)
        except UserError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        return self.finish(context, folder, model)

    def invoke(self, context, event):
        """Trains on a thread (training releases the GIL), its stage in the status bar; Esc
        stops it at the next stage."""
        import threading

        try:
            self._folder = self.folder(context)
        except UserError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        self._stage, self._result, self._stop = "starting", None, False

        def progress(label, stage, done, total):
            if self._stop:
                raise UserError("stopped")
            self._stage = f"{label}: {stage} ({done}/{total})"

        def work():
            try:
                self._result = train_in_process(self._folder, self.learning_curve, progress)
            except UserError as e:
                self._result = e

        self._thread = threading.Thread(target=work, daemon=True)
        self._thread.start()
        self._timer = context.window_manager.event_timer_add(0.25, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type == 'ESC':
            self._stop = True
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        if self._thread.is_alive():
            context.workspace.status_text_set(f"rrskin: {self._stage} (Esc stops)")
            return {'PASS_THROUGH'}
        context.window_manager.event_timer_remove(self._timer)
        context.workspace.status_text_set(None)
        if isinstance(self._result, UserError):
            self.report({'ERROR'}, str(self._result))
            return {'CANCELLED'}
        return self.finish(context, self._folder, self._result)


PREVIEWS = {}


def preview_frame(scene, *args):
    """Every preview's mesh in the current pose of its armature."""
    for name, (model, arm_name, bones) in list(PREVIEWS.items()):
        obj, arm = bpy.data.objects.get(name), bpy.data.objects.get(arm_name)
        if obj is None or arm is None:
            del PREVIEWS[name]
            continue
        q = pose_transforms(bpy.context, arm, [arm.data.bones[b] for b in bones])
        world = model.deform(q).astype(np.float64) @ Y_UP
        obj.data.vertices.foreach_set("co", (world - np.array(obj.location)).ravel())
        obj.data.update()


class RRSKIN_OT_preview(bpy.types.Operator):
    """Play the trained rrskin model on a copy of the mesh beside the rig, over the current
    action, so that its errors show against the rig"""
    bl_idname = "rrskin.preview"
    bl_label = "Preview rrskin model"
    bl_options = {'REGISTER', 'UNDO'}

    model: bpy.props.StringProperty(name="Model", subtype='FILE_PATH',
                                    description="Default: the model trained last")

    def execute(self, context):
        rrskin = package()
        path = bpy.path.abspath(self.model) if self.model else context.scene.get("rrskin_model")
        if rrskin is None or not path:
            self.report({'ERROR'}, "train a model first (the rrskin package in Blender's Python)")
            return {'CANCELLED'}
        try:
            names_file = os.path.join(os.path.dirname(path), "bone_names.json")
            with open(names_file) as f:
                bones = json.load(f)
            arm, mesh_obj = choose_rig(context, None, None)
            missing = [b for b in bones if b not in arm.data.bones]
            if missing:
                raise UserError(f"armature {arm.name!r} has no bone {missing[0]!r} of {names_file}")
            model = rrskin.Model.load(path)
        except (UserError, OSError, rrskin.Error) as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        skin = model.skin
        mesh = bpy.data.meshes.new(f"{mesh_obj.name} (rrskin)")
        mesh.from_pydata((skin["rest_positions"] @ Y_UP).tolist(), [], skin["triangles"].tolist())
        obj = bpy.data.objects.new(mesh.name, mesh)
        context.collection.objects.link(obj)
        size = np.ptp(skin["rest_positions"], axis=0).max()
        obj.location = (1.2 * size, 0.0, 0.0)
        PREVIEWS[obj.name] = (model, arm.name, bones)
        if preview_frame not in bpy.app.handlers.frame_change_post:
            bpy.app.handlers.frame_change_post.append(preview_frame)
        preview_frame(context.scene)
        self.report({'INFO'}, f"previewing {path} on {obj.name!r}")
        return {'FINISHED'}


class VIEW3D_PT_rrskin(bpy.types.Panel):
    bl_label = "rrskin"
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "rrskin"

    def draw(self, context):
        col = self.layout.column()
        col.operator(EXPORT_OT_rrskin_examples.bl_idname, text="Export example set")
        col.operator(RRSKIN_OT_train.bl_idname, text="Train")
        col.operator(RRSKIN_OT_preview.bl_idname, text="Preview")
        if "rrskin_summary" in context.scene:
            col.label(text=context.scene["rrskin_summary"])


CLASSES = (EXPORT_OT_rrskin_examples, RRSKIN_OT_train, RRSKIN_OT_preview, VIEW3D_PT_rrskin)


def menu_func_export(self, context):
    self.layout.operator(EXPORT_OT_rrskin_examples.bl_idname, text="rrskin example set")


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.TOPBAR_MT_file_export.append(menu_func_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_func_export)
    if preview_frame in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.remove(preview_frame)
    PREVIEWS.clear()
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)


if __name__ == "__main__":
    if "--" in sys.argv:
        sys.exit(main(sys.argv[sys.argv.index("--") + 1:]))
    else:
        register()
