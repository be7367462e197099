"""A small rig made in NumPy: a bending tube of three bones, skinned by smooth weights with a
bulge at the bends that linear blend skinning cannot make (so training has something to learn)."""

import numpy as np
import pytest

RINGS, SEGMENTS, BONES, POSES, TEST = 16, 10, 3, 36, 8


def rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def tube():
    """Rest vertices (V, 3) along +Y from 0 to BONES, and triangles (T, 3)."""
    y = np.linspace(0.0, BONES, RINGS)
    a = np.linspace(0.0, 2 * np.pi, SEGMENTS, endpoint=False)
    rest = np.array([[0.3 * np.cos(t), h, 0.3 * np.sin(t)] for h in y for t in a])
    faces = []
    for r in range(RINGS - 1):
        for s in range(SEGMENTS):
            i, j = r * SEGMENTS + s, r * SEGMENTS + (s + 1) % SEGMENTS
            faces += [[i, i + SEGMENTS, j], [j, i + SEGMENTS, j + SEGMENTS]]
    return rest, np.array(faces, dtype=np.int64)


def weights(rest):
    """(V, J): each vertex between its two nearest joints, smoothly."""
    centre = np.arange(BONES) + 0.5
    w = np.exp(-((rest[:, 1:2] - centre[None, :]) ** 2) / 0.25)
    return w / w.sum(axis=1, keepdims=True)


def pose(rng):
    """(J, 3, 4): each bone's transform relative to the rest pose, each joint bent at random."""
    world = np.eye(4)
    out = []
    for b in range(BONES):
        bend = rotation(rng.normal(size=3) * [1, 0.3, 1], rng.uniform(-1.0, 1.0))
        local = np.eye(4)
        local[:3, :3] = bend
        pivot = np.eye(4)
        pivot[1, 3] = b
        world = world @ pivot @ local @ np.linalg.inv(pivot)
        out.append(world[:3].copy())
    return np.array(out)


def deformed(rest, w, bones):
    """The rig: linear blend skinning and a bulge of each vertex out from the axis, growing
    with how far its joint bends."""
    homogeneous = np.c_[rest, np.ones(len(rest))]
    lbs = np.einsum("vj,jrc,vc->vr", w, bones, homogeneous)
    bends = np.array([np.arccos(np.clip((np.trace(b[:, :3]) - 1) / 2, -1, 1)) for b in bones])
    bulge = 0.15 * (w * bends[None, :]).sum(axis=1, keepdims=True)
    radial = rest * [1, 0, 1]
    moved = np.einsum("vj,jrc,vc->vr", w, bones[:, :, :3], radial)
    return lbs + bulge * moved


@pytest.fixture(scope="session")
def arrays():
    """The tube's arrays, as rrskin.ExampleSet takes them."""
    rng = np.random.default_rng(7)
    rest, faces = tube()
    w = weights(rest)
    transforms = np.array([pose(rng) for _ in range(POSES)])
    vertices = np.array([deformed(rest, w, t) for t in transforms])
    split = np.r_[np.zeros(POSES - TEST), np.ones(TEST)].astype(np.int64)
    return dict(
        rest_vertices=rest,
        faces=faces,
        bone_parents=np.array([-1, 0, 1], dtype=np.int64),
        pose_transforms=transforms,
        pose_vertices=vertices,
        split=split,
        skin_weights=w,
        bone_names=["root", "middle", "tip"],
    )


@pytest.fixture(scope="session")
def examples(arrays):
    import rrskin

    return rrskin.ExampleSet(**arrays)


@pytest.fixture(scope="session")
def model(examples):
    import rrskin

    return rrskin.train(examples, proxies=12)
