"""rrskin: learned character deformation at the cost of linear blend skinning.

Build an example set from a rig's poses and meshes (NumPy arrays, or any file ``rrskin train``
reads), train the runtime model, and read it back as arrays::

    import rrskin
    examples = rrskin.ExampleSet(rest, faces, parents, transforms, vertices, split=split)
    model = rrskin.train(examples, budget=1.25)
    mesh = model.deform(transforms[examples.test_poses[0]])   # (V, 3)
    print(model.report["rr_reduced"]["test"])     # held-out EE %, as `rrskin train --json`

Every error is an ``rrskin.Error`` naming the argument or file at fault.
"""

from ._rrskin import Error, ExampleSet, Model, __version__, evaluate, load_set, train

__all__ = ["Error", "ExampleSet", "Model", "evaluate", "load_set", "train", "__version__"]
