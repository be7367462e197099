"""Black-box example sets from four different deformers, built in Blender from the bundled
CesiumMan glb and exported with export_examples.py (the first-party exporter):

    blender -b --factory-startup --python-exit-code 1 --python tools/blender/make_black_boxes.py \\
        -- --out DIR [--sets muscle,cage,smooth,soft] [--poses 40] [--seed 7] [--glb FILE]
        [--swing 40] [--twist 60] [--sag 0.02] [--save-blend] [--prefix cesium]
        [--test-action NAME] [--smooth-iterations 20]

writes DIR/cesium_muscle, DIR/cesium_cage, DIR/cesium_smooth and DIR/cesium_soft (the layout of
data/README.md; each trains with `rrskin train` and evaluates with `rrskin eval`):

- muscle: plain LBS (Armature modifier, no Preserve Volume) plus 15 corrective shape keys on
  bone drivers: muscles that bulge with the joint angle (biceps and triceps with the elbow,
  hamstrings and quadriceps with the knee, calves with the ankle, deltoids with the arm's
  swing, forearms with their twist, the belly with the spine's bend), signed and nonlinear.
- cage: the character has no Armature modifier of its own: a Mesh Deform modifier binds it to
  a coarse closed cage (the body voxel-remeshed and inflated) that the armature deforms by LBS.
- smooth: plain LBS followed by Corrective Smooth (20 iterations, factor 0.5, length weighted).
- soft: plain LBS as the goal of a quasi-static elastic skin: edge springs keep the rest
  lengths, zero-length goal springs pull each vertex to its LBS position (weak on the belly,
  hips, thighs and upper arms, strong elsewhere) and gravity pulls the flesh down (-Y). Each
  pose's shape is the energy minimum, solved from the LBS mesh (projective dynamics), so it is
  a function of the pose alone: flesh sags with the limb's orientation and the skin resists
  LBS's collapse at twisted joints. --sag: how far the softest flesh alone would sink, metres
  (0.02; 0: no gravity, the elastic skin alone).

Every set: pose 0 the rest pose, --poses random range-of-motion poses (export_examples.py's:
swing <= --swing deg, twist <= +-(--twist) deg, numpy seeded by --seed; the same poses in every
set), then the glb's own walk (Anim_0, 48 frames) as held-out test poses. Deterministic up to
float rounding (Blender's threaded evaluation: runs differ by at most 2e-7 m). --save-blend also
writes DIR/<set>.blend (the rig, for a look in Blender).

Another character: --glb, --test-action (its animation's action, `NAME_ARMATURE`, or a prefix
of it) and --prefix (DIR/<prefix>_<set>). Only smooth and cage are independent of CesiumMan's
bones. The Khronos Fox (glTF-Sample-Models 2.0/Fox/glTF-Binary/Fox.glb; CC0 mesh, CC-BY 4.0
rig by @tomkranis, not bundled) with its walk held out, as in docs/experiments.md:

    ... make_black_boxes.py -- --out DIR --sets smooth --glb Fox.glb --test-action Walk --prefix fox
"""

import math
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Matrix, Vector

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import export_examples as ex  # noqa: E402

REPO = os.path.dirname(os.path.dirname(HERE))
GLB = os.path.join(REPO, "data", "cesiumman_gltf", "CesiumMan_examples.glb")
TEST_ACTION = "Anim_0_Armature"
SETS = ("muscle", "cage", "smooth", "soft")

# CesiumMan's bones (the glb's joint names).
PELVIS, SPINE, CHEST = "Skeleton_torso_joint_1", "Skeleton_torso_joint_2", "torso_joint_3"
ARM = {"L": ("Skeleton_arm_joint_L__4_", "Skeleton_arm_joint_L__3_", "Skeleton_arm_joint_L__2_"),
       "R": ("Skeleton_arm_joint_R", "Skeleton_arm_joint_R__2_", "Skeleton_arm_joint_R__3_")}
LEG = {s: (f"leg_joint_{s}_1", f"leg_joint_{s}_2", f"leg_joint_{s}_3") for s in "LR"}
# World directions (Blender, Z up; the character faces -Y).
FRONT, BACK, UP = Vector((0, -1, 0)), Vector((0, 1, 0)), Vector((0, 0, 1))


def say(text):
    print(f"make_black_boxes: {text}", flush=True)


def import_character(glb):
    """The glb with its seam vertices merged (welded, as riggers have it); its animations kept
    (the walk is the test action), none playing: the bind pose."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if "bool" not in np.__dict__:
        np.bool = bool  # io_scene_gltf2 3.4 still uses the alias numpy 1.24 removed
    bpy.ops.import_scene.gltf(filepath=glb, merge_vertices=True)
    arm = next(o for o in bpy.data.objects if o.type == 'ARMATURE')
    body = ex.deformed_meshes(bpy.data.objects, arm)[0]
    if arm.animation_data:
        arm.animation_data.action = None
        arm.animation_data.use_nla = False
    ex.reset_pose(arm)
    bpy.context.view_layer.update()
    return arm, body


def skin(body):
    return next(m for m in body.modifiers if m.type == 'ARMATURE')


def group_weights(obj, name):
    """(V,) weights of vertex group `name` (0 where absent)."""
    w = np.zeros(len(obj.data.vertices))
    g = obj.vertex_groups.get(name)
    if g is None:
        return w
    for v in obj.data.vertices:
        for e in v.groups:
            if e.group == g.index:
                w[v.index] = e.weight
    return w


def world_rest(obj):
    """(V,3) rest positions and (V,3) normals of `obj`'s own mesh, in world space."""
    me = obj.data
    co = np.empty(len(me.vertices) * 3)
    no = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    me.vertices.foreach_get("normal", no)
    mw = np.array(obj.matrix_world)
    r = mw[:3, :3]
    n = no.reshape(-1, 3) @ r.T
    return co.reshape(-1, 3) @ r.T + mw[:3, 3], n / np.linalg.norm(n, axis=1, keepdims=True)


# ---------------------------------------------------------------------------------------------
# muscle: LBS + corrective shape keys on bone drivers


def add_bulge(arm, body, name, segment, amount, side, span, expression, variables):
    """A shape key pushing `segment`'s skin out along the normals, `amount` metres at most:
    along the bone a sine bump over the fraction `span` of its length, around it strongest on
    the `side` (a world direction) and a third of that on the far side, scaled by the
    vertex's weight of the bone (doubled, at most 1). Its value is the driver `expression` of `variables`
    (name -> (bone, transform type), the bone's local rotation as swing and twist about Y)."""
    co, normal = world_rest(body)
    mw = arm.matrix_world
    bone = arm.data.bones[segment]
    head, tail = np.array(mw @ bone.head_local), np.array(mw @ bone.tail_local)
    axis = tail - head
    t = (co - head) @ axis / (axis @ axis)
    u = np.clip((t - span[0]) / (span[1] - span[0]), 0.0, 1.0)
    along = np.sin(math.pi * u)
    around = 0.35 + 0.65 * np.clip(normal @ np.array(side), 0.0, 1.0)
    # CesiumMan's weights are broad (few vertices above 0.8): full strength from 0.5 on.
    near = np.minimum(2.0 * group_weights(body, segment), 1.0)
    offset = (amount * near * along * around)[:, None] * normal
    local = offset @ np.array(body.matrix_world)[:3, :3]  # rotation only: its inverse is .T
    if body.data.shape_keys is None:
        body.shape_key_add(name="Basis", from_mix=False)
    key = body.shape_key_add(name=name, from_mix=False)
    base = np.empty(len(body.data.vertices) * 3)
    body.data.vertices.foreach_get("co", base)
    key.data.foreach_set("co", (base.reshape(-1, 3) + local).ravel())
    drv = key.driver_add("value").driver
    drv.type = 'SCRIPTED'
    for var_name, (bone_name, channel) in variables.items():
        var = drv.variables.new()
        var.name = var_name
        var.type = 'TRANSFORMS'
        target = var.targets[0]
        target.id = arm
        target.bone_target = bone_name
        target.transform_type = channel
        target.transform_space = 'LOCAL_SPACE'
        target.rotation_mode = 'SWING_TWIST_Y'
    drv.expression = expression
    return key


def ramp(x, start, full):
    """Driver text: 0 below `start` radians, rising smoothly (quadratically) to 1 at `full`."""
    return f"min(max(({x}) - {start}, 0) / {full - start}, 1) ** 2"


def build_muscle(arm, body):
    skin(body).use_deform_preserve_volume = False
    keys = []
    for s, (upper, fore, hand) in ARM.items():
        # Elbow flexion (one sign of the forearm's swing about X) bulges the biceps, extension
        # the triceps; the arm's swing away from rest the deltoid; the forearm's twist its
        # muscles.
        flex = {"x": (fore, 'ROT_X')}
        keys.append(add_bulge(arm, body, f"biceps_{s}", upper, 0.03, FRONT, (0.35, 1.0),
                              ramp("x", 0.05, 0.5), flex))
        keys.append(add_bulge(arm, body, f"triceps_{s}", upper, 0.015, BACK, (0.3, 0.95),
                              ramp("-x", 0.1, 0.5), flex))
        swing = {"x": (upper, 'ROT_X'), "z": (upper, 'ROT_Z')}
        keys.append(add_bulge(arm, body, f"deltoid_{s}", upper, 0.02, UP, (-0.1, 0.45),
                              ramp("sqrt(x * x + z * z)", 0.1, 0.6), swing))
        keys.append(add_bulge(arm, body, f"forearm_{s}", fore, 0.012, FRONT, (0.0, 0.7),
                              ramp("max(y, -y)", 0.2, 1.0), {"y": (fore, 'ROT_Y')}))
    for s, (thigh, shin, foot) in LEG.items():
        knee = {"x": (shin, 'ROT_X')}
        keys.append(add_bulge(arm, body, f"hamstring_{s}", thigh, 0.025, BACK, (0.3, 1.0),
                              ramp("x", 0.05, 0.5), knee))
        keys.append(add_bulge(arm, body, f"quadriceps_{s}", thigh, 0.018, FRONT, (0.2, 0.9),
                              ramp("-x", 0.05, 0.5), knee))
        keys.append(add_bulge(arm, body, f"calf_{s}", shin, 0.02, BACK, (0.05, 0.6),
                              ramp("max(x, -x)", 0.1, 0.5), {"x": (foot, 'ROT_X')}))
    keys.append(add_bulge(arm, body, "belly", SPINE, 0.03, FRONT, (-0.3, 0.8),
                          ramp("x", 0.05, 0.5), {"x": (SPINE, 'ROT_X')}))
    bpy.context.view_layer.update()
    bad = [k.name for k in keys if not k.id_data.animation_data.drivers.find(
        f'key_blocks["{k.name}"].value').driver.is_valid]
    if bad:
        raise RuntimeError(f"invalid drivers: {bad}")
    return f"LBS + {len(keys)} driven muscle shape keys"


# ---------------------------------------------------------------------------------------------
# cage: Mesh Deform bound to an LBS-skinned cage


def make_cage(arm, body, voxel=0.025, inflate=0.025):
    """A closed coarse cage around the rest body: its copy voxel-remeshed, inflated along the
    normals and smoothed; weights: inverse-distance blends of the 8 nearest body vertices'."""
    tmp = body.copy()
    tmp.data = body.data.copy()
    tmp.shape_key_clear()
    bpy.context.collection.objects.link(tmp)
    for m in list(tmp.modifiers):
        tmp.modifiers.remove(m)
    # The glb's mesh has open shells (the head's): thickened first, or the voxels miss them.
    so = tmp.modifiers.new("Solidify", 'SOLIDIFY')
    so.thickness = 0.03
    so.offset = 0.0
    rm = tmp.modifiers.new("Remesh", 'REMESH')
    rm.mode = 'VOXEL'
    rm.voxel_size = voxel
    sm = tmp.modifiers.new("Smooth", 'SMOOTH')
    sm.iterations = 4
    dp = tmp.modifiers.new("Inflate", 'DISPLACE')
    dp.mid_level = 0.0
    dp.strength = inflate
    dp.direction = 'NORMAL'
    dc = tmp.modifiers.new("Coarse", 'DECIMATE')
    dc.ratio = 0.3
    dg = bpy.context.evaluated_depsgraph_get()
    mesh = bpy.data.meshes.new_from_object(tmp.evaluated_get(dg))
    bpy.data.objects.remove(tmp)
    cage = bpy.data.objects.new("cage", mesh)
    bpy.context.collection.objects.link(cage)
    cage.parent = body.parent
    cage.matrix_parent_inverse = body.matrix_parent_inverse.copy()
    cage.matrix_world = body.matrix_world.copy()
    cage.display_type = 'WIRE'
    bpy.context.view_layer.update()

    body_co, _ = world_rest(body)
    cage_co, _ = world_rest(cage)
    names = [g.name for g in body.vertex_groups]
    w = np.stack([group_weights(body, n) for n in names], axis=1)
    d = np.linalg.norm(cage_co[:, None, :] - body_co[None, :, :], axis=2)
    near = np.argsort(d, axis=1)[:, :8]
    inv = 1.0 / (np.take_along_axis(d, near, axis=1) + 1e-4)
    cw = (w[near] * inv[:, :, None]).sum(axis=1) / inv.sum(axis=1)[:, None]
    cw /= np.maximum(cw.sum(axis=1, keepdims=True), 1e-12)
    cage.vertex_groups.clear()  # the copied mesh keeps the body's group names, empty
    for j, n in enumerate(names):
        g = cage.vertex_groups.new(name=n)
        for i in np.nonzero(cw[:, j] > 1e-4)[0]:
            g.add([int(i)], float(cw[i, j]), 'REPLACE')
    m = cage.modifiers.new("Armature", 'ARMATURE')
    m.object = arm
    return cage


def build_cage(arm, body):
    cage = make_cage(arm, body)
    body.modifiers.remove(skin(body))  # the cage alone deforms it
    md = body.modifiers.new("MeshDeform", 'MESH_DEFORM')
    md.object = cage
    md.precision = 5
    bpy.context.view_layer.objects.active = body
    with bpy.context.temp_override(object=body, active_object=body):
        bpy.ops.object.meshdeform_bind(modifier=md.name)
    bpy.context.view_layer.update()  # the bind happens on this evaluation
    if not md.is_bound:
        raise RuntimeError("Mesh Deform did not bind")
    return (f"Mesh Deform (precision {md.precision}) on a cage of {len(cage.data.vertices)} "
            f"vertices skinned by LBS")


# ---------------------------------------------------------------------------------------------
# smooth: LBS + Corrective Smooth


SMOOTH_ITERATIONS = [20]  # --smooth-iterations


def build_smooth(arm, body):
    skin(body).use_deform_preserve_volume = False
    cs = body.modifiers.new("CorrectiveSmooth", 'CORRECTIVE_SMOOTH')
    cs.iterations = SMOOTH_ITERATIONS[0]
    cs.factor = 0.5
    cs.smooth_type = 'LENGTH_WEIGHTED'
    cs.rest_source = 'ORCO'
    return f"LBS + Corrective Smooth ({cs.iterations} iterations, factor 0.5, length weighted)"


# ---------------------------------------------------------------------------------------------
# soft: LBS as the goal of a quasi-static elastic skin under gravity (applied after the export)

# Goal stiffness (per unit of the edge springs' stiffness) by bone: flesh is soft.
SOFT_GOAL = {PELVIS: 0.05, SPINE: 0.08, LEG["L"][0]: 0.08, LEG["R"][0]: 0.08,
             ARM["L"][0]: 0.12, ARM["R"][0]: 0.12}
HARD_GOAL = 4.0
SAG = 0.02  # metres, the default of --sag
ITERATIONS = 200


def build_soft(arm, body):
    skin(body).use_deform_preserve_volume = False
    return "LBS, then a quasi-static elastic skin under gravity (after the export)"


def soften(folder, bone_names, sag):
    """Replaces the exported LBS positions by the soft skin's equilibria, pose by pose: the
    minimum over x of sum_edges (|x_i - x_j| - L_ij)^2 + sum_i k_i |x_i - g_i|^2 - 2 G . x
    (L the rest lengths, g the LBS mesh, k the goal stiffness, G gravity along -Y, as strong as
    sinks the softest flesh alone by `sag` metres). Vertices
    with no weight on a soft bone are pinned to LBS (bone-hard skin); the others are solved
    by ITERATIONS steps of projective dynamics from the LBS mesh (a fixed matrix, inverted
    once), so each pose's shape is a fixed function of that pose."""
    rest = np.load(os.path.join(folder, "rest_vertices.npy")).astype(np.float64)
    faces = np.load(os.path.join(folder, "faces.npy"))
    poses = np.load(os.path.join(folder, "pose_vertices.npy")).astype(np.float64)
    weights = np.load(os.path.join(folder, "skin_weights.npy")).astype(np.float64)
    v = len(rest)
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]],
                                              faces[:, [2, 0]]]), axis=1), axis=0)
    length = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    # Strains, not lengths, in the energy: a mesh's density does not change its stiffness.
    scale = 1.0 / np.mean(length) ** 2
    column = {n: j for j, n in enumerate(bone_names)}
    k = np.full(v, HARD_GOAL)
    flesh = np.zeros(v)
    for name, soft in SOFT_GOAL.items():
        w = weights[:, column[name]]
        k = k * (1.0 - w) + np.minimum(k, soft) * w
        flesh += w
    k *= scale
    free = np.nonzero(flesh > 0.05)[0]
    pinned = np.nonzero(flesh <= 0.05)[0]
    a = np.zeros((v, v))
    for i, j in ((0, 0), (1, 1), (0, 1), (1, 0)):
        np.add.at(a, (edges[:, i], edges[:, j]), scale if i == j else -scale)
    a[np.arange(v), np.arange(v)] += k
    a_inv = np.linalg.inv(a[np.ix_(free, free)])
    a_fp = a[np.ix_(free, pinned)]
    # Gravity, the same on every vertex: the softest flesh alone would sink `sag` metres.
    g = np.zeros((v, 3))
    g[:, 1] = -sag * min(SOFT_GOAL.values()) * scale

    def spread(d):  # sum over each vertex's edges of +-d
        return np.stack([np.bincount(edges[:, 0], d[:, c], v) - np.bincount(edges[:, 1], d[:, c], v)
                         for c in range(3)], axis=1)

    out = np.empty_like(poses)
    worst = 0.0
    for i, goal in enumerate(poses):
        x = goal.copy()
        fixed = k[:, None] * goal + g
        boundary = a_fp @ goal[pinned]
        for it in range(ITERATIONS):
            e = x[edges[:, 0]] - x[edges[:, 1]]
            d = e * (length / np.maximum(np.linalg.norm(e, axis=1), 1e-12))[:, None] * scale
            b = (fixed + spread(d))[free] - boundary
            new = a_inv @ b
            step = np.abs(new - x[free]).max()
            x[free] = new
        worst = max(worst, step)
        out[i] = x
    np.save(os.path.join(folder, "pose_vertices.npy"), out.astype("<f4"))
    np.save(os.path.join(folder, "rest_vertices.npy"), out[0].astype("<f4"))
    moved = np.linalg.norm(out - poses, axis=2)
    return (f"soft skin: {len(free)} free vertices, {len(edges)} edge springs, {ITERATIONS} "
            f"iterations (last step {worst:.1e} m), moved from LBS by up to "
            f"{moved.max() * 100:.1f} cm (mean {moved.mean() * 100:.2f} cm; the rest pose sags "
            f"{moved[0].max() * 100:.1f} cm)")


# ---------------------------------------------------------------------------------------------


BUILDERS = {"muscle": build_muscle, "cage": build_cage, "smooth": build_smooth, "soft": build_soft}


def test_action_name(wanted):
    """The action named `wanted`, or the one whose name starts with it (a glb's `Walk` is the
    action `Walk_<armature>`)."""
    names = [a.name for a in bpy.data.actions]
    if wanted in names:
        return wanted
    matches = [n for n in names if n.startswith(wanted)]
    if len(matches) != 1:
        raise RuntimeError(f"no single action named {wanted!r}: {names}")
    return matches[0]


def make_set(name, args):
    """Builds the set `name` into args.out with the options of `args` (main's)."""
    t0 = time.time()
    arm, body = import_character(os.path.abspath(args.glb))
    what = BUILDERS[name](arm, body)
    folder = os.path.join(args.out, f"{args.prefix}_{name}")
    os.makedirs(args.out, exist_ok=True)
    if args.save_blend:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(folder + ".blend"))
    summary = ex.export_examples(bpy.context, folder, poses=args.poses, seed=args.seed,
                                 swing=args.swing, twist=args.twist,
                                 test_action=test_action_name(args.test_action),
                                 mesh=body.name, log=lambda t: say(f"{name}: {t}"))
    if name == "soft":
        bones = [b.name for b in ex.deform_bones(arm)[0]]
        say(f"{name}: " + soften(folder, bones, args.sag))
    say(f"{name}: {what}; {summary} ({time.time() - t0:.0f} s)")


def main(argv):
    import argparse
    p = argparse.ArgumentParser(prog="make_black_boxes.py")
    p.add_argument("--out", required=True)
    p.add_argument("--sets", default=",".join(SETS))
    p.add_argument("--poses", type=int, default=40)
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--glb", default=GLB)
    p.add_argument("--save-blend", action="store_true")
    p.add_argument("--swing", type=float, default=40.0, help="largest swing, degrees (40)")
    p.add_argument("--twist", type=float, default=60.0, help="largest twist, degrees (60)")
    p.add_argument("--sag", type=float, default=SAG,
                   help="soft: how far the softest flesh alone sinks under gravity, metres (0.02)")
    p.add_argument("--prefix", default="cesium", help="the sets' folder prefix (cesium)")
    p.add_argument("--test-action", default=TEST_ACTION, help="held-out action (or its prefix)")
    p.add_argument("--smooth-iterations", type=int, default=20,
                   help="Corrective Smooth iterations of the smooth set (20)")
    args = p.parse_args(argv)
    SMOOTH_ITERATIONS[0] = args.smooth_iterations
    names = [s for s in args.sets.split(",") if s]
    unknown = [s for s in names if s not in BUILDERS]
    if unknown:
        print(f"make_black_boxes: error: unknown set(s) {unknown} (known: {list(SETS)})",
              file=sys.stderr)
        return 1
    for name in names:
        make_set(name, args)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []))
