"""How well a view network stands in for the exact eq. 14 scores: the metrics of
:func:`heapgrasp.training.train_views.evaluate` (loss, Spearman ρ, top-1 regret) plus how often
eq. 18's choice on the network's scores is the oracle's (HEAPGrasp §IV-B).

Eq. 18 picks ``argmax s + γ2 h`` with ``h`` the progress towards the target grasp (eq. 19);
:func:`selection_agreement` runs :func:`~heapgrasp.planning.selection.select_next_waypoint`
on both maps with each sample's camera pose and target and counts the samples where both
choose the same pose (the ``θ = 0`` candidates are one pose for every ``u``). At
``γ2 = 0`` that is the top-1 agreement of the maps; at ``γ2 = 0.35`` (Table I) the samples
without a target use eq. 18 with ``s`` alone, as the loop does before its first grasp.

Evaluates a network in training (needs PyTorch); eq. 18 itself is the planning layer's
(:mod:`heapgrasp.planning.selection`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import torch

from heapgrasp.planning.selection import select_next_waypoint
from heapgrasp.training.models import ViewNet
from heapgrasp.training.train_views import loss_fn, predict, ranking_metrics
from heapgrasp.training.view_data import ViewDataset

__all__ = ["GAMMA2", "evaluate", "selection_agreement"]

F64 = npt.NDArray[np.float64]

#: γ2 values the report compares at: eq. 18 without and with Table I's progress term.
GAMMA2 = (0.0, 0.35)


def _same_pose(a: tuple[int, int], b: tuple[int, int]) -> bool:
    return a == b or (a[1] == 0 and b[1] == 0)


def selection_agreement(
    pred: npt.ArrayLike,
    labels: npt.ArrayLike,
    candidates: npt.ArrayLike,
    current: npt.ArrayLike,
    target: npt.ArrayLike,
    gamma2: float,
    gamma1: float = 0.2,
) -> F64:
    """Per sample, 1.0 where eq. 18 picks the same candidate pose on ``pred`` as on
    ``labels``, else 0.0.

    Parameters
    ----------
    pred, labels
        ``(N, U, V)`` network and exact scores.
    candidates
        ``(U, V, 4, 4)`` candidates of eq. 12 (``v = 0`` is θ = 0: one pose).
    current
        ``(N, 4, 4)`` camera poses the samples were scored from.
    target
        ``(N, 4, 4)`` target grasps, NaN where none (eq. 18 with ``s`` alone).
    gamma2, gamma1
        Eq. 18's and eq. 17's weights.
    """
    p = np.asarray(pred, dtype=np.float64)
    y = np.asarray(labels, dtype=np.float64)
    cur = np.asarray(current, dtype=np.float64)
    tgt = np.asarray(target, dtype=np.float64)
    if p.shape != y.shape or p.ndim != 3:
        raise ValueError(f"pred {p.shape} and labels {y.shape} must be the same (N, U, V)")
    if cur.shape != (len(p), 4, 4) or tgt.shape != (len(p), 4, 4):
        raise ValueError(f"current {cur.shape} and target {tgt.shape} must be ({len(p)}, 4, 4)")
    out = np.zeros(len(p))
    for i in range(len(p)):
        t = tgt[i] if np.isfinite(tgt[i]).all() else None
        a = select_next_waypoint(p[i], candidates, cur[i], t, gamma2, gamma1)
        b = select_next_waypoint(y[i], candidates, cur[i], t, gamma2, gamma1)
        out[i] = float(_same_pose(a, b))
    return out


def evaluate(
    net: ViewNet,
    data: ViewDataset,
    *,
    loss: str = "mse",
    gammas: Sequence[float] = GAMMA2,
    batch_size: int = 64,
    device: str | torch.device | None = None,
) -> dict[str, float]:
    """The network's metrics on ``data`` (a validation or test dataset): ``loss``,
    ``spearman_median``, ``spearman_mean``, ``constant_labels``, ``regret_mean``,
    ``regret_median``, ``top1_exact`` (:func:`heapgrasp.training.train_views.ranking_metrics`),
    ``eq18_match_g<γ2>`` for each of ``gammas`` and ``with_target`` (samples with a
    target grasp, which only the γ2 > 0 comparisons use), on the samples the network can
    score (a 1-channel network: only those whose eq. 14 counts the whole grid)."""
    data = data.for_network(net.in_channels)

    pred = predict(net, data, batch_size=batch_size, device=device)
    report = {
        "loss": float(loss_fn(torch.from_numpy(pred), torch.from_numpy(data.scores), loss)),
        **ranking_metrics(pred, data.scores),
    }
    candidates = data.geometry.candidates()
    for g in gammas:
        match = selection_agreement(pred, data.scores, candidates, data.current, data.target, g)
        report[f"eq18_match_g{g:g}"] = float(match.mean())
    report["with_target"] = float(data.has_target.sum())
    return report
