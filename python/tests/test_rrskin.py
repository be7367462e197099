"""The Python package against its contract (rrskin/_rrskin.pyi): sets validated as the NumPy
loader validates them, training equal to the CLI's, the CPU reference and the palette an
engine skins with, and errors that name what is wrong. The suite runs it under Debian's
Python and under Blender 4.5's (tools/tests/python.rs)."""

import json
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import rrskin

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "data")


def test_a_set_holds_its_arrays_and_any_layout_reads_alike(arrays, examples):
    assert (examples.vertex_count, examples.bone_count, examples.pose_count) == (160, 3, 36)
    assert examples.test_poses == list(range(28, 36))
    np.testing.assert_array_equal(examples.rest_vertices, arrays["rest_vertices"])
    np.testing.assert_array_equal(examples.pose_transforms, arrays["pose_transforms"])
    np.testing.assert_array_equal(examples.faces, arrays["faces"])
    assert examples.bone_names == ["root", "middle", "tip"]
    # float32 and a non-contiguous view: the same set, to float32's precision.
    strided = np.zeros((36, 160, 6))
    strided[:, :, ::2] = arrays["pose_vertices"]
    other = dict(arrays, pose_vertices=strided[:, :, ::2], faces=arrays["faces"].astype(np.int32))
    other["rest_vertices"] = arrays["rest_vertices"].astype(np.float32)
    assert not other["pose_vertices"].flags["C_CONTIGUOUS"]
    again = rrskin.ExampleSet(**other)
    np.testing.assert_array_equal(again.pose_vertices, arrays["pose_vertices"])
    np.testing.assert_allclose(again.rest_vertices, arrays["rest_vertices"], atol=1e-6)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda a: dict(a, rest_vertices=a["rest_vertices"][:, :2]), "rest_vertices: shape [160, 2], expected (V, 3)"),
        (lambda a: dict(a, faces=a["faces"].astype(float)), "faces: dtype float64, expected an int32 or int64"),
        (lambda a: dict(a, faces=a["faces"].tolist()), "faces: a list, not a NumPy array"),
        (lambda a: dict(a, faces=np.where(a["faces"] == 5, 999, a["faces"])), "has vertex index 999 outside 0..160"),
        (lambda a: dict(a, bone_parents=np.array([-1, 2, 1])), "bone_parents"),
        (lambda a: dict(a, split=np.r_[a["split"][:-1], 2]), "split: pose 35 has split 2"),
        (lambda a: dict(a, bone_names=["root"]), "bone_names: 1 names for 3 bones"),
        (lambda a: dict(a, pose_transforms=a["pose_transforms"][:, :2]), "pose_transforms: shape [36, 2, 3, 4], expected (N, J = 3, 3, 4)"),
    ],
)
def test_a_bad_array_is_refused_naming_it(arrays, change, message):
    with pytest.raises(rrskin.Error, match=message.replace("[", r"\[").replace("(", r"\(").replace(")", r"\)")):
        rrskin.ExampleSet(**change(arrays))


def test_a_number_that_is_not_finite_is_refused_with_its_index(arrays):
    vertices = arrays["pose_vertices"].copy()
    vertices[4, 17, 1] = np.nan
    with pytest.raises(rrskin.Error, match=r"pose_vertices: element \d+ \(\[4, 17, 1\]\) is not finite"):
        rrskin.ExampleSet(**dict(arrays, pose_vertices=vertices))


def test_vertices_that_do_not_follow_the_skin_are_refused(arrays):
    shuffled = arrays["pose_vertices"][:, ::-1]
    with pytest.raises(rrskin.Error, match="pose_vertices is not in the space"):
        rrskin.ExampleSet(**dict(arrays, pose_vertices=np.ascontiguousarray(shuffled)))


def test_a_missing_file_and_a_wrong_option_are_named():
    with pytest.raises(rrskin.Error, match="no_such_set"):
        rrskin.load_set("no_such_set")
    with pytest.raises(rrskin.Error, match="proxie: not an option"):
        rrskin.train(rrskin.load_set(os.path.join(DATA, "cesiumman")), proxie=3)
    with pytest.raises(rrskin.Error, match="reduction: 'fast': expected one of"):
        rrskin.train(rrskin.load_set(os.path.join(DATA, "cesiumman")), reduction="fast")


def test_training_equals_the_cli_on_the_same_set(examples, model, tmp_path):
    examples.save(tmp_path / "set")
    cli = subprocess.run(
        [os.environ["RRSKIN_BIN"], "train", str(tmp_path / "set"), "--proxies", "12", "-o", str(tmp_path / "m.rrs"), "--json"],
        check=True, capture_output=True, text=True,
    )
    figures = json.loads(cli.stdout)
    # The saved set is float32, as the folder layout's files are: the figures agree to that.
    for method in ["rr_reduced", "ssd"]:
        assert model.report[method]["test"] == pytest.approx(figures[method]["test"], rel=1e-3)
    assert model.report["rr_reduced"]["test"] < 0.6 * model.report["ssd"]["test"]
    assert model.info["proxies"] == rrskin.Model.load(tmp_path / "m.rrs").info["proxies"]


def test_the_palette_and_skin_reproduce_the_reference(examples, model):
    bones = examples.pose_transforms[examples.test_poses]
    meshes = model.deform(bones)
    assert meshes.shape == (8, 160, 3) and meshes.dtype == np.float32
    np.testing.assert_array_equal(meshes[2], model.deform(bones[2]))
    # An engine's linear blend skinning of the palette, in NumPy.
    skin = model.skin
    palette = model.palette(bones)
    assert palette.shape == (8, model.info["proxies"] + 3, 3, 4)
    rest = np.c_[skin["rest_positions"], np.ones(160)]
    blended = np.einsum("vk,cvkrs->cvrs", skin["weights"], palette[:, skin["indices"]])
    skinned = np.einsum("cvrs,vs->cvr", blended, rest)
    np.testing.assert_allclose(skinned, meshes, atol=1e-4)
    # Held out, closer to the rig than the rig's own weights are.
    truth = examples.pose_vertices[examples.test_poses]
    lbs = np.einsum("vj,cjrs,vs->cvr", examples_weights(examples), bones, rest)
    assert np.abs(meshes - truth).mean() < np.abs(lbs - truth).mean()


def examples_weights(examples):
    from conftest import weights

    return weights(examples.rest_vertices)


def test_a_model_saved_loads_the_same(examples, model, tmp_path):
    model.save(tmp_path / "m.rrs")
    loaded = rrskin.Model.load(tmp_path / "m.rrs")
    bones = examples.pose_transforms[0]
    np.testing.assert_array_equal(loaded.deform(bones), model.deform(bones))
    assert loaded.report is None and loaded.info == model.info
    assert model.info["cost"]["targets"]["transformed_normals"]["ratio"] <= 1.25
    with pytest.raises(rrskin.Error, match="bones: shape"):
        model.deform(bones[:2])
    glb = model.export_gltf(tmp_path / "m.glb")
    assert (tmp_path / "m.glb").stat().st_size > 0 and glb["joints"] > 0


def test_progress_is_told_and_its_exception_stops_training(examples):
    stages = []
    rrskin.train(examples, proxies=12, progress=lambda *update: stages.append(update))
    assert stages[0][:2] == ("training", "SSD") and len(stages) >= 3

    def stop(label, stage, done, total):
        if stage == "reduction":
            raise ValueError("stopped at the reduction")

    with pytest.raises(ValueError, match="stopped at the reduction"):
        rrskin.train(examples, proxies=12, progress=stop)


def test_ctrl_c_stops_training_and_nothing_is_lost(examples):
    cesium = rrskin.load_set(os.path.join(DATA, "cesiumman"))
    timer = threading.Timer(0.3, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        rrskin.train(cesium)
    timer.join()
    assert time.monotonic() - start < 5.0
    # The interpreter and the package go on.
    assert rrskin.train(examples, proxies=12).info["proxies"] > 0


def test_evaluate_reports_every_method(examples):
    report = rrskin.evaluate(examples, proxies=12, learning_curve=False)
    for method in ["rr_reduced", "ssd", "dqs", "ddm"]:
        assert report[method]["test"] > 0
    assert report["rr_reduced"]["test"] < report["ssd"]["test"]


def test_the_stub_names_what_the_module_has():
    import ast
    import inspect

    stub = ast.parse(open(os.path.join(os.path.dirname(rrskin.__file__), "_rrskin.pyi")).read())
    named = {n.name for n in stub.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    public = {name for name in dir(rrskin._rrskin) if not name.startswith("_")}
    assert named - {"TrainOptions"} == public
    # Every option the stub names is one the module takes: a value of the wrong kind is refused
    # naming it, not as an unknown option.
    typed = next(n for n in stub.body if isinstance(n, ast.ClassDef) and n.name == "TrainOptions")
    options = [a.target.id for a in typed.body if isinstance(a, ast.AnnAssign)]
    assert len(options) == 13
    cesium = rrskin.load_set(os.path.join(DATA, "cesiumman"))
    for name in options:
        with pytest.raises(rrskin.Error) as refused:
            rrskin.train(cesium, **{name: object()})
        assert str(refused.value).startswith(f"{name}: ") and "not an option" not in str(refused.value)
    for function in [rrskin.train, rrskin.evaluate, rrskin.ExampleSet, rrskin.Model.deform]:
        assert inspect.getdoc(function)


def test_a_rig_and_its_cache_train_and_export_over_the_files_vertices(tmp_path):
    rig = os.path.join(DATA, "cesiumman_gltf", "CesiumMan_examples.glb")
    cache = os.path.join(DATA, "cesiumman_gltf", "CesiumMan_examples.pc2")
    examples = rrskin.load_set(rig, clip="examples", cache=cache, fps=24, test_frames=(41, 60))
    assert len(examples.test_poses) == 20
    # The NumPy folder of the same rig is its welded form: the same figures, to float32.
    folder = rrskin.load_set(os.path.join(DATA, "cesiumman"))
    assert examples.vertex_count == folder.vertex_count
    model = rrskin.train(examples, proxies=20, delta_mush=False, proxy_correctives=False)
    on_file = examples.for_file(model)
    assert on_file.info["vertices"] >= model.info["vertices"]
    report = on_file.export_gltf(tmp_path / "m.glb", rig=rig, clips=["examples"])
    assert [c["name"] for c in report["clips"]] == ["examples"]
    assert report["clips"][0]["worst_at_samples"] < 1e-3
    with pytest.raises(rrskin.Error, match="a rig needs --clip"):
        rrskin.load_set(rig)
