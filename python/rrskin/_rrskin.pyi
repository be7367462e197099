"""Types of rrskin's extension module (re-exported by ``rrskin``)."""

from collections.abc import Callable, Sequence
from os import PathLike
from typing import Any, Literal, TypedDict, overload

from typing_extensions import Unpack

import numpy as np
import numpy.typing as npt

__version__: str

_Path = str | PathLike[str]
_Floats = npt.NDArray[np.float32] | npt.NDArray[np.float64]
_Ints = npt.NDArray[np.int32] | npt.NDArray[np.int64]
_Progress = Callable[[str, str, int, int], object]
_Reduction = Literal["auto", "joint-blend", "paper", "delta-mush", "both"]

class TrainOptions(TypedDict, total=False):
    """The CLI's training flags by name (`--palette-budget` is `palette_budget`; each `--no-…`
    flag a boolean of the positive name); absent: the CLI's default, given here."""

    proxies: int  # 60
    influences: int  # 4
    reduction: _Reduction  # "auto"
    epsilon: float | None  # None
    correctives: int  # 0
    proxy_correctives: bool  # True
    proxy_kernels: bool  # False
    up: tuple[float, float, float] | None  # (0, 1, 0); None: no gravity
    delta_mush: bool  # True
    budget: float | None  # 1.25; None: no limit
    palette_budget: float | None  # None
    folds: int  # 4
    gentle_poses: bool  # True

class Error(Exception):
    """Bad input, a failed training or an unreadable file: the message names the argument or
    file, and what is wrong."""

class ExampleSet:
    """A rig's examples: N poses of J bones and the V vertices the rig made of each, over a
    rest mesh of T triangles, split into training and test poses."""

    def __init__(
        self,
        rest_vertices: _Floats,
        faces: _Ints,
        bone_parents: _Ints,
        pose_transforms: _Floats,
        pose_vertices: _Floats,
        split: _Ints | None = None,
        skin_weights: _Floats | None = None,
        bone_names: Sequence[str] | None = None,
    ) -> None: ...
    @property
    def vertex_count(self) -> int: ...
    @property
    def bone_count(self) -> int: ...
    @property
    def pose_count(self) -> int: ...
    @property
    def train_poses(self) -> list[int]: ...
    @property
    def test_poses(self) -> list[int]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def bone_names(self) -> list[str] | None: ...
    @property
    def rest_vertices(self) -> npt.NDArray[np.float64]: ...
    @property
    def faces(self) -> npt.NDArray[np.int64]: ...
    @property
    def bone_parents(self) -> npt.NDArray[np.int64]: ...
    @property
    def pose_transforms(self) -> npt.NDArray[np.float64]: ...
    @property
    def pose_vertices(self) -> npt.NDArray[np.float64]: ...
    @property
    def split(self) -> npt.NDArray[np.int64]: ...
    def save(self, path: _Path) -> None: ...
    def for_file(self, model: Model) -> Model: ...

class Model:
    """A trained runtime model: P proxy bones over J bones, skinning V vertices with K
    influences."""

    @staticmethod
    def load(path: _Path) -> Model: ...
    def save(self, path: _Path) -> None: ...
    @property
    def info(self) -> dict[str, Any]: ...
    @property
    def report(self) -> dict[str, Any] | None: ...
    @overload
    def deform(self, bones: _Floats, normals: Literal[False] = False) -> npt.NDArray[np.float32]: ...
    @overload
    def deform(
        self, bones: _Floats, normals: Literal[True]
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]: ...
    def palette(self, bones: _Floats) -> npt.NDArray[np.float32]: ...
    @property
    def skin(self) -> dict[str, Any]: ...
    def export_gltf(
        self,
        path: _Path,
        rig: _Path | None = None,
        clips: Sequence[str] | None = None,
        fps: float = 30.0,
        tolerance: float = 1e-3,
    ) -> dict[str, Any]: ...

def load_set(
    path: _Path,
    clip: str | None = None,
    cache: _Path | None = None,
    fps: float | None = None,
    test_frames: tuple[float, float] | None = None,
) -> ExampleSet: ...
def train(
    example_set: ExampleSet,
    *,
    progress: _Progress | None = None,
    learning_curve: bool = False,
    **options: Unpack[TrainOptions],
) -> Model: ...
def evaluate(
    example_set: ExampleSet,
    *,
    progress: _Progress | None = None,
    loocv: bool = False,
    diagnose: bool = False,
    learning_curve: bool = True,
    **options: Unpack[TrainOptions],
) -> dict[str, Any]: ...
