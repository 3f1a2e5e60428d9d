"""Natarajan et al.'s learned viewsphere policies (§4.3): the state vector, the policy files and
the policy that runs them.

**The state** (:func:`state_features`, ``2n² + 2`` values, n = 5): height-accumulated
features (HAF) of the object's points and of the unexplored points on an ``n × n``
grid, then the camera's polar and azimuth angles (radians). The grid is a square about
the object's points, 1.25 times their largest half extent (at least 2 cm), aligned with
the camera: its rows run from the far side toward the camera's side, its columns from
west to east (the directions N/E/S/W are the camera's, so the grid is too). An object
cell holds the highest point above the table there (m); an unexplored cell holds the
share of the unexplored points over the square (in the object's box,
:meth:`~heapgrasp.viewsphere.heuristics.ViewsphereScorer.targets`) that fall in it.
Without object points the grids are zero.

**A policy file** is an ONNX model of kind ``viewsphere-policy``
(:mod:`heapgrasp.inference`): ``state`` ``(B, 52)`` → ``scores`` ``(B, 8)``, a stack
of dense layers with ReLU between them (:func:`policy_onnx`). PCA + logistic regression
and PCA + LDA are one layer (the standardisation, the projection and the classifier's
decision function folded together: exact, as all are linear); the deep Q-network is four
hidden layers of 128 and its 8 Q-values. Building a file needs the ``onnx`` package
(``pip install 'heapgrasp[train]'``); running one needs onnxruntime only.

:class:`LearnedPolicy` takes the best-scoring direction whose step does not fall back
onto another's and does not return to a view already taken.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.inference import (
    FORMAT_VERSION,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_VERSION,
    SHIPPED_VIEWSPHERE_POLICIES,
    OnnxNetwork,
    require_onnx,
    seal,
    weights_dir,
)
from heapgrasp.viewsphere.heuristics import ViewsphereScorer
from heapgrasp.viewsphere.policies import ViewState
from heapgrasp.viewsphere.sphere import DIRECTIONS, DiscreteViewsphere, SpherePose

__all__ = [
    "GRID",
    "MODELS",
    "N_FEATURES",
    "LearnedPolicy",
    "policy_onnx",
    "shipped_policy",
    "state_features",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]

#: The HAF grid's side (the paper's n = 5).
GRID = 5
#: The state's length, ``2n² + 2``.
N_FEATURES = 2 * GRID * GRID + 2
#: The learned policies' models.
MODELS = ("pca-lr", "pca-lda", "dqn", "imitation")
#: The ONNX opset of policy files.
OPSET = 17
#: The grid's half side over the object's half extent, and its least half side (m).
_MARGIN = 1.25
_MIN_HALF = 0.02


def state_features(
    obj: F64,
    unexplored: F64,
    pose: SpherePose,
    sphere: DiscreteViewsphere,
    *,
    grid: int = GRID,
) -> F32:
    """The state vector of the views (module doc): ``(2 grid² + 2,)`` float32.
    ``unexplored`` is already restricted to the object's box."""
    c = np.asarray(sphere.centre)
    a = pose.azimuth
    toward = np.array([math.cos(a), math.sin(a)])
    east = np.array([-math.sin(a), math.cos(a)])
    out = np.zeros(2 * grid * grid + 2, dtype=np.float32)
    out[-2:] = (pose.polar, pose.azimuth % (2 * math.pi))
    if len(obj) == 0:
        return out

    def plane(points: F64) -> F64:
        rel = points[:, :2] - c[:2]
        return np.column_stack([rel @ toward, rel @ east])

    st = plane(obj)
    lo, hi = st.min(axis=0), st.max(axis=0)
    middle = (lo + hi) / 2
    half = max(_MARGIN * float(np.max(hi - lo)) / 2, _MIN_HALF)
    cell = 2 * half / grid

    def cells(points: F64) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.bool_]]:
        ij = np.floor((plane(points) - (middle - half)) / cell).astype(np.int64)
        inside = np.all((ij >= 0) & (ij < grid), axis=1)
        return ij[:, 0] * grid + ij[:, 1], inside

    k, inside = cells(obj)
    heights = np.zeros(grid * grid)
    np.maximum.at(heights, k[inside], obj[inside, 2] - c[2])
    out[: grid * grid] = heights
    if len(unexplored):
        k, inside = cells(unexplored)
        counts = np.bincount(k[inside], minlength=grid * grid).astype(np.float64)
        if counts.sum() > 0:
            out[grid * grid : 2 * grid * grid] = counts / counts.sum()
    return out


def policy_onnx(
    layers: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    hparams: Mapping[str, Any],
    provenance: Mapping[str, Any],
) -> bytes:
    """A policy file's bytes (module doc): dense ``layers`` ``(W (out, in), b (out,))``
    with ReLU between them, from ``state`` ``(B, W₀.shape[1])`` to ``scores`` ``(B, 8)``.
    ``hparams`` (``model``, ...) get ``n_features`` and ``grid`` added. Needs ``onnx``."""
    onnx = require_onnx("building a viewsphere policy file")
    from onnx import TensorProto, helper, numpy_helper

    if not layers:
        raise ValueError("a policy needs at least one layer")
    ws = [np.asarray(w, dtype=np.float64) for w, _ in layers]
    bs = [np.asarray(b, dtype=np.float64) for _, b in layers]
    n_in = ws[0].shape[1] if ws[0].ndim == 2 else -1
    width = n_in
    for i, (w, b) in enumerate(zip(ws, bs, strict=True)):
        if w.ndim != 2 or w.shape[1] != width or b.shape != (w.shape[0],):
            raise ValueError(
                f"layer {i}: weights {w.shape} and bias {b.shape} do not follow a width {width}"
            )
        if not (np.isfinite(w).all() and np.isfinite(b).all()):
            raise ValueError(f"layer {i} holds NaN or infinity")
        width = w.shape[0]
    if width != len(DIRECTIONS):
        raise ValueError(f"the last layer must give {len(DIRECTIONS)} scores, gives {width}")
    inits, nodes = [], []
    x = "state"
    for i, (w, b) in enumerate(zip(ws, bs, strict=True)):
        inits += [
            numpy_helper.from_array(w.astype(np.float32), f"w{i}"),
            numpy_helper.from_array(b.astype(np.float32), f"b{i}"),
        ]
        last = i == len(ws) - 1
        y = "scores" if last else f"h{i}"
        nodes.append(helper.make_node("Gemm", [x, f"w{i}", f"b{i}"], [y], transB=1))
        if not last:
            nodes.append(helper.make_node("Relu", [y], [f"r{i}"]))
            y = f"r{i}"
        x = y
    graph = helper.make_graph(
        nodes,
        "heapgrasp-viewsphere-policy",
        [helper.make_tensor_value_info("state", TensorProto.FLOAT, ["batch", n_in])],
        [helper.make_tensor_value_info("scores", TensorProto.FLOAT, ["batch", len(DIRECTIONS)])],
        inits,
    )
    proto = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="heapgrasp"
    )
    hp = {**dict(hparams), "n_features": int(n_in), "grid": GRID}
    meta = {
        META_KIND: "viewsphere-policy",
        META_VERSION: str(FORMAT_VERSION),
        META_HPARAMS: json.dumps(hp, sort_keys=True, allow_nan=False),
        META_PROVENANCE: json.dumps(dict(provenance), sort_keys=True, allow_nan=False),
    }
    for key, value in meta.items():
        entry = proto.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(proto, full_check=True)
    data: bytes = seal(proto.SerializeToString())
    return data


def shipped_policy(model: str) -> Path | None:
    """The shipped file of a learned policy (``pca-lr``, ``pca-lda``, ``dqn``), or None
    when none ships."""
    if model not in SHIPPED_VIEWSPHERE_POLICIES:
        raise ValueError(f"model must be one of {', '.join(MODELS)}; got {model!r}")
    p = weights_dir() / SHIPPED_VIEWSPHERE_POLICIES[model]
    return p if p.is_file() else None


@dataclass
class LearnedPolicy:
    """A learned policy (module doc) run from its file."""

    network: OnnxNetwork
    scorer: ViewsphereScorer
    name: str = "learned"

    def __post_init__(self) -> None:
        if self.network.kind != "viewsphere-policy":
            raise ValueError(f"{self.network.path}: a {self.network.kind}, not a viewsphere policy")
        n = self.network.hparams.get("n_features")
        if n != N_FEATURES or self.network.hparams.get("grid") != GRID:
            raise ValueError(
                f"{self.network.path}: a policy of {n} features on a grid of "
                f"{self.network.hparams.get('grid')}; this version computes {N_FEATURES} on "
                f"{GRID}"
            )

    @classmethod
    def from_file(
        cls, path: str | Path, scorer: ViewsphereScorer, name: str | None = None
    ) -> LearnedPolicy:
        """The policy in ``path`` (FileNotFoundError or WeightsError naming it)."""
        network = OnnxNetwork(path, kind="viewsphere-policy", threads=1)
        return cls(network, scorer, name or str(network.hparams.get("model", "learned")))

    def reset(self, seed: int) -> None:
        pass

    def state(self, state: ViewState) -> F32:
        """The state vector of ``state``'s views."""
        obj, unexplored = state.fused()
        return state_features(obj, self.scorer.targets(unexplored), state.pose, self.scorer.sphere)

    def scores(self, state: ViewState) -> F32:
        """The network's 8 scores."""
        out: F32 = self.network.run(self.state(state)[None])[0][0]
        return out

    def choose(self, state: ViewState) -> int:
        """The best-scoring direction whose step neither falls back onto another's nor
        returns to a view already taken (within half a step of one: it would add nothing
        the fused state lacks, and a state without the views' history cannot tell); where
        every step returns, the best of them."""
        scores = self.scores(state)
        steps = self.scorer.next_views(state.pose)
        sphere = self.scorer.sphere
        fresh = [
            d
            for d, nxt in steps
            if all(sphere.arc(nxt, seen) >= 0.5 * sphere.step for seen in state.visited)
        ]
        valid = fresh or [d for d, _ in steps] or list(range(len(DIRECTIONS)))
        return max(valid, key=lambda d: (float(scores[d]), -d))
