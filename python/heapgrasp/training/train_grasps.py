"""Training the grasp network (HEAPGrasp §IV-B eq. 11, VGN's network and losses) on the
grasp datasets of ``heapgrasp grasps data``. Needs PyTorch, safetensors and matplotlib:
``pip install 'heapgrasp[train]'``.

**Batches.** A step reads ``batch_size`` scenes (one forward pass each) and takes the
loss at every labelled voxel of them (:func:`heapgrasp.training.grasp_data.make_batch`);
VGN runs one forward pass per labelled grasp. Each scene is turned by a random number of
quarter turns about the vertical axis and shifted by up to ``max_shift`` voxels along x
and y (exact on the grid, :func:`~heapgrasp.training.grasp_data.augment_scene`).

**Losses** (VGN's, :func:`grasp_losses`), per labelled grasp with label ``y``::

    loss = BCE(quality, y) + y · (rotation + 0.01 · width)

averaged over the batch's labelled grasps, as VGN averages over its batch: quality at
every labelled voxel; orientation and width on the positives only. ``rotation`` is
``1 − |⟨q̂, q⟩|`` minimised over the gripper's symmetry (``q`` and ``q ⊗ rot_z(π)``: the
fingers swapped give the same grasp). ``width`` is the squared error of the opening in
voxels (``(ŵ − w) / voxel_size``, 7.5 mm at R = 40 in the 0.3 m cube): VGN's unit,
where its weight 0.01 brings the term (up to ~10 voxels of opening) to the scale of the
other two. The network still outputs metres (what the planner reads).

**Metrics** (:func:`grasp_metrics`, on the validation data after every epoch, and on
the test data at the end): the loss and its terms; precision and recall of ``quality ≥
ε`` for ε in :data:`THRESHOLDS` (predicted positive against labelled positive); the average
precision of the quality ranking (area under the precision-recall curve, the step sum
``Σ (R_n − R_{n−1}) P_n`` over the distinct thresholds, as scikit-learn's); the mean
width error (m) and the mean and median rotation error (degrees, the angle between the
predicted and the nearer labelled orientation) on the positives. The best epoch is the
one with the lowest validation loss (all three heads; the planner needs all three).

Adam at a constant learning rate (VGN: 3e-4); a checkpoint every epoch with an exact
resume (:mod:`heapgrasp.training.common`); ``OUT/metrics.csv`` and ``OUT/metrics.png``.
:func:`write_outputs` writes the trained network (safetensors and its model card), its
ONNX file for :class:`~heapgrasp.planning.grasp_network.NetworkGraspPlanner` and the
validation and test metrics.
"""

from __future__ import annotations

import dataclasses
import math
import os
import platform
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch
import torch.nn.functional as F
from torch import Tensor

from heapgrasp.training.common import (
    Panel,
    RunResult,
    TrainSetupError,
    card_header,
    check_lr,
    check_train_split,
    data_sources,
    evaluating,
    finite,
    read_network,
    require_int,
    run_epochs,
    run_identity,
    save_network,
    start_run,
    write_metrics,
)
from heapgrasp.training.grasp_data import (
    INPUT_KINDS,
    GraspBatch,
    GraspDataError,
    GraspDataset,
    check_compatible,
    draw_augments,
    make_batch,
)
from heapgrasp.training.models import GraspNet

__all__ = [
    "NETWORK_FORMAT",
    "THRESHOLDS",
    "WIDTH_WEIGHT",
    "GraspTrainConfig",
    "GraspTrainResult",
    "average_precision",
    "evaluate",
    "grasp_losses",
    "grasp_metrics",
    "load_grasp_network",
    "predict",
    "rotation_error_deg",
    "save_grasp_network",
    "train",
    "write_outputs",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]

#: ``"format"`` in the header of a trained grasp network's safetensors file.
NETWORK_FORMAT = "heapgrasp-grasp-network"
_CHECKPOINT_FORMAT = "heapgrasp-grasp-train-checkpoint"
#: Weight of the width term, the width in voxels (VGN's).
WIDTH_WEIGHT = 0.01
#: Quality thresholds ε of the precision and recall metrics: 0.5, the loop's ε for the
#: network planner (Table I, 0.8) and VGN's grasp detection threshold (0.9).
THRESHOLDS = (0.5, 0.8, 0.9)
#: Entries of :func:`grasp_metrics` that count rather than measure.
_COUNTS = ("grasps", "positives")


# --------------------------------------------------------------------------- losses


def _flip(q: Tensor) -> Tensor:
    """``q ⊗ (0, 0, 1, 0)``: the orientation turned by π about its own z (approach)."""
    x, y, z, w = q.unbind(-1)
    return torch.stack([y, -x, w, -z], dim=-1)


def _gather(out: Tensor, batch: GraspBatch, device: torch.device) -> Tensor:
    """``out[b, :, i, j, k]`` at every grasp of the batch: ``(N, C)``."""
    b = torch.from_numpy(batch.scene).to(device)
    v = torch.from_numpy(batch.voxel).to(device)
    return out[b, :, v[:, 0], v[:, 1], v[:, 2]]


def grasp_losses(
    quality: Tensor,
    rotation: Tensor,
    width: Tensor,
    label: Tensor,
    target_quat: Tensor,
    target_width: Tensor,
    voxel_size: Tensor,
) -> dict[str, Tensor]:
    """VGN's loss terms at ``N`` labelled grasps (module docstring).

    Parameters
    ----------
    quality, width : (N,) tensors
        The network's quality (in [0, 1]) and width (m) at each grasp's voxel.
    rotation : (N, 4) tensor
        Its unit quaternions ``x, y, z, w``.
    label : (N,) tensor
        1 (success) or 0.
    target_quat : (N, 4) tensor
        The labelled orientations.
    target_width, voxel_size : (N,) tensors
        The labelled opening and the grid's voxel size (m).

    Returns
    -------
    dict
        ``loss`` (the mean of ``BCE + y (rotation + 0.01 width)``, what is minimised),
        ``quality`` (mean BCE), ``rotation`` and ``width`` (means over the positives;
        NaN where there is none) and the per-grasp ``rotation_each``, ``width_each``.
    """
    bce = F.binary_cross_entropy(quality.clamp(1e-7, 1.0 - 1e-7), label, reduction="none")
    dot = (rotation * target_quat).sum(-1).abs()
    dot_flip = (rotation * _flip(target_quat)).sum(-1).abs()
    rot = torch.minimum(1.0 - dot, 1.0 - dot_flip)
    wid = ((width - target_width) / voxel_size) ** 2
    loss = (bce + label * (rot + WIDTH_WEIGHT * wid)).mean()
    pos = label > 0.5
    n_pos = pos.sum()
    nan = torch.full((), math.nan, device=label.device)
    return {
        "loss": loss,
        "quality": bce.mean(),
        "rotation": rot[pos].mean() if n_pos else nan,
        "width": wid[pos].mean() if n_pos else nan,
        "rotation_each": rot,
        "width_each": wid,
    }


def _batch_losses(net: GraspNet, batch: GraspBatch, device: torch.device) -> dict[str, Tensor]:
    x = torch.from_numpy(batch.grids).to(device)
    quality, rotation, width = net(x)

    def t(a: np.ndarray) -> Tensor:
        return torch.from_numpy(a).to(device)

    return grasp_losses(
        _gather(quality, batch, device)[:, 0],
        _gather(rotation, batch, device),
        _gather(width, batch, device)[:, 0],
        t(batch.label),
        t(batch.quat),
        t(batch.width),
        t(batch.voxel_size),
    )


# --------------------------------------------------------------------------- metrics


def average_precision(scores: npt.ArrayLike, labels: npt.ArrayLike) -> float:
    """Area under the precision-recall curve of ``scores`` ranking ``labels`` (1/0):
    ``Σ (R_n − R_{n−1}) P_n`` over the distinct score thresholds, highest first (ties
    enter together; scikit-learn's ``average_precision_score``). NaN without positives."""
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y = np.asarray(labels, dtype=np.float64).reshape(-1)
    if s.shape != y.shape:
        raise ValueError(f"scores {s.shape} and labels {y.shape} differ")
    n_pos = y.sum()
    if n_pos <= 0:
        return math.nan
    order = np.argsort(-s, kind="stable")
    s, y = s[order], y[order]
    last = np.r_[np.flatnonzero(np.diff(s)), len(s) - 1]  # last index of each threshold
    tp = np.cumsum(y)[last]
    precision = tp / (last + 1)
    recall = tp / n_pos
    return float(np.sum(np.diff(np.r_[0.0, recall]) * precision))


def rotation_error_deg(pred: npt.ArrayLike, target: npt.ArrayLike) -> F64:
    """Angle (degrees) between each predicted orientation and the nearer of the labelled
    one and its finger-swapped twin (``q ⊗ rot_z(π)``); ``(N, 4)`` quaternions."""
    p = np.asarray(pred, dtype=np.float64)
    q = np.asarray(target, dtype=np.float64)
    flip = np.stack([q[:, 1], -q[:, 0], q[:, 3], -q[:, 2]], axis=1)
    p = p / np.linalg.norm(p, axis=1, keepdims=True)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    flip = flip / np.linalg.norm(flip, axis=1, keepdims=True)
    dot = np.maximum(np.abs((p * q).sum(1)), np.abs((p * flip).sum(1)))
    return np.asarray(np.degrees(2.0 * np.arccos(np.clip(dot, 0.0, 1.0))), dtype=np.float64)


@dataclass(frozen=True)
class Predictions:
    """The network's outputs at every labelled grasp of a dataset, and the labels."""

    quality: F64
    rotation: F64
    width: F64
    label: F64
    quat: F64
    target_width: F64
    voxel_size: F64


def predict(
    net: GraspNet,
    data: GraspDataset,
    *,
    batch_size: int = 8,
    device: str | torch.device | None = None,
) -> Predictions:
    """The network at every labelled grasp of ``data`` (no augmentation, eval mode, no
    gradients; the network's mode is restored)."""
    dev = torch.device(device) if device is not None else next(net.parameters()).device
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("q", "r", "w")}
    labels: list[GraspBatch] = []
    with evaluating(net):
        for start in range(0, len(data), batch_size):
            batch = make_batch(data, np.arange(start, min(start + batch_size, len(data))))
            quality, rotation, width = net(torch.from_numpy(batch.grids).to(dev))
            parts["q"].append(_gather(quality, batch, dev)[:, 0].float().cpu().numpy())
            parts["r"].append(_gather(rotation, batch, dev).float().cpu().numpy())
            parts["w"].append(_gather(width, batch, dev)[:, 0].float().cpu().numpy())
            labels.append(batch)

    def cat(arrays: Sequence[np.ndarray]) -> F64:
        return np.concatenate(arrays).astype(np.float64)

    return Predictions(
        quality=cat(parts["q"]),
        rotation=cat(parts["r"]),
        width=cat(parts["w"]),
        label=cat([b.label for b in labels]),
        quat=cat([b.quat for b in labels]),
        target_width=cat([b.width for b in labels]),
        voxel_size=cat([b.voxel_size for b in labels]),
    )


def grasp_metrics(p: Predictions) -> dict[str, float]:
    """The loss terms and the metrics of the module docstring, of predictions at
    labelled grasps. Precision is NaN at a threshold nothing reaches; the positives'
    metrics are NaN without positives."""
    terms = grasp_losses(
        *(torch.from_numpy(a) for a in (p.quality, p.rotation, p.width, p.label)),
        *(torch.from_numpy(a) for a in (p.quat, p.target_width, p.voxel_size)),
    )
    y = p.label > 0.5
    out: dict[str, float] = {
        "grasps": float(len(y)),
        "positives": float(y.sum()),
        **{k: float(terms[k]) for k in ("loss", "quality", "rotation", "width")},
    }
    out["accuracy"] = float(((p.quality >= 0.5) == y).mean()) if len(y) else math.nan
    for eps in THRESHOLDS:
        hit = p.quality >= eps
        out[f"precision_{eps:g}"] = float((hit & y).sum() / hit.sum()) if hit.any() else math.nan
        out[f"recall_{eps:g}"] = float((hit & y).sum() / y.sum()) if y.any() else math.nan
    out["average_precision"] = average_precision(p.quality, y)
    if y.any():
        err = rotation_error_deg(p.rotation[y], p.quat[y])
        out["width_error_m"] = float(np.abs(p.width[y] - p.target_width[y]).mean())
        out["rotation_error_deg"] = float(err.mean())
        out["rotation_error_deg_median"] = float(np.median(err))
    else:
        out["width_error_m"] = out["rotation_error_deg"] = math.nan
        out["rotation_error_deg_median"] = math.nan
    return out


def evaluate(
    net: GraspNet,
    data: GraspDataset,
    *,
    batch_size: int = 8,
    device: str | torch.device | None = None,
) -> dict[str, float]:
    """:func:`grasp_metrics` of ``net`` on ``data``."""
    return grasp_metrics(predict(net, data, batch_size=batch_size, device=device))


# --------------------------------------------------------------------------- training


@dataclass(frozen=True, kw_only=True)
class GraspTrainConfig:
    """Settings of :func:`train` (all must match on resume)."""

    epochs: int = 20
    """Passes over the training scenes."""
    batch_size: int = 8
    """Scenes per step (their labelled grasps all count)."""
    lr: float = 3e-4
    """Adam's learning rate (constant, VGN's)."""
    seed: int = 0
    """Initial weights (``torch.manual_seed``) and each epoch's order and augmentations."""
    input_kind: str = "occupancy"
    """The grid the network reads: ``occupancy`` (``Ŝ≥λ``, HEAPGrasp and no-vp) or
    ``tsdf`` (the VGN baseline)."""
    channels: tuple[int, ...] = (8, 16, 32)
    """Encoder channels (VGN: 16, 32, 64); the decoder's are the reverse. With
    ``head_kernel = 3`` the default is the size that plans in under 30 ms a call on a
    2-core CPU (``docs/training.md``)."""
    head_kernel: int = 3
    """Kernel of the convolutions near full resolution: the last decoder block's and
    the three heads' (VGN: 5). They are most of the cost (docs/training.md); 5 is ~4x
    dearer there."""
    augment: bool = True
    """Quarter turns and shifts per scene."""
    max_shift: int = 4
    """Largest shift (voxels) along x and y."""

    def __post_init__(self) -> None:
        require_int("epochs", self.epochs, 1)
        require_int("batch_size", self.batch_size, 1)
        check_lr(self.lr)
        require_int("seed", self.seed, 0)
        if self.input_kind not in INPUT_KINDS:
            raise ValueError(
                f"input_kind must be one of {', '.join(INPUT_KINDS)}, got {self.input_kind!r}"
            )
        ch = self.channels
        if (
            not isinstance(ch, tuple)
            or len(ch) != 3
            or any(isinstance(c, bool) or not isinstance(c, int) or c < 1 for c in ch)
        ):
            raise ValueError(f"channels must be 3 integers >= 1, got {ch!r}")
        hk = self.head_kernel
        if isinstance(hk, bool) or not isinstance(hk, int) or hk < 1 or hk % 2 == 0:
            raise ValueError(f"head_kernel must be an odd integer >= 1, got {hk!r}")
        require_int("max_shift", self.max_shift, 0)

    def as_dict(self) -> dict[str, Any]:
        """Plain types."""
        d = dataclasses.asdict(self)
        d["channels"] = list(self.channels)
        return d

    def network(self, resolution: int) -> GraspNet:
        """A fresh network of this size for ``R³`` grids."""
        return GraspNet(
            resolution,
            encoder_channels=self.channels,
            decoder_channels=self.channels[::-1],
            decoder_kernels=(3, 3, self.head_kernel),
            head_kernel=self.head_kernel,
        )


class GraspTrainResult(RunResult[GraspNet]):
    """What :func:`train` returns: ``net`` has the best epoch's weights (lowest
    validation loss)."""


def _epoch_plan(
    config: GraspTrainConfig, epoch: int, n: int
) -> Iterator[tuple[npt.NDArray[np.int64], list[Any] | None]]:
    """Each epoch's batches and augmentations, from a generator seeded by (seed, epoch),
    so a resumed run draws the same ones."""
    rng = np.random.default_rng([config.seed, epoch])
    order = rng.permutation(n)
    for i in range(0, n, config.batch_size):
        idx = order[i : i + config.batch_size]
        yield idx, (draw_augments(rng, len(idx), config.max_shift) if config.augment else None)


_PANELS: list[Panel] = [
    (
        "loss",
        [("train_loss", "train"), ("val_loss", "validation")],
    ),
    (
        "loss terms (validation)",
        [("val_quality", "quality BCE"), ("val_rotation", "rotation"), ("val_width", "width")],
    ),
    (
        "quality: precision (validation)",
        [
            ("val_average_precision", "average precision"),
            *((f"val_precision_{e:g}", f"ε = {e:g}") for e in THRESHOLDS),
        ],
    ),
    (
        "quality: recall (validation)",
        [(f"val_recall_{e:g}", f"ε = {e:g}") for e in THRESHOLDS],
    ),
    ("rotation error on positives (°)", [("val_rotation_error_deg", "mean")]),
    ("width error on positives (m)", [("val_width_error_m", "mean")]),
]


def check_datasets(
    train_data: GraspDataset, val_data: GraspDataset, test_data: GraspDataset | None = None
) -> None:
    """TrainSetupError unless ``train_data`` is a ``train`` dataset, ``val_data`` a
    ``val`` one and ``test_data`` (where given) a ``test`` one, all of the same grid kind
    and geometry, the held-out ones with no object of the training data."""
    check_train_split(train_data)
    for data, split in ((val_data, "val"), (test_data, "test")):
        if data is None:
            continue
        paths = ", ".join(s.path for s in data.sources)
        if data.split != split:
            raise TrainSetupError(
                f"{paths}: {split} data must be a {split!r} dataset, this one is {data.split!r}"
            )
        try:
            check_compatible(train_data, data)
        except GraspDataError as exc:
            raise TrainSetupError(str(exc)) from None
        shared = train_data.objects & data.objects
        if shared:
            raise TrainSetupError(
                f"the training data and the {split} data ({paths}) share objects "
                f"({', '.join(sorted(shared)[:5])}): {split} must be on held-out objects"
            )


def train(
    config: GraspTrainConfig,
    train_data: GraspDataset,
    val_data: GraspDataset,
    out: str | os.PathLike[str],
    *,
    device: str = "cpu",
    resume: bool = False,
    init: str | os.PathLike[str] | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = print,
) -> GraspTrainResult:
    """Trains a :class:`GraspNet` on ``train_data``, validating on ``val_data`` after
    every epoch, writing to ``out`` (module docstring).

    Parameters
    ----------
    config : GraspTrainConfig
        The settings; ``config.input_kind`` must be the datasets' grid.
    train_data, val_data : GraspDataset
        Splits ``train`` and ``val`` (TrainSetupError otherwise, or when they share
        objects or differ in geometry).
    out : path-like
        Output directory: ``checkpoint.safetensors``, ``best.safetensors``,
        ``metrics.csv``, ``metrics.png``.
    device : str
        A torch device name (``heapgrasp.training.resolve_device`` checks one first).
    resume : bool
        Continue from ``out``'s checkpoint (TrainSetupError when there is none, or when
        it was made with other settings or data); without it an existing checkpoint is
        refused.
    init : path-like or None
        Start from these weights (a ``grasp_network.safetensors`` of this size and grid:
        fine-tuning, e.g. a DAgger round on ``heapgrasp grasps loop-data``) instead of
        fresh ones; TrainSetupError when they are not. Their digest is part of what a
        resumed checkpoint must match.
    progress : bool
        A tqdm progress bar per epoch (on a terminal).
    log : callable or None
        Receives one line per epoch.
    """
    check_datasets(train_data, val_data)
    if train_data.input_kind != config.input_kind:
        raise TrainSetupError(
            f"config.input_kind is {config.input_kind!r}, the datasets were read as "
            f"{train_data.input_kind!r}"
        )
    if not train_data.grasps or not val_data.grasps:
        raise TrainSetupError("no labelled grasp to train or validate on")
    out_dir = Path(out)
    torch.manual_seed(config.seed)
    net = config.network(train_data.resolution)
    start_from = None
    if init is not None:
        start_from = _initial_weights(net, init, config.input_kind)
    else:
        # Width starts at the positives' mean opening, quality at their share: fewer
        # steps spent learning offsets (a resume loads the trained values).
        pos = train_data.label > 0
        share = min(max(float(pos.mean()), 1e-3), 1.0 - 1e-3)
        with torch.no_grad():
            assert net.quality_head.bias is not None and net.width_head.bias is not None
            net.quality_head.bias.fill_(math.log(share / (1.0 - share)))
            net.width_head.bias.fill_(float(train_data.width[pos].mean()) if pos.any() else 0.0)
    dev = torch.device(device)
    net.to(dev)
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    # The learning rate is constant and each epoch's order and augmentations come from
    # (seed, epoch) alone, so a resumed run may also go on for more epochs than asked
    # first: the epochs are not part of what a checkpoint must match.
    settings = {k: v for k, v in config.as_dict().items() if k != "epochs"}
    settings["init"] = start_from  # None (fresh weights) matches checkpoints made before
    state = start_run(
        out_dir,
        net,
        opt,
        run_identity(settings, train_data, val_data, dict(train_data.geometry)),
        resume=resume,
        fmt=_CHECKPOINT_FORMAT,
        what="grasp network",
        epochs=config.epochs,
        log=log,
    )
    n = len(train_data)
    steps = -(-n // config.batch_size)

    def train_epoch(epoch: int, bar: Any) -> dict[str, float]:
        sums = {"loss": 0.0, "quality": 0.0, "rotation": 0.0, "width": 0.0}
        counted = {"loss": 0, "rotation": 0}
        for idx, augments in _epoch_plan(config, epoch, n):
            batch = make_batch(train_data, idx, augments)
            if not len(batch):  # every grasp shifted out of the grid
                bar.update()
                continue
            terms = _batch_losses(net, batch, dev)
            opt.zero_grad(set_to_none=True)
            terms["loss"].backward()  # type: ignore[no-untyped-call]
            opt.step()
            g, p = len(batch), int(batch.label.sum())
            sums["loss"] += float(terms["loss"].detach()) * g
            sums["quality"] += float(terms["quality"].detach()) * g
            if p:
                sums["rotation"] += float(terms["rotation"].detach()) * p
                sums["width"] += float(terms["width"].detach()) * p
            counted["loss"] += g
            counted["rotation"] += p
            bar.update()
            bar.set_postfix(loss=f"{sums['loss'] / max(counted['loss'], 1):.4f}")
        g, p = max(counted["loss"], 1), counted["rotation"]
        return {
            "train_loss": sums["loss"] / g,
            "train_quality": sums["quality"] / g,
            "train_rotation": sums["rotation"] / p if p else math.nan,
            "train_width": sums["width"] / p if p else math.nan,
        }

    def summary(row: Mapping[str, float]) -> str:
        return (
            f"train loss {row['train_loss']:.4f}, val loss {row['val_loss']:.4f}, val AP "
            f"{row['val_average_precision']:.3f}, precision/recall@0.5 "
            f"{row['val_precision_0.5']:.3f}/{row['val_recall_0.5']:.3f}, rotation error "
            f"{row['val_rotation_error_deg']:.1f}°, width error "
            f"{1000 * row['val_width_error_m']:.1f} mm"
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
        validate=lambda: evaluate(net, val_data, batch_size=config.batch_size, device=dev),
        uncounted=_COUNTS,
        select="val_loss",
        higher_is_better=False,
        fmt=_CHECKPOINT_FORMAT,
        network_format=NETWORK_FORMAT,
        panels=lambda row: _PANELS,
        summary=summary,
        log=log,
    )
    return GraspTrainResult(net=net, best_epoch=best_epoch, history=history, seconds=seconds)


def _initial_weights(net: GraspNet, path: str | os.PathLike[str], input_kind: str) -> str:
    """Loads ``path``'s weights into ``net`` (TrainSetupError naming the file unless they
    are a grasp network of ``net``'s size, for ``input_kind`` grids where its card says);
    returns the file's digest."""
    import json

    p = Path(path)
    try:
        start = load_grasp_network(p)
    except FileNotFoundError as exc:
        raise TrainSetupError(f"--init: {exc}") from None
    card = p.with_suffix(".json")
    if card.is_file():
        try:
            kind = json.loads(card.read_text()).get("input_kind")
        except (OSError, ValueError):
            kind = None
        if isinstance(kind, str) and kind != input_kind:
            raise TrainSetupError(
                f"--init {p}: a network of {kind!r} grids ({card}); these data are {input_kind!r}"
            )
    try:
        net.load_state_dict(start.state_dict(), strict=True)
    except RuntimeError:
        raise TrainSetupError(
            f"--init {p}: its network is not of the size asked (--channels, "
            f"--head-kernel, the grid's resolution): {start.hparams()}"
        ) from None
    return _sha256(p)[:16]


def _sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


# --------------------------------------------------------------------------- outputs


def save_grasp_network(
    net: GraspNet, path: str | os.PathLike[str], card: Mapping[str, Any]
) -> tuple[Path, Path]:
    """Writes ``PATH`` (``.safetensors``: the state dict, ``format`` and ``hparams`` in
    its header) and the model card ``PATH`` with suffix ``.json``. Returns both."""
    return save_network(net, path, card, fmt=NETWORK_FORMAT)


def load_grasp_network(path: str | os.PathLike[str], device: str = "cpu") -> GraspNet:
    """The :class:`GraspNet` of a ``.safetensors`` file written by :func:`train` or
    :func:`save_grasp_network`, in eval mode (TrainSetupError when the file is not one)."""
    net = read_network(path, GraspNet, fmt=NETWORK_FORMAT, what="grasp network")
    assert isinstance(net, GraspNet)
    return net.to(device).eval()


def _machine(device: str) -> dict[str, Any]:
    from heapgrasp.training.export import describe_machine

    return {
        "description": describe_machine(),
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "torch": torch.__version__,
        "device": device,
        "threads": torch.get_num_threads(),
    }


def write_outputs(
    result: GraspTrainResult,
    config: GraspTrainConfig,
    out: str | os.PathLike[str],
    *,
    train_data: GraspDataset,
    val_data: GraspDataset,
    test_data: GraspDataset | None,
    device: str = "cpu",
    command: str = "",
    init: str | os.PathLike[str] | None = None,
) -> list[Path]:
    """The trained network's files in ``out``: ``metrics.json`` (the best epoch's
    :func:`evaluate` on the validation and, where given, the test data),
    ``grasp_network.safetensors`` and its model card ``grasp_network.json``, and
    ``grasp_network.onnx`` (:func:`heapgrasp.training.export.export_onnx`, kind
    ``grasp-network``, ``input_kind`` in its hyper-parameters) for
    :class:`~heapgrasp.planning.grasp_network.NetworkGraspPlanner`. Returns the paths."""
    from heapgrasp.training.export import export_onnx

    out_dir = Path(out)
    net = result.net
    metrics: dict[str, Any] = {
        "best_epoch": result.best_epoch,
        "val": evaluate(net, val_data, batch_size=config.batch_size, device=device),
    }
    if test_data is not None:
        metrics["test"] = evaluate(net, test_data, batch_size=config.batch_size, device=device)
    metrics = write_metrics(out_dir, metrics)
    card = {
        **card_header(command),
        "machine": _machine(device),
        "input_kind": config.input_kind,
        "input": (
            "occupancy: the high-confidence grid S>=lambda (0/1) the loop feeds the grasp planner"
            if config.input_kind == "occupancy"
            else "tsdf: the TSDF of the depth camera along the circle (0 where unobserved)"
        )
        + ", float32 (B, 1, R, R, R) indexed [x, y, z]",
        "output": "quality sigmoid (B, 1, R, R, R); rotation unit quaternion x, y, z, w in "
        "the grid's axes (B, 4, R, R, R); width opening in metres (B, 1, R, R, R); a voxel's "
        "grasp has its origin (the centre of the palm's face, VGN's) at the voxel's centre",
        "geometry": finite(dict(train_data.geometry)),
        "data": data_sources(train_data, val_data, test_data),
        "training": {
            **config.as_dict(),
            "device": device,
            "best_epoch": result.best_epoch,
            "epochs_done": len(result.history),
            "seconds": round(result.seconds, 1),
            "seconds_per_epoch": round(result.seconds / max(len(result.history), 1), 2),
            "selection": "best epoch by validation loss",
            "init": None
            if init is None
            else {"path": str(init), "sha256": _sha256(Path(init))[:16]},
            "losses": "BCE(quality) + label * (rotation + 0.01 * width in voxels^2), VGN's",
            "augmentation": (
                f"quarter turns about z, x-y shifts up to {config.max_shift} voxels"
                if config.augment
                else "none"
            ),
        },
        "metrics": metrics,
    }
    weights, meta = save_grasp_network(net, out_dir / "grasp_network.safetensors", card)
    onnx_path = export_onnx(
        net,
        out_dir / "grasp_network.onnx",
        provenance=finite(card),
        hparams={
            "input_kind": config.input_kind,
            "grasp_origin": "palm",
            "gripper": str(train_data.geometry.get("gripper") or "panda"),
        },
    )
    return [weights, meta, out_dir / "metrics.json", onnx_path]
