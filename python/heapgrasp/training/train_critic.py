"""Fitting, saving and evaluating the grasp critic (:mod:`heapgrasp.planning.critic`
runs it) on data of :mod:`heapgrasp.data.critic`.

:func:`fit_critic` fits a model on feature rows and labels (``linear``: PCA of the crops
and :func:`fit_logistic`; ``cnn``: :func:`heapgrasp.training.critic_net.fit_conv`);
:func:`save_critic` writes it as an ONNX file with its provenance.
:func:`design_matrix` turns scene files into feature rows (each candidate twice, once
per finger assignment: the hand is symmetric) and labels (1 = the object was held).
:func:`cross_validate` fits on all scenes but one fold and predicts the fold, ``folds``
times, grouped by scene so that no scene is on both sides; it reports the area under
the ROC curve of the critic and of the planner's own score, and what the critic does to
the grasps a phase chooses from (:func:`phase_picks`): the planner's candidates at its
threshold ε against those the critic keeps
(:meth:`~heapgrasp.planning.critic.GraspCritic.rescore`).

Needs numpy and the ``onnx`` package (``heapgrasp[train]``); the ``cnn`` model PyTorch
too, imported only when one is fitted.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.grid import GridFrame
from heapgrasp.inference import OnnxNetwork, write_atomically
from heapgrasp.planning.critic import (
    MODELS,
    N_SCALARS,
    GraspCritic,
    _unit,
    candidate_features,
    flip_pose,
)
from heapgrasp.training.critic_net import critic_onnx, fit_conv, with_metadata

__all__ = [
    "Design",
    "auc",
    "cross_validate",
    "design_matrix",
    "evaluation_report",
    "fit_critic",
    "fit_logistic",
    "hull_kind",
    "phase_picks",
    "save_critic",
]

F64 = npt.NDArray[np.float64]


def fit_logistic(x: F64, y: npt.ArrayLike, l2: float = 1.0, iterations: int = 50) -> F64:
    """Logistic regression ``P(y=1) = σ(w·[x, 1])`` by Newton's method, L2 penalty
    ``l2`` on ``w`` (not on the bias). Returns ``w`` with the bias last."""
    t = np.asarray(y, dtype=np.float64)
    if x.ndim != 2 or len(x) != len(t) or len(t) == 0:
        raise ValueError(f"x must be (n, d) with n = len(y) > 0, got {x.shape} and {t.shape}")
    xb = np.hstack([x, np.ones((len(x), 1))])
    w = np.zeros(xb.shape[1])
    reg = np.full(xb.shape[1], l2)
    reg[-1] = 0.0
    for _ in range(iterations):
        prob = 1.0 / (1.0 + np.exp(-np.clip(xb @ w, -30, 30)))
        grad = xb.T @ (prob - t) + reg * w
        hess = (xb * (prob * (1 - prob))[:, None]).T @ xb + np.diag(reg) + 1e-9 * np.eye(len(w))
        step = np.linalg.solve(hess, grad)
        w -= step
        if np.max(np.abs(step)) < 1e-8:
            break
    return w


def fit_critic(
    features: F64,
    labels: npt.ArrayLike,
    *,
    components: int = 32,
    l2: float = 1.0,
    threshold: float = 0.7,
    candidate_epsilon: float = 0.2,
    model: str = "linear",
    epochs: int = 30,
    weight_decay: float = 1e-2,
    seed: int = 0,
) -> GraspCritic:
    """A critic fitted on rows of :func:`~heapgrasp.planning.critic.candidate_features`
    and 0/1 labels: ``linear`` uses ``components`` and ``l2``; ``cnn`` uses ``epochs``,
    ``weight_decay`` and ``seed`` (:func:`~heapgrasp.training.critic_net.fit_conv`,
    needs PyTorch). Building the model's graph needs the ``onnx`` package
    (``heapgrasp[train]``)."""
    if model not in MODELS:
        raise ValueError(f"model must be one of {', '.join(MODELS)}; got {model!r}")
    f = np.asarray(features, dtype=np.float64)
    mean = f.mean(axis=0)
    scale = f.std(axis=0)
    scale[scale < 1e-6] = 1.0
    z = (f - mean) / scale
    n_crop = f.shape[1] - N_SCALARS
    hparams = {
        "threshold": _unit("threshold", threshold),
        "candidate_epsilon": _unit("candidate_epsilon", candidate_epsilon),
    }
    if model == "cnn":
        net = fit_conv(z, labels, epochs=epochs, weight_decay=weight_decay, seed=seed)
        data = critic_onnx(mean, scale, net=net, hparams=hparams, provenance={})
    else:
        _, _, vt = np.linalg.svd(z[:, :n_crop], full_matrices=False)
        comps = vt[: min(components, len(vt))]
        design = np.hstack([z[:, :n_crop] @ comps.T, z[:, n_crop:]])
        w = fit_logistic(design, labels, l2=l2)
        data = critic_onnx(mean, scale, components=comps, weights=w, hparams=hparams, provenance={})
    network = OnnxNetwork.from_bytes(data, kind="grasp-critic", name=f"<fitted {model} critic>")
    return GraspCritic(network, threshold, candidate_epsilon)


def save_critic(
    critic: GraspCritic,
    path: str | os.PathLike[str],
    *,
    command: str,
    metadata: dict[str, Any] | None = None,
) -> Path:
    """Writes ``critic`` as an ONNX file (atomically), its provenance the critic's
    :attr:`~heapgrasp.planning.critic.GraspCritic.metadata` updated with ``metadata``,
    ``command`` and the time. Needs the ``onnx`` package (``heapgrasp[train]``)."""
    meta = dict(critic.metadata)
    meta.update(metadata or {})
    meta.update(
        command=command,
        created=_dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
    )
    hparams = dict(critic.network.hparams)
    hparams.update(threshold=critic.threshold, candidate_epsilon=critic.candidate_epsilon)
    data = with_metadata(critic.network.model_bytes, hparams, meta)
    return write_atomically(data, path)


@dataclass(frozen=True)
class Design:
    """Feature rows, two per candidate (pose, flipped pose), and their groups."""

    features: F64
    labels: F64
    scene: npt.NDArray[np.int64]
    phase: npt.NDArray[np.int64]
    score: F64
    start: npt.NDArray[np.str_]
    """``METHOD_START`` of the candidate's scene, e.g. ``heapgrasp_top``."""

    def __len__(self) -> int:
        return len(self.labels) // 2


def hull_kind(scene: dict[str, Any]) -> str:
    """Whose hulls a scene file holds: its method (files written before ``--method``
    existed are HEAPGrasp's), with ``-stop`` where its phases stopped viewing early
    (``--set stop_below=...`` > 0), so that the picks are reported per kind of hull."""
    method = str(scene["method"]) if "method" in scene else "heapgrasp"
    overrides = json.loads(str(scene["overrides"])) if "overrides" in scene else {}
    if float(overrides.get("stop_below", 0.0)) > 0.0:
        return f"{method}-stop"
    return method


def design_matrix(scenes: Sequence[dict[str, Any]], frame: GridFrame) -> Design:
    """Feature rows of every candidate of ``scenes`` (scene files as loaded by
    :func:`~heapgrasp.data.critic.load_dataset`)."""
    rows, labels, scene_ids, phases, scores, starts = [], [], [], [], [], []
    for si, s in enumerate(scenes):
        bounds = np.concatenate([[0], np.cumsum(s["camera_counts"])])
        tag = f"{hull_kind(s)}_{s['start']}"
        for k in range(len(s["phase"])):
            ph = int(s["phase"][k])
            cams = s["camera_positions"][bounds[ph] : bounds[ph + 1]]
            for pose in (s["pose"][k], flip_pose(s["pose"][k])):
                rows.append(
                    candidate_features(
                        s["grasp_input"][ph],
                        s["high"][ph],
                        frame,
                        pose,
                        float(s["width"][k]),
                        float(s["score"][k]),
                        cams,
                    )
                )
                labels.append(float(s["outcome"][k] == "success"))
                scene_ids.append(si)
                phases.append(ph)
                scores.append(float(s["score"][k]))
                starts.append(tag)
    if not rows:
        raise ValueError("the critic's data has no candidates")
    return Design(
        np.stack(rows),
        np.asarray(labels),
        np.asarray(scene_ids, dtype=np.int64),
        np.asarray(phases, dtype=np.int64),
        np.asarray(scores),
        np.asarray(starts),
    )


def auc(scores: npt.ArrayLike, labels: npt.ArrayLike) -> float:
    """Area under the ROC curve (ties count half); NaN with one class only."""
    s = np.asarray(scores, dtype=np.float64)
    y = np.asarray(labels) > 0.5
    n1, n0 = int(y.sum()), int((~y).sum())
    if n1 == 0 or n0 == 0:
        return float("nan")
    greater = (s[y][:, None] > s[~y][None, :]).sum()
    ties = (s[y][:, None] == s[~y][None, :]).sum()
    return float((greater + 0.5 * ties) / (n1 * n0))


def phase_picks(design: Design, prob: F64, threshold: float, epsilon: float) -> dict[str, Any]:
    """What the critic does to the grasps of each phase (``prob``: one value per
    candidate), per start: phases; the success of the planner's pick (its best
    candidate at ``epsilon``) and of the critic's most probable candidate at
    ``threshold``; the mean success of the candidates each keeps (what eq. 16 picks from,
    a proxy for its pick); phases where each keeps none (the phase ends the scene); and
    the share of phases in which any tried candidate held (what a perfect critic's pick
    would reach)."""
    y = design.labels[::2]
    score = design.score[::2]
    scene = design.scene[::2]
    phase = design.phase[::2]
    start = design.start[::2]
    rows: dict[str, list[list[float]]] = {}
    for key in sorted(set(zip(scene.tolist(), phase.tolist(), strict=True))):
        idx = np.flatnonzero((scene == key[0]) & (phase == key[1]))
        base = idx[score[idx] >= epsilon]
        kept = idx[prob[idx] >= threshold]
        rows.setdefault(str(start[idx[0]]), []).append(
            [
                y[base[np.argmax(score[base])]] if base.size else np.nan,
                y[kept[np.argmax(prob[kept])]] if kept.size else np.nan,
                y[base].mean() if base.size else np.nan,
                y[kept].mean() if kept.size else np.nan,
                float(base.size == 0),
                float(kept.size == 0),
                float(y[idx].max()),
            ]
        )

    def mean(column: F64) -> float | None:  # None when no phase had a candidate
        finite = column[np.isfinite(column)]
        return float(finite.mean()) if finite.size else None

    out: dict[str, Any] = {}
    for name, values in sorted(rows.items()):
        a = np.asarray(values, dtype=np.float64)
        out[f"{name}_start"] = {
            "phases": len(a),
            "planner_pick_success": mean(a[:, 0]),
            "critic_pick_success": mean(a[:, 1]),
            "planner_kept_success": mean(a[:, 2]),
            "critic_kept_success": mean(a[:, 3]),
            "planner_no_candidate": int(a[:, 4].sum()),
            "critic_no_candidate": int(a[:, 5].sum()),
            "any_candidate_success": mean(a[:, 6]),
        }
    return out


def cross_validate(
    design: Design,
    *,
    thresholds: Sequence[float],
    epsilon: float = 0.4,
    folds: int = 5,
    **model: Any,
) -> dict[str, Any]:
    """Grouped ``folds``-fold cross-validation (module docstring); ``model`` are the
    keyword arguments of :func:`fit_critic` (``model``, ``components``, ``l2``,
    ``epochs``, ...)."""
    if folds < 2:
        raise ValueError(f"folds must be >= 2, got {folds}")
    prob = np.zeros(len(design.labels))
    for f in range(folds):
        test = design.scene % folds == f
        if test.all() or not test.any():
            raise ValueError(f"too few scenes ({design.scene.max() + 1}) for {folds} folds")
        critic = fit_critic(design.features[~test], design.labels[~test], **model)
        prob[test] = critic.probability(design.features[test])
    return evaluation_report(design, prob, thresholds, epsilon)


def evaluation_report(
    design: Design, prob: npt.ArrayLike, thresholds: Sequence[float], epsilon: float
) -> dict[str, Any]:
    """The critic's report on ``design`` from its probabilities ``prob`` (one per feature
    row; the two rows of a candidate are averaged): candidates, their success fraction,
    the AUC of the critic and of the planner's score, and :func:`phase_picks` at each
    of ``thresholds``."""
    per_candidate = np.asarray(prob, dtype=np.float64).reshape(-1, 2).mean(axis=1)
    y = design.labels[::2]
    return {
        "candidates": len(design),
        "success_fraction": float(y.mean()),
        "auc_critic": auc(per_candidate, y),
        "auc_planner_score": auc(design.score[::2], y),
        "picks": {f"{t:g}": phase_picks(design, per_candidate, t, epsilon) for t in thresholds},
    }
