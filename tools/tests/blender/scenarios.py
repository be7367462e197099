"""Blender's own exporters, default settings, on a small black-box rig: test scenarios for the
glTF rig + point cache route of rrskin.

    blender -b --factory-startup --python tools/tests/blender/scenarios.py -- --out DIR
        [--glb data/cesiumman_gltf/CesiumMan_examples.glb] [--poses 30] [--seed 0]

The rig (rig.py): CesiumMan imported welded, Armature modifier with Preserve Volume, a
corrective knee shape key driven by the knee's bend, Corrective Smooth. Its action `rom`: the
bind pose on the first frame, then --poses random range-of-motion poses on consecutive
frames, a key on every bone at every frame, 24 fps. Three scenes, each exported with
`bpy.ops.export_scene.gltf` (defaults: GLB, Y-up, UVs and normals, sampled animation):

    start0   frames 0..P   rig.glb         the plain case
    start1   frames 1..P+1 rig_start1.glb  Blender's default start frame (1)
    scaled   frames 0..P   rig_scaled.glb  the armature object at scale 0.01, its bones and
                                           mesh 100 times larger (a character in cm)

and point caches of the deformed mesh (every modifier, shape key and driver):

    mdd_start0.mdd, mdd_start1.mdd  io_shape_mdd, scene fps and range passed explicitly: world
                                    space, Z-up (3.4 writes no Y/Z swap), Blender's welded
                                    vertex order; times are seconds from 0 whatever the start
                                    frame, so mdd_start1's sample 0 (t = 0) is frame 1
    pc2_world.pc2                   io_export_pc2, "Export into Worldspace": world, Y-up,
                                    Blender's vertex order, header start frame and rate
    pc2_object.pc2, pc2_object_scaled.pc2
                                    io_export_pc2 defaults: object space (the mesh object's
                                    own axes and, scaled, its cm), Y-up, Blender's order
    ref.pc2, ref_start1.pc2, ref_scaled.pc2
                                    the aligned reference: the same evaluated positions in
                                    the glTF file's vertex order, world space, Y-up, header
                                    start frame = the scene's first frame, rate 1

and the studio pairs of the start0 and scaled scenes, each exporter at its defaults: rig.fbx and
rig_scaled.fbx, and where Blender has Alembic cache.abc and cache_scaled.abc (dcc_exports); and
numpy/, the NumPy route of the start0 scene (numpy_reference), the reference of both pairs.

The io_export_pc2 operator's range defaults to frames 1..250 (in the UI too: it does not read
the scene's range), so the range is passed; the MDD operator, called from Python, defaults to
25 fps and frames 1..250 (only its UI copies the scene's), so fps and range are passed.

The reference order comes from a second export with an integer point attribute holding the
Blender vertex index (`_blender_index`, written by export_attributes=True as the float
accessor `__BLENDER_INDEX`); its POSITIONs are checked equal to rig.glb's.

manifest.json: {"blender", "fps", "poses", "clip", "blender_vertices", "gltf_vertices",
"rigs": {name: {"start_frame", "end_frame", "test_frames": "A..B", "gltf_vertices"}},
"caches": [{"file", "rig", "format", "fps", "start_frame", "frames", "space", "up",
"vertex_order", "vertices"}]}
"""

import json
import os
import struct
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import rig  # noqa: E402

FPS = 24
Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def log(text):
    print(f"scenarios: {text}", flush=True)


def read_glb(path):
    data = open(path, "rb").read()
    magic, _version, _length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF", path
    offset, doc, binary = 12, None, None
    while offset < len(data):
        length, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8: offset + 8 + length]
        if kind == 0x4E4F534A:
            doc = json.loads(chunk)
        elif kind == 0x004E4942:
            binary = chunk
        offset += 8 + length
    return doc, binary


def accessor(doc, binary, index):
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    comps = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2", 5121: "u1"}[acc["componentType"]]
    item = np.dtype(dtype).itemsize * comps
    stride = view.get("byteStride", item)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    rows = [np.frombuffer(binary, dtype=dtype, count=comps, offset=start + i * stride)
            for i in range(acc["count"])] if stride != item else None
    if rows is None:
        return np.frombuffer(binary, dtype=dtype, count=comps * acc["count"], offset=start).reshape(acc["count"], comps)
    return np.array(rows)


def skinned_primitives(doc):
    node = next(n for n in doc["nodes"] if "skin" in n and "mesh" in n)
    return doc["meshes"][node["mesh"]]["primitives"]


def gltf_attribute(path, name):
    doc, binary = read_glb(path)
    return np.concatenate([accessor(doc, binary, p["attributes"][name]) for p in skinned_primitives(doc)])


def world_positions(mesh):
    dg = bpy.context.evaluated_depsgraph_get()
    ev = mesh.evaluated_get(dg)
    me = ev.to_mesh()
    co = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    mw = np.array(ev.matrix_world)
    return co.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]


def write_pc2(path, samples, start_frame, rate=1.0):
    samples = np.ascontiguousarray(samples, dtype="<f4")
    with open(path, "wb") as f:
        f.write(struct.pack("<12siiffi", b"POINTCACHE2\0", 1, samples.shape[1], float(start_frame),
                            float(rate), samples.shape[0]))
        f.write(samples.tobytes())


def select_only(obj):
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj


def scale_character(arm, mesh, factor=100.0):
    """Bones and mesh `factor` times larger, the armature object 1/factor: same world size."""
    from mathutils import Matrix
    m = Matrix.Scale(factor, 4)
    arm.data.transform(m)
    mesh.data.transform(m, shape_keys=True)
    arm.scale = arm.scale / factor
    bpy.context.view_layer.update()


def point_cache_addons():
    """Enables the MDD and PC2 exporters where Blender bundles them (3.x; 4.2 and later moved
    them to the extensions platform): whether it could."""
    try:
        for module in ("io_shape_mdd", "io_export_pc2"):
            bpy.ops.preferences.addon_enable(module=module)
        return hasattr(bpy.ops.export_shape, "mdd") and hasattr(bpy.ops.export_shape, "pc2")
    except (RuntimeError, AttributeError):
        return False


def build_scene(args, variant):
    arm, mesh = rig.build_rig(args.glb)
    # read_factory_settings (in build_rig) resets the preferences: enable the add-ons here.
    args.point_caches = point_cache_addons()
    if variant == "scaled":
        scale_character(arm, mesh)
    start = 1 if variant == "start1" else 0
    rig.rom_action(arm, args.poses, seed=args.seed, start=start)
    return arm, mesh, start


def export_variant(args, variant, manifest):
    t0 = time.time()
    arm, mesh, start = build_scene(args, variant)
    scene = bpy.context.scene
    end = scene.frame_end
    out = args.out
    suffix = {"start0": "", "start1": "_start1", "scaled": "_scaled"}[variant]
    glb = f"rig{suffix}.glb"
    frames = end - start + 1
    test_first = start + args.poses - args.test_poses + 1
    blender_vertices = len(mesh.data.vertices)

    scene.frame_set(start)
    bpy.ops.export_scene.gltf(filepath=os.path.join(out, glb))
    # The same export with the Blender vertex index as a point attribute: the glTF order.
    attr = mesh.data.attributes.new("_blender_index", 'INT', 'POINT')
    attr.data.foreach_set("value", list(range(blender_vertices)))
    indexed = os.path.join(out, f".indexed{suffix}.glb")
    bpy.ops.export_scene.gltf(filepath=indexed, export_attributes=True)
    mesh.data.attributes.remove(mesh.data.attributes["_blender_index"])
    # Blender 3.4's exporter names the attribute `__BLENDER_INDEX`, 4.x `_BLENDER_INDEX`.
    name = "__BLENDER_INDEX" if bpy.app.version < (4, 0, 0) else "_BLENDER_INDEX"
    order = gltf_attribute(indexed, name)[:, 0]
    plain_positions = gltf_attribute(os.path.join(out, glb), "POSITION")
    if not np.array_equal(gltf_attribute(indexed, "POSITION"), plain_positions):
        raise SystemExit(f"scenarios: error: {glb}: the indexed export's POSITIONs differ")
    os.remove(indexed)
    order = np.rint(order).astype(np.int64)
    assert order.min() >= 0 and order.max() < blender_vertices
    doc, _ = read_glb(os.path.join(out, glb))
    clips = [a.get("name") for a in doc.get("animations", [])]

    # The reference: evaluated world positions, Y-up, glTF order, every frame of the range.
    samples = []
    for frame in range(start, end + 1):
        scene.frame_set(frame)
        samples.append(world_positions(mesh) @ Y_UP.T)
    samples = np.array(samples)
    ref = f"ref{suffix}.pc2"
    write_pc2(os.path.join(out, ref), samples[:, order], start)
    caches = [dict(file=ref, rig=glb, format="pc2", fps=FPS, start_frame=start, frames=frames,
                   space="world", up="Y", vertex_order="gltf", vertices=len(order))]

    select_only(mesh)

    def cache(file, fmt, space, up, **kw):
        caches.append(dict(file=file, rig=glb, format=fmt, fps=FPS, start_frame=start,
                           frames=frames, space=space, up=up, vertex_order="blender",
                           vertices=blender_vertices, **kw))

    if variant in ("start0", "scaled"):
        # The scaled character moves as the plain one does, world space alike: one reference.
        dcc_exports(out, scene, start, end, suffix, cache, manifest)
    if variant == "start0":
        numpy_reference(os.path.join(out, "numpy"), scene, arm, mesh, start, end, test_first)
    if args.point_caches:
        point_caches(out, variant, suffix, start, end, frames, glb, blender_vertices, cache, caches)
    scene.frame_set(start)

    manifest["rigs"][glb] = dict(start_frame=start, end_frame=end, clips=clips,
                                 test_frames=f"{test_first}..{end}", gltf_vertices=len(order),
                                 blender_vertices=blender_vertices)
    manifest["caches"].extend(caches)
    manifest["blender_vertices"] = blender_vertices
    manifest["gltf_vertices"] = len(order)
    manifest["clip"] = clips[0] if clips else None
    log(f"{variant}: {glb} ({len(order)} glTF vertices, {blender_vertices} Blender vertices, "
        f"clips {clips}, frames {start}..{end}) and {', '.join(c['file'] for c in caches)} "
        f"in {time.time() - t0:.1f} s")


def point_caches(out, variant, suffix, start, end, frames, glb, blender_vertices, cache, caches):
    """The MDD and PC2 exports of a variant (Blender 3.x's bundled add-ons)."""
    if variant in ("start0", "start1"):
        name = f"mdd{suffix or '_start0'}.mdd"
        bpy.ops.export_shape.mdd(filepath=os.path.join(out, name), fps=FPS, frame_start=start,
                                 frame_end=end)
        cache(name, "mdd", "world", "Z", times="seconds from 0")
    if variant == "start0":
        # The scene's range set to 1..end after keying the bind pose on frame 0: the MDD holds
        # frames 1..end at times 0..(end-1)/fps, and no sample at the bind pose.
        bpy.ops.export_shape.mdd(filepath=os.path.join(out, "mdd_range1.mdd"), fps=FPS,
                                 frame_start=start + 1, frame_end=end)
        caches.append(dict(file="mdd_range1.mdd", rig=glb, format="mdd", fps=FPS,
                           start_frame=start + 1, frames=frames - 1, space="world", up="Z",
                           vertex_order="blender", vertices=blender_vertices,
                           times="seconds from 0"))
        bpy.ops.export_shape.pc2(filepath=os.path.join(out, "pc2_world.pc2"), world_space=True,
                                 range_start=start, range_end=end)
        cache("pc2_world.pc2", "pc2", "world", "Y")
    if variant in ("start0", "scaled"):
        name = f"pc2_object{suffix}.pc2"
        bpy.ops.export_shape.pc2(filepath=os.path.join(out, name), range_start=start,
                                 range_end=end)
        cache(name, "pc2", "object", "Y")


def dcc_exports(out, scene, start, end, suffix, cache, manifest):
    """The studio pair, each with its exporter's defaults: the rig as FBX (`rig.fbx`: cm, leaf
    bones added, the animation baked and simplified) and, where Blender has Alembic (4.x from
    PyPI; Debian's 3.4 has not), the deformed mesh as an Alembic cache over the scene's range
    (`cache.abc`: Y-up, world transforms above the mesh, Blender's vertex order); `suffix` names
    the variant's pair (`rig_scaled.fbx`, `cache_scaled.abc`: the armature object at 0.01)."""
    fbx, abc = f"rig{suffix}.fbx", f"cache{suffix}.abc"
    bpy.ops.export_scene.fbx(filepath=os.path.join(out, fbx))
    manifest.setdefault("fbx", []).append(fbx)
    if bpy.app.build_options.alembic:
        scene.frame_start, scene.frame_end = start, end
        bpy.ops.wm.alembic_export(filepath=os.path.join(out, abc))
        cache(abc, "abc", "world", "Y", times="seconds")


def numpy_reference(out, scene, arm, mesh, start, end, test_first):
    """The NumPy route of the same rig and frames (export_examples.py's layout, bones and axes):
    the reference of the FBX and Alembic routes, in Blender's vertex order. Pose 0 is the bind
    pose on frame `start`; frames from `test_first` on are held out."""
    ex = rig.export_examples
    bones = ex.skinning_bones(mesh, ex.deform_bones(arm)[0])
    parents = ex.nearest_parents(bones)
    context = bpy.context
    to_y = np.eye(4)
    to_y[:3, :3] = Y_UP
    transforms, vertices = [], []
    scene.frame_set(start)
    rest_inv = np.linalg.inv(ex.bone_worlds(context, arm, bones)[1])
    for frame in range(start, end + 1):
        scene.frame_set(frame)
        posed, _ = ex.bone_worlds(context, arm, bones)
        transforms.append((to_y @ posed @ rest_inv @ np.linalg.inv(to_y))[:, :3, :])
        vertices.append(ex.evaluated_vertices(context, mesh) @ Y_UP.T)
    scene.frame_set(start)
    os.makedirs(out, exist_ok=True)
    f4, i4 = np.dtype("<f4"), np.dtype("<i4")
    save = lambda name, a, t: np.save(os.path.join(out, name), np.ascontiguousarray(a, dtype=t))
    save("rest_vertices.npy", vertices[0], f4)
    save("faces.npy", ex.evaluated_faces(context, mesh), i4)
    save("bone_parents.npy", parents, i4)
    save("pose_transforms.npy", np.array(transforms), f4)
    save("pose_vertices.npy", np.array(vertices), f4)
    save("split.npy", [int(f >= test_first) for f in range(start, end + 1)], i4)
    save("skin_weights.npy", ex.skin_weights(mesh, bones, parents, len(vertices[0])), f4)
    with open(os.path.join(out, "bone_names.json"), "w") as f:
        json.dump([b.name for b in bones], f)


def arguments(prog, argv):
    """The scenario scripts' arguments (this one's and usd_scenarios.py's), the paths absolute
    and the output folder made."""
    import argparse
    p = argparse.ArgumentParser(prog=prog)
    p.add_argument("--out", required=True)
    p.add_argument("--glb", default=os.path.join(HERE, "..", "..", "..", "data", "cesiumman_gltf",
                                                 "CesiumMan_examples.glb"))
    p.add_argument("--poses", type=int, default=30)
    p.add_argument("--test-poses", type=int, default=8)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    args.glb = os.path.abspath(args.glb)
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    return args


def main(argv):
    args = arguments("scenarios.py", argv)
    manifest = dict(blender=bpy.app.version_string, fps=FPS, poses=args.poses + 1, rigs={},
                    caches=[])
    t0 = time.time()
    for variant in ("start0", "start1", "scaled"):
        export_variant(args, variant, manifest)
    with open(os.path.join(args.out, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)
    log(f"wrote {args.out}: {len(manifest['rigs'])} rigs, {len(manifest['caches'])} caches, "
        f"manifest.json, in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
