"""Training the view network (HEAPGrasp §IV-B, eq. 13) on the view dataset of
``heapgrasp views data`` (Algorithm 1, exact eq. 14 labels). Needs PyTorch, safetensors
and matplotlib: ``pip install 'heapgrasp[train]'``.

* :func:`train` — Adam, a cosine learning rate per step, MSE (default) or BCE on the
  ``U × V`` map, each batch turned by one of the 8 exact symmetries of
  :mod:`heapgrasp.training.view_data` (quarter turns about z shift ``u`` by ``U/4``, the
  mirror ``y → −y`` sends ``u`` to ``−u``); a checkpoint every epoch (safetensors:
  weights, optimizer state, RNG; JSON in its header: settings, history), ``resume=True``
  continues it exactly; ``OUT/metrics.csv`` and ``OUT/metrics.png`` per epoch; the
  weights of the best epoch by validation median Spearman ρ kept in
  ``OUT/best.safetensors``.
* :func:`predict`, :func:`ranking_metrics`, :func:`evaluate` — loss, per-sample Spearman ρ
  and top-1 regret of a network on a dataset. Eq. 18 agreement (with the planning
  layer's eq. 18) is :func:`heapgrasp.training.view_eval.evaluate`.
* :func:`save_view_network` / :func:`load_view_network` — the trained network as
  ``NAME.safetensors`` (the state dict; the architecture in its header) plus a model
  card ``NAME.json``.

Labels can be negative (eq. 14 of a view that segments voxels never seen before), the
network's sigmoid cannot: the loss compares it with the labels clipped to [0, 1]; every
metric uses the exact labels.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch
import torch.nn.functional as F
from torch import Tensor

from heapgrasp.training.common import (
    CHECKPOINT,
    Panel,
    RunResult,
    TrainSetupError,
    check_lr,
    check_train_split,
    evaluating,
    read_network,
    require_int,
    run_epochs,
    run_identity,
    save_network,
    start_run,
)
from heapgrasp.training.models import ViewNet
from heapgrasp.training.view_data import (
    SYMMETRIES,
    ViewDataError,
    ViewDataset,
    batch_inputs,
    check_compatible,
    transform_grid,
    transform_scores,
)

__all__ = [
    "CHECKPOINT",
    "LOSSES",
    "NETWORK_FORMAT",
    "Evaluator",
    "TrainConfig",
    "TrainResult",
    "TrainSetupError",
    "distinct_views",
    "evaluate",
    "load_view_network",
    "loss_fn",
    "predict",
    "ranking_metrics",
    "save_view_network",
    "spearman",
    "top1_regret",
    "train",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]

#: ``"format"`` in the header of a trained view network's safetensors file.
NETWORK_FORMAT = "heapgrasp-view-network"
_CHECKPOINT_FORMAT = "heapgrasp-view-train-checkpoint"
#: Losses :func:`train` offers.
LOSSES = ("bce", "mse")


# --------------------------------------------------------------------------- metrics


def loss_fn(pred: Tensor, labels: Tensor, loss: str) -> Tensor:
    """Mean BCE or MSE of the predicted map against the labels clipped to [0, 1]."""
    y = labels.clamp(0.0, 1.0)
    if loss == "bce":
        return F.binary_cross_entropy(pred, y)
    if loss == "mse":
        return F.mse_loss(pred, y)
    raise ValueError(f"loss must be one of {', '.join(LOSSES)}, got {loss!r}")


def distinct_views(maps: npt.ArrayLike) -> F64:
    """``(N, U, V)`` maps → ``(N, 1 + U (V−1))``: the ``v = 0`` column (θ = 0, one pose
    for every ``u``) becomes one entry, its mean, so that the pole counts once."""
    m = np.asarray(maps, dtype=np.float64)
    if m.ndim != 3:
        raise ValueError(f"maps must be (N, U, V), got shape {m.shape}")
    return np.concatenate(
        [m[:, :, 0].mean(axis=1, keepdims=True), m[:, :, 1:].reshape(len(m), -1)], 1
    )


def _ranks(x: F64) -> F64:
    from scipy.stats import rankdata

    return np.asarray(rankdata(x, axis=1), dtype=np.float64)


def spearman(pred: npt.ArrayLike, labels: npt.ArrayLike) -> F64:
    """Per-sample Spearman ρ of ``(N, M)`` predictions and labels (ties: average ranks).

    NaN where a sample's labels are constant (no ranking to match); 0 where only the
    predictions are (they rank nothing).
    """
    p, y = np.asarray(pred, dtype=np.float64), np.asarray(labels, dtype=np.float64)
    if p.shape != y.shape or p.ndim != 2:
        raise ValueError(f"pred {p.shape} and labels {y.shape} must be the same (N, M)")
    rp, ry = _ranks(p), _ranks(y)
    rp -= rp.mean(axis=1, keepdims=True)
    ry -= ry.mean(axis=1, keepdims=True)
    sp, sy = (rp * rp).sum(axis=1), (ry * ry).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = (rp * ry).sum(axis=1) / np.sqrt(sp * sy)
    rho = np.where(sp > 0, rho, 0.0)
    return np.asarray(np.where(sy > 0, rho, np.nan), dtype=np.float64)


def top1_regret(pred: npt.ArrayLike, labels: npt.ArrayLike) -> F64:
    """Per sample ``max(labels) − labels[argmax(pred)]`` (≥ 0, 0 when the network's best
    view is the oracle's): the eq. 14 score lost by trusting the network. ``(N, ...)``."""
    p = np.asarray(pred, dtype=np.float64)
    y = np.asarray(labels, dtype=np.float64)
    if p.shape != y.shape or p.ndim < 2:
        raise ValueError(f"pred {p.shape} and labels {y.shape} must be the same (N, ...)")
    p, y = p.reshape(len(p), -1), y.reshape(len(y), -1)
    picked = y[np.arange(len(y)), p.argmax(axis=1)]
    return np.asarray(y.max(axis=1) - picked, dtype=np.float64)


def ranking_metrics(pred: npt.ArrayLike, labels: npt.ArrayLike) -> dict[str, float]:
    """Spearman ρ (over :func:`distinct_views`; median and mean over the samples with
    non-constant labels) and top-1 regret (mean, median) of ``(N, U, V)`` maps."""
    p, y = np.asarray(pred, dtype=np.float64), np.asarray(labels, dtype=np.float64)
    rho = spearman(distinct_views(p), distinct_views(y))
    defined = rho[np.isfinite(rho)]
    regret = top1_regret(p, y)
    return {
        "samples": float(len(y)),
        "spearman_median": float(np.median(defined)) if defined.size else math.nan,
        "spearman_mean": float(defined.mean()) if defined.size else math.nan,
        "constant_labels": float(len(rho) - defined.size),
        "regret_mean": float(regret.mean()),
        "regret_median": float(np.median(regret)),
        "top1_exact": float((regret <= 0.0).mean()),
    }


def predict(
    net: ViewNet,
    data: ViewDataset,
    *,
    batch_size: int = 64,
    device: str | torch.device | None = None,
) -> F32:
    """The network's ``(N, U, V)`` scores for every sample (eval mode, no gradients;
    the network's mode is restored)."""
    dev = torch.device(device) if device is not None else next(net.parameters()).device
    out = np.empty((len(data), *net.view_shape), dtype=np.float32)
    with evaluating(net):
        for start in range(0, len(data), batch_size):
            idx = np.arange(start, min(start + batch_size, len(data)))
            x = torch.from_numpy(batch_inputs(data, idx, net.in_channels)).to(dev)
            out[idx] = net(x).float().cpu().numpy()
    return out


def evaluate(
    net: ViewNet,
    data: ViewDataset,
    *,
    loss: str = "bce",
    batch_size: int = 64,
    device: str | torch.device | None = None,
) -> dict[str, float]:
    """``loss`` (the training loss) and :func:`ranking_metrics` of ``net`` on the samples
    of ``data`` it can score (:meth:`ViewDataset.for_network`: a 1-channel network only
    on the whole-grid ones)."""
    data = data.for_network(net.in_channels)
    pred = predict(net, data, batch_size=batch_size, device=device)
    value = float(loss_fn(torch.from_numpy(pred), torch.from_numpy(data.scores), loss))
    return {"loss": value, **ranking_metrics(pred, data.scores)}


# --------------------------------------------------------------------------- training

#: ``(net, dataset) → {metric: value}``, run on the validation data after every epoch.
Evaluator = Callable[[ViewNet, ViewDataset], dict[str, float]]


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """Settings of :func:`train` (all but ``device`` and ``workers`` must match on resume)."""

    epochs: int = 30
    """Passes over the training data."""
    batch_size: int = 32
    """Samples per step."""
    lr: float = 1e-3
    """Adam's learning rate at step 0; cosine-annealed to 0 at the last step."""
    loss: str = "bce"
    """``mse`` or ``bce`` on the ``U × V`` map (labels clipped to [0, 1]); MSE ranked the
    validation views better in each of 3 seeds (docs/training.md)."""
    seed: int = 0
    """Initial weights (``torch.manual_seed``) and each epoch's order and symmetries."""
    in_channels: int = 1
    """1: ``Ŝ_{0-1}`` (the paper); 2: plus the region mask."""
    augment: bool = True
    """Draw one of the 8 :data:`SYMMETRIES` per batch."""

    def __post_init__(self) -> None:
        require_int("epochs", self.epochs, 1)
        require_int("batch_size", self.batch_size, 1)
        check_lr(self.lr)
        if self.loss not in LOSSES:
            raise ValueError(f"loss must be one of {', '.join(LOSSES)}, got {self.loss!r}")
        if self.in_channels not in (1, 2, 3):
            raise ValueError(f"in_channels must be 1, 2 or 3, got {self.in_channels!r}")
        require_int("seed", self.seed, 0)

    def as_dict(self) -> dict[str, Any]:
        """Plain types."""
        return dataclasses.asdict(self)


class TrainResult(RunResult[ViewNet]):
    """What :func:`train` returns: ``net`` has the best epoch's weights by validation
    median Spearman ρ."""


def _lr_at(config: TrainConfig, step: int, total: int) -> float:
    return config.lr * 0.5 * (1.0 + math.cos(math.pi * step / max(total, 1)))


def _epoch_plan(
    config: TrainConfig, epoch: int, n: int
) -> Iterator[tuple[npt.NDArray[np.int64], tuple[int, bool]]]:
    """Each epoch's batches and symmetries, from a generator seeded by (seed, epoch) so a
    resumed run draws the same ones."""
    rng = np.random.default_rng([config.seed, epoch])
    order = rng.permutation(n)
    batches = [order[i : i + config.batch_size] for i in range(0, n, config.batch_size)]
    drawn = rng.integers(0, len(SYMMETRIES), len(batches))
    for idx, g in zip(batches, drawn, strict=True):
        yield idx, (SYMMETRIES[int(g)] if config.augment else (0, False))


def _panels(row: Mapping[str, float]) -> list[Panel]:
    """The plot's panels for an epoch row's columns."""
    panels: list[Panel] = [
        ("loss", [("train_loss", "train"), ("val_loss", "validation")]),
        (
            "Spearman ρ (validation)",
            [("val_spearman_median", "median"), ("val_spearman_mean", "mean")],
        ),
        ("top-1 regret (validation)", [("val_regret_mean", "mean")]),
    ]
    matches = [k for k in row if k.startswith("val_eq18_match")]
    if matches:
        panels.append(
            ("eq. 18 = oracle (validation)", [(k, k[len("val_eq18_match_") :]) for k in matches])
        )
    return panels


def train(
    config: TrainConfig,
    train_data: ViewDataset,
    val_data: ViewDataset,
    out: str | os.PathLike[str],
    *,
    device: str = "cpu",
    resume: bool = False,
    evaluator: Evaluator | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = print,
) -> TrainResult:
    """Trains a :class:`ViewNet` on ``train_data``, validating on ``val_data`` after
    every epoch, writing to ``out`` (module docstring).

    Parameters
    ----------
    config : TrainConfig
        The settings.
    train_data, val_data : ViewDataset
        Splits ``train`` and ``val`` of the same geometry (TrainSetupError otherwise: a
        ``test`` dataset is never trained on).
    out : path-like
        Output directory: ``checkpoint.safetensors``, ``best.safetensors``,
        ``metrics.csv``, ``metrics.png``.
    device : str
        A torch device name (``heapgrasp.training.resolve_device`` checks one first).
    resume : bool
        Continue from ``out``'s checkpoint (TrainSetupError when there is none, or when it
        was made with other settings or data); without it an existing checkpoint is
        refused.
    evaluator : callable, optional
        ``(net, dataset) → {name: value}`` run on ``val_data`` every epoch; default
        :func:`evaluate` with the training loss. Needs ``loss`` and ``spearman_median``.
    progress : bool
        A tqdm progress bar per epoch (on a terminal).
    log : callable or None
        Receives one line per epoch.
    """
    check_train_split(train_data)
    if val_data.split != "val":
        raise TrainSetupError(
            f"{', '.join(s.path for s in val_data.sources)}: validation needs a 'val' "
            f"dataset, this one is {val_data.split!r}"
        )
    try:
        check_compatible(train_data, val_data)
    except ViewDataError as exc:
        raise TrainSetupError(str(exc)) from None
    shared = train_data.objects & val_data.objects
    if shared:
        raise TrainSetupError(
            f"training and validation data share objects ({', '.join(sorted(shared)[:5])}): "
            "validation must be on held-out objects"
        )
    if train_data.geometry.U % 4 and config.augment:
        raise TrainSetupError(f"U = {train_data.geometry.U}: symmetries need U divisible by 4")
    given = (len(train_data), len(val_data))
    train_data = train_data.for_network(config.in_channels)
    val_data = val_data.for_network(config.in_channels)
    if not len(train_data) or not len(val_data):
        raise TrainSetupError(
            "no whole-grid sample to train or validate a 1-channel network on (every "
            "sample's eq. 14 is counted on a region): use --in-channels 2"
        )
    if log and (len(train_data), len(val_data)) != given:
        log(
            f"in_channels = 1: {given[0] - len(train_data)} training and "
            f"{given[1] - len(val_data)} validation samples with eq. 14 counted on a region "
            "left out (--in-channels 2 reads the region and uses them)"
        )

    out_dir = Path(out)
    geo = train_data.geometry
    torch.manual_seed(config.seed)
    net = ViewNet(geo.resolution, geo.view_shape, in_channels=config.in_channels)
    # The output starts at the mean label rather than 0.5: far fewer steps spent
    # learning the scale, and no early saturation of the sigmoid (a resume loads it).
    mean = float(np.clip(train_data.scores, 0.0, 1.0).mean())
    mean = min(max(mean, 1e-3), 1.0 - 1e-3)
    with torch.no_grad():
        assert net.head.bias is not None
        net.head.bias.fill_(math.log(mean / (1.0 - mean)))
    net.to(device)
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    state = start_run(
        out_dir,
        net,
        opt,
        run_identity(
            config.as_dict(), train_data, val_data, dataclasses.asdict(train_data.geometry)
        ),
        resume=resume,
        fmt=_CHECKPOINT_FORMAT,
        what="view network",
        epochs=config.epochs,
        log=log,
    )

    def default_eval(n: ViewNet, d: ViewDataset) -> dict[str, float]:
        return evaluate(n, d, loss=config.loss, device=device)

    run_eval = evaluator or default_eval
    n = len(train_data)
    steps = -(-n // config.batch_size)
    total = steps * config.epochs

    def train_epoch(epoch: int, bar: Any) -> dict[str, float]:
        losses: list[float] = []
        for b, (idx, (k, mirror)) in enumerate(_epoch_plan(config, epoch, n)):
            lr = _lr_at(config, epoch * steps + b, total)
            for group in opt.param_groups:
                group["lr"] = lr
            x = torch.from_numpy(batch_inputs(train_data, idx, config.in_channels))
            y = torch.from_numpy(train_data.scores[idx])
            x = transform_grid(x, k, mirror).to(device)
            y = transform_scores(y, k, mirror).to(device)
            loss = loss_fn(net(x), y, config.loss)
            opt.zero_grad(set_to_none=True)
            loss.backward()  # type: ignore[no-untyped-call]
            opt.step()
            losses.append(float(loss.detach()))
            bar.update()
            bar.set_postfix(loss=f"{np.mean(losses):.4f}")
        return {
            "lr_end": float(opt.param_groups[0]["lr"]),
            "train_loss": float(np.mean(losses)),
        }

    def summary(row: Mapping[str, float]) -> str:
        return (
            f"train loss {row['train_loss']:.4f}, val loss {row['val_loss']:.4f}, val "
            f"Spearman median {row['val_spearman_median']:.3f}, val regret "
            f"{row['val_regret_mean']:.4f}"
        )

    best_epoch, history, seconds = run_epochs(
        out_dir,
        net,
        opt,
        state,
        epochs=config.epochs,
        steps=steps,
        progress=progress,
        train_epoch=train_epoch,
        validate=lambda: run_eval(net, val_data),
        uncounted=("samples",),
        select="val_spearman_median",
        higher_is_better=True,
        fmt=_CHECKPOINT_FORMAT,
        network_format=NETWORK_FORMAT,
        panels=_panels,
        summary=summary,
        log=log,
    )
    return TrainResult(net=net, best_epoch=best_epoch, history=history, seconds=seconds)


# --------------------------------------------------------------------------- weights files


def save_view_network(
    net: ViewNet, path: str | os.PathLike[str], card: Mapping[str, Any]
) -> tuple[Path, Path]:
    """Writes ``PATH`` (``.safetensors``: the state dict, with ``format`` and ``hparams``
    in its header) and the model card ``PATH`` with suffix ``.json`` (``card`` plus the
    architecture). Returns both paths."""
    return save_network(net, path, card, fmt=NETWORK_FORMAT)


def load_view_network(path: str | os.PathLike[str], device: str = "cpu") -> ViewNet:
    """The :class:`ViewNet` of a ``.safetensors`` file written by :func:`train` or
    :func:`save_view_network`, in eval mode (TrainSetupError when the file is not one)."""
    net = read_network(path, ViewNet, fmt=NETWORK_FORMAT, what="view network")
    assert isinstance(net, ViewNet)
    return net.to(device).eval()
