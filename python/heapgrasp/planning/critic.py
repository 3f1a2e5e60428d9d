"""A learned grasp critic: the probability that a candidate on a measured hull holds an
object, from the hull around it and the views that carved it.

Silhouettes alone cannot tell a roof left by one-sided views from a real top
(``docs/benchmarks.md``, "Verdict"): every bound built from the views was tried and moved
failures between empty grasps and collisions. HEAPGrasp's answer (§V) is a grasp network
trained on such hulls, which learns what the objects under a hull usually look like. The
critic is that idea at the size of a logistic regression, as seed 001 §4 does for its
view policies (PCA of a local volume + logistic regression): it re-scores the analytic
planner's candidates instead of replacing the planner.

Features of a candidate (:func:`candidate_features`):

* two crops in the TCP frame (x across the fingers, y the closing axis, z the
  approach), :data:`CROP_SHAPE` voxels at the grid's voxel size centred at the TCP: the
  planner's input (roofs trimmed) and the untrimmed high-confidence grid ``Ŝ≥λ``; below
  the table counts as occupied;
* the planner's score, the opening, the approach's tilt from straight down, the TCP's
  height, and how far the hull's column at the TCP rises above it;
* the views as seen from the TCP: elevation (min, mean, max), how one-sided they are
  (length of the mean horizontal direction), and how close any comes to grazing the
  contact faces (min and mean ``|d·y|``) or the finger sides (min ``|d·x|``).

The model (:class:`GraspCritic`), after standardisation: either (``linear``) PCA of the
crops and logistic regression with an L2 penalty, fitted by Newton's method, or
(``cnn``) a small 3-D convolutional network on the crops and the scalars
(:mod:`heapgrasp.training.critic_net`; trained with PyTorch). Trained on the train
split's objects with :mod:`heapgrasp.data.critic` (fitted and saved by
:mod:`heapgrasp.training.train_critic`). Either model, its standardisation included, is
one ONNX file holding the command and measurements that made it, run with onnxruntime as
every shipped network (:class:`heapgrasp.inference.OnnxNetwork`); this module only
reads and runs critics. :func:`read_critic_arrays` reads the former ``.npz`` files for
:func:`heapgrasp.training.critic_net.convert_npz`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.inference import OnnxNetwork
from heapgrasp.inference.errors import WeightsError, check_archive
from heapgrasp.planning.volumes import GraspCandidate

__all__ = [
    "ARRAYS",
    "CRITIC_FORMAT",
    "CROP_SHAPE",
    "DEFAULT_CRITIC",
    "MODELS",
    "GraspCritic",
    "WeightsError",
    "candidate_features",
    "crop_in_grasp_frame",
    "read_critic_arrays",
    "view_features",
]

F64 = npt.NDArray[np.float64]

CROP_SHAPE = (7, 13, 12)
"""Crop in voxels along the TCP's x (across the fingers), y (closing) and z (approach):
±3 across, ±6 along the 8 cm opening, from 6 voxels behind the TCP (toward the palm)
to 5 beyond it."""
_CROP_LOW = (-3, -6, -6)

DEFAULT_CRITIC = Path(__file__).resolve().parent.parent / "weights" / "critic.onnx"
"""The critic shipped with the package (``docs/critic.md``)."""

N_SCALARS = 12
_N_FEATURES = 2 * int(np.prod(CROP_SHAPE)) + N_SCALARS

ARRAYS = ("conv1_w", "conv1_b", "conv2_w", "conv2_b", "fc1_w", "fc1_b", "fc2_w", "fc2_b")
"""The ``cnn`` model's arrays, in the order of the fields of
:class:`heapgrasp.training.critic_net.ConvCritic` (``net_<name>`` in a former ``.npz``
file)."""


def cnn_shapes(c1: int, c2: int, hidden: int) -> dict[str, tuple[int, ...]]:
    """Shapes of the CNN critic's arrays for ``c1``, ``c2`` convolution channels and
    ``hidden`` units (the biases ``conv1_b``, ``conv2_b``, ``fc1_b`` set them)."""
    return {
        "conv1_w": (c1, 2, 3, 3, 3),
        "conv2_w": (c2, c1, 3, 3, 3),
        "fc1_w": (hidden, 8 * c2 + N_SCALARS),
        "fc2_w": (1, hidden),
        "fc2_b": (1,),
    }


def _lattice() -> F64:
    axes = [
        np.arange(lo, lo + n, dtype=np.float64) for lo, n in zip(_CROP_LOW, CROP_SHAPE, strict=True)
    ]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    return grid.reshape(-1, 3)


_LATTICE = _lattice()


def _occupied(grid: npt.ArrayLike) -> npt.NDArray[np.bool_]:
    """``grid > 0.5`` (a bool grid as it is, without a copy)."""
    g = np.asarray(grid)
    return g if g.dtype == np.bool_ else np.asarray(g > 0.5)


def crop_in_grasp_frame(grid: npt.ArrayLike, frame: GridFrame, pose: npt.ArrayLike) -> F64:
    """``grid`` (R³, occupied > 0.5) sampled at :data:`CROP_SHAPE` points of the TCP
    frame ``pose`` (nearest voxel); outside the grid 0, below the table 1. Returns the
    flattened crop as 0/1."""
    g = _occupied(grid)
    p = np.asarray(pose, dtype=np.float64)
    if p.shape != (4, 4) or not np.isfinite(p).all():
        raise ValueError(f"pose must be a finite (4, 4) matrix, got shape {p.shape}")
    points = p[:3, 3] + (_LATTICE * frame.voxel_size) @ p[:3, :3].T
    idx = frame.index(points)
    r = g.shape[0]
    inside = np.all((idx >= 0) & (idx < r), axis=1)
    out = np.zeros(len(points))
    out[inside] = g[idx[inside, 0], idx[inside, 1], idx[inside, 2]]
    out[points[:, 2] < frame.origin[2]] = 1.0
    return out


def view_features(pose: npt.ArrayLike, cameras: npt.ArrayLike) -> F64:
    """The views seen from the TCP of ``pose``: elevation min, mean, max (rad); length
    of the mean horizontal direction; min and mean ``|d·y|``; min ``|d·x|``."""
    p = np.asarray(pose, dtype=np.float64)
    cams = np.asarray(cameras, dtype=np.float64).reshape(-1, 3)
    if len(cams) == 0:
        raise ValueError("view_features needs at least one camera position")
    d = cams - p[:3, 3]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
    elev = np.arcsin(np.clip(d[:, 2], -1.0, 1.0))
    horiz = d[:, :2] / np.maximum(np.linalg.norm(d[:, :2], axis=1, keepdims=True), 1e-9)
    dy = np.abs(d @ p[:3, 1])
    dx = np.abs(d @ p[:3, 0])
    return np.array(
        [
            elev.min(),
            elev.mean(),
            elev.max(),
            float(np.linalg.norm(horiz.mean(axis=0))),
            dy.min(),
            dy.mean(),
            dx.min(),
        ]
    )


def _column_rise(grid: npt.NDArray[np.bool_], frame: GridFrame, pose: F64) -> float:
    """Height (m) of the hull's top in the TCP's column above the TCP (0 if empty)."""
    i, j, _ = frame.index(pose[:3, 3])
    r = grid.shape[0]
    if not (0 <= i < r and 0 <= j < r):
        return 0.0
    col = np.flatnonzero(grid[i, j])
    if col.size == 0:
        return 0.0
    top = frame.origin[2] + (col[-1] + 1) * frame.voxel_size
    return float(top - pose[2, 3])


def candidate_features(
    grasp_input: npt.ArrayLike,
    high: npt.ArrayLike,
    frame: GridFrame,
    pose: npt.ArrayLike,
    width: float,
    score: float,
    cameras: npt.ArrayLike,
) -> F64:
    """The feature vector of one candidate: the two crops, then :data:`N_SCALARS`
    scalars (see the module docstring)."""
    p = np.asarray(pose, dtype=np.float64)
    g = _occupied(grasp_input)
    h = _occupied(high)
    if g.shape != h.shape or g.shape != (frame.resolution,) * 3:
        raise ValueError(
            f"grids must both have shape {(frame.resolution,) * 3}, got {g.shape} and {h.shape}"
        )
    tilt = math.acos(float(np.clip(-p[2, 2], -1.0, 1.0)))
    scalars = np.concatenate(
        [
            [
                score,
                width / PANDA_HAND.max_opening,
                tilt,
                (p[2, 3] - frame.origin[2]) / frame.size,
                _column_rise(g, frame, p) / frame.size,
            ],
            view_features(p, cameras),
        ]
    )
    return np.concatenate(
        [crop_in_grasp_frame(g, frame, p), crop_in_grasp_frame(h, frame, p), scalars]
    )


def flip_pose(pose: npt.ArrayLike) -> F64:
    """The same grasp with the fingers swapped (a half turn about the approach axis):
    the Panda's hand is symmetric, so both poses are the same grasp."""
    p = np.array(pose, dtype=np.float64)
    p[:3, 0] *= -1.0
    p[:3, 1] *= -1.0
    return p


MODELS = ("linear", "cnn")
"""The critic's model kinds (module docstring)."""


def _unit(name: str, value: float) -> float:
    v = float(value)
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{name} must be in [0, 1], got {value}")
    return v


@dataclass
class GraspCritic:
    """A critic model (:data:`MODELS`) as an ONNX network from feature rows
    (:func:`candidate_features`) to logits, with the thresholds it is used with (module
    docstring). Built by :meth:`load` (or, in training,
    :func:`heapgrasp.training.train_critic.fit_critic`)."""

    network: OnnxNetwork
    """The model, standardisation included: ``features`` ``(B, F)`` → ``logits``."""
    threshold: float = 0.7
    """Candidates below this probability are dropped (:meth:`rescore`): the critic's ε."""
    candidate_epsilon: float = 0.2
    """Threshold ε on the analytic planner's score for the candidates the critic sees
    (the data's, :class:`~heapgrasp.data.critic.CriticDataConfig`)."""
    metadata: dict[str, Any] = field(default_factory=dict)
    """What made it (command, data, cross-validation, ...): the file's provenance."""

    @property
    def model(self) -> str:
        """``"linear"`` or ``"cnn"``."""
        return str(self.network.hparams["model"])

    def __post_init__(self) -> None:
        if not isinstance(self.network, OnnxNetwork) or self.network.kind != "grasp-critic":
            raise ValueError(f"network must be a grasp-critic OnnxNetwork, got {self.network!r}")
        self.threshold = _unit("threshold", self.threshold)
        self.candidate_epsilon = _unit("candidate_epsilon", self.candidate_epsilon)

    # ------------------------------------------------------------------ model
    def probability(self, features: npt.ArrayLike) -> F64:
        """``P(success)`` of each row of ``features`` (:func:`candidate_features`)."""
        f = np.atleast_2d(np.asarray(features, dtype=np.float64))
        if f.ndim != 2 or f.shape[1] != _N_FEATURES:
            raise ValueError(f"features must have {_N_FEATURES} columns, got shape {f.shape}")
        if len(f) == 0:
            return np.zeros(0)
        (logit,) = self.network.run(f.astype(np.float32))
        z = np.clip(logit.astype(np.float64), -30, 30)
        return np.asarray(1.0 / (1.0 + np.exp(-z)))

    # ------------------------------------------------------------------ use
    def score_candidates(
        self,
        candidates: Sequence[GraspCandidate],
        grasp_input: npt.ArrayLike,
        high: npt.ArrayLike,
        frame: GridFrame,
        cameras: npt.ArrayLike,
    ) -> F64:
        """``P(success)`` of each candidate (both finger assignments averaged)."""
        if not candidates:
            return np.zeros(0)
        grasp_input, high = _occupied(grasp_input), _occupied(high)  # once for all rows
        rows = []
        for c in candidates:
            for pose in (c.pose, flip_pose(c.pose)):
                rows.append(
                    candidate_features(grasp_input, high, frame, pose, c.width, c.score, cameras)
                )
        prob = self.probability(np.stack(rows))
        return np.asarray(prob.reshape(-1, 2).mean(axis=1))

    def rescore(
        self,
        candidates: Sequence[GraspCandidate],
        grasp_input: npt.ArrayLike,
        high: npt.ArrayLike,
        frame: GridFrame,
        cameras: npt.ArrayLike,
    ) -> list[GraspCandidate]:
        """The critic as the grasp quality of eq. 15: each candidate's score becomes its
        probability of success, those below :attr:`threshold` are dropped, the rest are
        returned best first (so eq. 16 picks among grasps the critic trusts)."""
        if not candidates:
            return []
        prob = self.score_candidates(candidates, grasp_input, high, frame, cameras)
        kept = [
            dataclasses.replace(c, score=float(p))
            for c, p in zip(candidates, prob, strict=True)
            if p >= self.threshold
        ]
        return sorted(kept, key=lambda c: -c.score)

    # ------------------------------------------------------------------ files
    @classmethod
    def load(cls, path: str | os.PathLike[str], *, device: str = "cpu") -> GraspCritic:
        """Reads a critic file (ONNX, ``kind`` ``grasp-critic``), checked whole: a missing
        file raises :class:`FileNotFoundError`, any other bad file a
        :class:`~heapgrasp.inference.errors.WeightsError` naming the file and the problem
        (:class:`~heapgrasp.inference.OnnxNetwork`; and a model, crop shape, feature
        count, threshold or ε other than this heapgrasp's)."""
        network = OnnxNetwork(path, kind="grasp-critic", device=device)
        p, hp = network.path, network.hparams
        for key, want in (
            ("model", None),
            ("crop_shape", list(CROP_SHAPE)),
            ("n_features", _N_FEATURES),
        ):
            if key not in hp:
                raise WeightsError(p, f"hparams field {key!r} missing")
            if want is not None and hp[key] != want:
                raise WeightsError(p, f"hparams field {key!r} is {hp[key]!r}, expected {want!r}")
        if hp["model"] not in MODELS:
            raise WeightsError(p, f"hparams field 'model' is {hp['model']!r}, not one of {MODELS}")
        values = {}
        for key in ("threshold", "candidate_epsilon"):
            value = hp.get(key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise WeightsError(p, f"hparams field {key!r} is {value!r}, not a number")
            if not 0.0 <= value <= 1.0:
                raise WeightsError(
                    p, f"hparams field {key!r} is {value}, expected a number in [0, 1]"
                )
            values[key] = float(value)
        return cls(network, values["threshold"], values["candidate_epsilon"], network.provenance)


# --------------------------------------------------------------------------- former files

CRITIC_FORMAT = "heapgrasp-critic"
"""``format`` entry of a former ``.npz`` critic file."""


def _describe(a: npt.NDArray[Any]) -> str:
    return f"{a.dtype} array of shape {a.shape}"


def _open_npz(p: Path) -> dict[str, npt.NDArray[Any]]:
    """Every array of the ``.npz`` file ``p``, the file checked first
    (:func:`~heapgrasp.inference.errors.check_archive`); the members must be ``.npy``
    arrays without pickles."""
    if not p.exists():
        raise FileNotFoundError(f"grasp critic file not found: {p}")
    check_archive(p, "grasp critic file (.npz)")
    try:
        with np.load(p, allow_pickle=False) as data:
            return {k: np.asarray(data[k]) for k in data.files}
    except (OSError, EOFError, ValueError, zipfile.BadZipFile) as exc:
        raise WeightsError(p, f"cannot read its arrays ({_detail(exc)})") from exc


def _detail(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _get(
    p: Path, arrays: dict[str, npt.NDArray[Any]], name: str, kinds: str, what: str
) -> npt.NDArray[Any]:
    """``arrays[name]``, its dtype's kind one of ``kinds`` (numpy's letters)."""
    if name not in arrays:
        raise WeightsError(p, f"missing key {name!r}")
    a = arrays[name]
    if a.dtype.kind not in kinds:
        raise WeightsError(p, f"dtype of {name!r} is {a.dtype}, expected {what}")
    return a


def _floats(
    p: Path, arrays: dict[str, npt.NDArray[Any]], name: str, shape: tuple[int, ...] | int
) -> npt.NDArray[Any]:
    """A finite floating-point array of ``shape`` (or of ``shape`` dimensions)."""
    a = _get(p, arrays, name, "f", "a floating-point array")
    if isinstance(shape, int):
        if a.ndim != shape:
            raise WeightsError(p, f"{name!r} is {_describe(a)}, expected {shape} dimensions")
    elif a.shape != shape:
        raise WeightsError(p, f"shape of {name!r} is {a.shape}, expected {shape}")
    for label, bad in (("NaN", np.isnan(a)), ("infinity", np.isinf(a))):
        if bad.any():
            first = tuple(int(i) for i in np.argwhere(bad)[0])
            raise WeightsError(
                p,
                f"{label} in {name!r} ({int(bad.sum())} of {a.size} values, first at "
                f"index {first[0] if len(first) == 1 else first})",
            )
    return a


def _scalar(p: Path, arrays: dict[str, npt.NDArray[Any]], name: str, kinds: str) -> Any:
    what = {"U": "a string", "iu": "an integer", "fiu": "a number"}[kinds]
    a = _get(p, arrays, name, kinds, what)
    if a.shape != ():
        raise WeightsError(p, f"{name!r} is {_describe(a)}, expected {what}")
    return a.item()


def read_critic_arrays(
    path: str | os.PathLike[str],
) -> tuple[dict[str, npt.NDArray[Any]], dict[str, Any]]:
    """The arrays and the metadata of the former ``.npz`` critic file ``path`` (the input
    of :func:`heapgrasp.training.critic_net.convert_npz`), checked whole: the file
    (:class:`FileNotFoundError` if missing), ``format`` and ``version``, every array's
    presence, dtype (floating point), shape and finite values, the scale of each feature
    (> 0: features are divided by it), ``threshold`` and ``candidate_epsilon`` in [0, 1],
    and the metadata (a JSON object whose ``model`` and ``crop_shape`` are this file's).
    Anything wrong raises :class:`~heapgrasp.inference.errors.WeightsError` naming ``path``
    and what is wrong."""
    p = Path(path)
    arrays = _open_npz(p)
    fmt = _scalar(p, arrays, "format", "U")
    if fmt != CRITIC_FORMAT:
        raise WeightsError(p, f"format is {fmt!r}, not a heapgrasp critic ({CRITIC_FORMAT!r})")
    version = _scalar(p, arrays, "version", "iu")
    if version not in (1, 2):
        raise WeightsError(p, f"unsupported critic version {version} (this heapgrasp reads 1, 2)")
    n = _N_FEATURES
    n_crop = n - N_SCALARS
    _floats(p, arrays, "mean", (n,))
    scale = _floats(p, arrays, "scale", (n,))
    bad = np.flatnonzero(scale <= 0)
    if bad.size:
        raise WeightsError(
            p,
            f"zero or negative scale: {bad.size} of {n} values of 'scale' are <= 0 (first "
            f"at index {int(bad[0])}: {scale[bad[0]]}); features are divided by their scale",
        )
    components = _floats(p, arrays, "components", 2)
    k = components.shape[0]
    _floats(p, arrays, "components", (k, n_crop))
    _floats(p, arrays, "weights", (k + N_SCALARS + 1,))
    for name in ("threshold", "candidate_epsilon"):
        value = float(_scalar(p, arrays, name, "fiu"))
        if not 0.0 <= value <= 1.0:
            raise WeightsError(p, f"{name!r} is {value}, expected a number in [0, 1]")
    if version == 2:
        names = {k: f"net_{k}" for k in ARRAYS}
        c1 = len(_floats(p, arrays, names["conv1_b"], 1))
        c2 = len(_floats(p, arrays, names["conv2_b"], 1))
        hidden = len(_floats(p, arrays, names["fc1_b"], 1))
        for name, shape in cnn_shapes(c1, c2, hidden).items():
            _floats(p, arrays, names[name], shape)
    meta = _metadata(p, arrays, "linear" if version == 1 else "cnn")
    return arrays, meta


def _metadata(p: Path, arrays: dict[str, npt.NDArray[Any]], model: str) -> dict[str, Any]:
    text = _scalar(p, arrays, "metadata", "U")
    try:
        meta = json.loads(text)
    except json.JSONDecodeError as exc:
        raise WeightsError(p, f"metadata is not valid JSON: {exc}") from exc
    if not isinstance(meta, dict):
        raise WeightsError(p, f"metadata is a JSON {type(meta).__name__}, not an object")
    for key, want in (("model", model), ("crop_shape", list(CROP_SHAPE))):
        if key not in meta:
            raise WeightsError(p, f"metadata field {key!r} missing")
        if meta[key] != want:
            raise WeightsError(p, f"metadata field {key!r} is {meta[key]!r}, expected {want!r}")
    return meta
