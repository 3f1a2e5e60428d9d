"""What the trainers of the networks share (:mod:`heapgrasp.training.train_views`,
:mod:`heapgrasp.training.train_grasps`): safetensors files written atomically, the training
checkpoint and its exact resume, the per-epoch CSV and plot, and a trained network's
weights file with its model card.

**Checkpoint.** ``OUT/checkpoint.safetensors`` after every epoch: the model's tensors
(``model.*``), Adam's state (``optimizer.<param>.<name>``) and PyTorch's RNG state
(``rng.torch``); its header holds the format name and, as JSON, the run's state (the
settings and data it must be resumed with, the epochs done, the history, the best
epoch, the optimizer's param groups, the network's architecture). Every random draw of
a trainer comes from PyTorch's RNG (restored) or from generators seeded by ``(seed,
epoch)``, so a resumed run ends with the weights of an uninterrupted one, bit for bit.
"""

from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import os
import time
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

import numpy as np
import torch
from torch import Tensor, nn

__all__ = [
    "BEST",
    "CHECKPOINT",
    "RunResult",
    "TrainSetupError",
    "card_header",
    "check_lr",
    "check_train_split",
    "data_sources",
    "end_run",
    "epoch_bar",
    "evaluating",
    "finish_epoch",
    "finite",
    "json_default",
    "plot_history",
    "read_network",
    "read_safetensors",
    "require_int",
    "run_epochs",
    "run_identity",
    "save_atomic",
    "save_network",
    "start_run",
    "write_csv",
    "write_metrics",
]

#: Checkpoint file name inside the output directory.
CHECKPOINT = "checkpoint.safetensors"
#: The best epoch's weights inside the output directory.
BEST = "best.safetensors"
#: ``(title, [(column, label), ...])``: one panel of :func:`plot_history`.
Panel = tuple[str, Sequence[tuple[str, str]]]


NetT = TypeVar("NetT", bound=nn.Module)


class TrainSetupError(ValueError):
    """Training cannot start as asked (wrong split, clashing settings on resume, ...)."""


@dataclass
class RunResult(Generic[NetT]):
    """What a trainer's ``train`` returns."""

    net: NetT
    """The network with the best epoch's weights (the trainer's selection metric)."""
    best_epoch: int
    """1-based epoch of those weights."""
    history: list[dict[str, float]]
    """One row per epoch (as ``metrics.csv``)."""
    seconds: float
    """Training and validation time over every epoch, resumed runs included."""


def _hparams(net: nn.Module) -> dict[str, Any]:
    """The network's constructor arguments (its ``hparams()``; {} where it has none)."""
    hparams = getattr(net, "hparams", None)
    return dict(hparams()) if callable(hparams) else {}


# --------------------------------------------------------------------------- settings and data


def require_int(name: str, value: object, minimum: int) -> None:
    """ValueError unless ``value`` is an integer (not a bool) ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def check_lr(lr: object) -> None:
    """ValueError unless the learning rate ``lr`` is a finite number > 0."""
    if not (isinstance(lr, float | int) and math.isfinite(lr) and lr > 0):
        raise ValueError(f"lr must be > 0, got {lr!r}")


def check_train_split(data: Any) -> None:
    """TrainSetupError unless ``data`` (a dataset with ``split`` and ``sources``) is a
    ``train`` dataset: held-out data is never trained on."""
    if data.split != "train":
        raise TrainSetupError(
            f"{', '.join(s.path for s in data.sources)}: a {data.split!r} "
            "dataset cannot be trained on; training takes 'train' datasets (val: "
            "held-out train objects for validation; test: the benchmark's objects)"
        )


def run_identity(
    config: Mapping[str, Any], train: Any, val: Any, geometry: Mapping[str, Any]
) -> dict[str, Any]:
    """What must match for a checkpoint to be resumed: the settings, the training and
    validation datasets' sources and the data's geometry."""
    return {
        "config": config,
        "train": [s.as_dict() for s in train.sources],
        "val": [s.as_dict() for s in val.sources],
        "geometry": geometry,
    }


@contextmanager
def evaluating(net: nn.Module) -> Iterator[None]:
    """``net`` in eval mode without gradients for the block; its mode restored after."""
    was_training = net.training
    net.eval()
    try:
        with torch.inference_mode():
            yield
    finally:
        net.train(was_training)


# --------------------------------------------------------------------------- files


def save_atomic(tensors: Mapping[str, Tensor], path: Path, metadata: dict[str, str]) -> None:
    """``tensors`` as a safetensors file with ``metadata`` in its header, written to a
    temporary file and renamed (whole or absent)."""
    from safetensors.torch import save_file

    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        plain = {k: v.detach().cpu().contiguous() for k, v in tensors.items()}
        save_file(plain, str(tmp), metadata=metadata)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def read_safetensors(path: Path, what: str) -> tuple[dict[str, Tensor], dict[str, str]]:
    """Tensors and header metadata of a safetensors file (TrainSetupError naming the file
    and ``what`` it should be when it is unreadable; FileNotFoundError when missing)."""
    from safetensors import SafetensorError, safe_open

    try:
        with safe_open(str(path), framework="pt") as f:
            meta = dict(f.metadata() or {})
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except FileNotFoundError:
        raise
    except (OSError, SafetensorError, ValueError) as exc:
        raise TrainSetupError(f"{path}: not a readable {what} ({exc})") from None
    return tensors, meta


def json_default(value: object) -> object:
    """``json.dumps``'s ``default`` for numpy scalars and paths."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def save_network(
    net: nn.Module, path: str | os.PathLike[str], card: Mapping[str, Any], *, fmt: str
) -> tuple[Path, Path]:
    """Writes ``PATH`` (``.safetensors``: the state dict, with ``format`` = ``fmt`` and
    ``hparams`` in its header) and the model card ``PATH`` with suffix ``.json`` (``card``
    plus the architecture). Returns both paths."""
    weights = Path(path)
    if weights.suffix != ".safetensors":
        raise ValueError(f"{weights}: the weights file must end in .safetensors")
    weights.parent.mkdir(parents=True, exist_ok=True)
    hparams = _hparams(net)
    save_atomic(net.state_dict(), weights, {"format": fmt, "hparams": json.dumps(hparams)})
    meta = weights.with_suffix(".json")
    doc = {"format": fmt, "weights": weights.name, "architecture": hparams, **card}
    tmp = meta.with_name(f".{meta.name}.tmp")
    tmp.write_text(json.dumps(doc, indent=2, default=json_default) + "\n")
    os.replace(tmp, meta)
    return weights, meta


def read_network(
    path: str | os.PathLike[str], build: Callable[..., nn.Module], *, fmt: str, what: str
) -> nn.Module:
    """The network of a file :func:`save_network` wrote (``build(**hparams)`` with the
    file's tensors, on the CPU, in eval mode); TrainSetupError when it is not one."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{what} weights not found: {p}")
    tensors, meta = read_safetensors(p, f"{what} weights file")
    if meta.get("format") != fmt:
        raise TrainSetupError(f"{p}: not a {what} weights file (format)")
    try:
        net = build(**json.loads(meta["hparams"]))
        net.load_state_dict(tensors, strict=True)
    except (KeyError, TypeError, ValueError, RuntimeError, json.JSONDecodeError) as exc:
        raise TrainSetupError(f"{p}: weights do not make a {what} ({exc})") from None
    return net.eval()


# --------------------------------------------------------------------------- checkpoints


def _save_checkpoint(
    path: Path, net: nn.Module, opt: torch.optim.Optimizer, state: dict[str, Any], fmt: str
) -> None:
    tensors = {f"model.{k}": v for k, v in net.state_dict().items()}
    sd = opt.state_dict()
    for pid, entry in sd["state"].items():
        for key, value in entry.items():
            tensors[f"optimizer.{pid}.{key}"] = torch.as_tensor(value)
    tensors["rng.torch"] = torch.get_rng_state()
    hparams = _hparams(net)
    full = {**state, "param_groups": sd["param_groups"], "hparams": hparams}
    save_atomic(tensors, path, {"format": fmt, "state": json.dumps(full)})


def _load_checkpoint(
    path: Path, net: nn.Module, opt: torch.optim.Optimizer, fmt: str, what: str
) -> dict[str, Any]:
    tensors, meta = read_safetensors(path, "training checkpoint")
    if meta.get("format") != fmt:
        raise TrainSetupError(f"{path}: not a {what} training checkpoint")
    try:
        state = json.loads(meta["state"])
    except (KeyError, json.JSONDecodeError) as exc:
        raise TrainSetupError(f"{path}: checkpoint state unreadable ({exc})") from None
    model = {k[len("model.") :]: v for k, v in tensors.items() if k.startswith("model.")}
    try:
        net.load_state_dict(model, strict=True)
        opt_state: dict[int, dict[str, Tensor]] = {}
        for key, value in tensors.items():
            if key.startswith("optimizer."):
                _, pid, name = key.split(".", 2)
                opt_state.setdefault(int(pid), {})[name] = value
        opt.load_state_dict({"state": opt_state, "param_groups": state["param_groups"]})
    except (RuntimeError, KeyError, ValueError) as exc:
        raise TrainSetupError(f"{path}: checkpoint does not fit this network ({exc})") from None
    torch.set_rng_state(tensors["rng.torch"])
    return dict(state)


def _mismatch(saved: Mapping[str, Any], wanted: Mapping[str, Any]) -> list[str]:
    """What differs between a checkpoint's identity and this run's: dict entries field
    by field, anything else whole."""
    diff = []
    for key, b in wanted.items():
        a = saved.get(key)
        if isinstance(b, dict) and isinstance(a, dict):
            diff += [f"{key}.{k}: {a.get(k)!r} there, {b[k]!r} now" for k in b if a.get(k) != b[k]]
        elif a != b:
            diff.append(f"{key}: {a!r} there, {b!r} now")
    return diff


_PROGRESS = ("epoch", "history", "best_epoch", "best_value", "seconds")


def start_run(
    out_dir: Path,
    net: nn.Module,
    opt: torch.optim.Optimizer,
    identity: Mapping[str, Any],
    *,
    resume: bool,
    fmt: str,
    what: str,
    epochs: int,
    log: Callable[[str], None] | None,
) -> dict[str, Any]:
    """The state of a training run in ``out_dir``: a fresh one, or with ``resume`` the
    checkpoint's (the network, optimizer and RNG restored from it).

    ``identity`` (plain JSON: settings, data) must equal the checkpoint's. Raises
    TrainSetupError when ``out_dir`` holds a run and ``resume`` is off, when there is no
    checkpoint to resume, or when it was made with another identity (naming what
    differs).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    ckpt = out_dir / CHECKPOINT
    state: dict[str, Any] = {
        **identity,
        "epoch": 0,
        "history": [],
        "best_epoch": 0,
        "best_value": None,
        "seconds": 0.0,
    }
    if ckpt.exists() and not resume:
        raise TrainSetupError(
            f"{out_dir} holds a training run ({CHECKPOINT}); pass --resume to continue it "
            "or choose another output directory"
        )
    if resume:
        if not ckpt.exists():
            raise TrainSetupError(f"--resume: no {CHECKPOINT} in {out_dir} to resume")
        saved = _load_checkpoint(ckpt, net, opt, fmt, what)
        diff = _mismatch(saved, identity)
        if diff:
            raise TrainSetupError(
                f"{ckpt} was made with other settings or data; resume with the same ones "
                f"or train into another directory ({'; '.join(diff)})"
            )
        state.update({k: saved[k] for k in _PROGRESS})
        if log:
            log(f"resuming {out_dir} after epoch {state['epoch']} of {epochs}")
    return state


def finish_epoch(
    out_dir: Path,
    net: nn.Module,
    opt: torch.optim.Optimizer,
    state: dict[str, Any],
    row: dict[str, float],
    *,
    value: float,
    higher_is_better: bool,
    fmt: str,
    network_format: str,
    panels: Sequence[Panel],
) -> None:
    """Records epoch ``row`` (its ``epoch`` and ``seconds`` entries included) in
    ``state``; keeps the weights as ``OUT/best.safetensors`` when ``value`` (the
    selection metric) is the best so far; writes the checkpoint, ``metrics.csv`` and
    ``metrics.png``."""
    epoch = int(row["epoch"])
    state["history"].append(row)
    state["seconds"] = float(state["seconds"]) + float(row["seconds"])
    best = state["best_value"]
    better = best is None or (value > best if higher_is_better else value < best)
    if math.isfinite(value) and better:
        state["best_value"], state["best_epoch"] = value, epoch
        hparams = _hparams(net)
        save_atomic(
            net.state_dict(),
            out_dir / BEST,
            {"format": network_format, "hparams": json.dumps(hparams), "epoch": str(epoch)},
        )
    state["epoch"] = epoch
    _save_checkpoint(out_dir / CHECKPOINT, net, opt, state, fmt)
    write_csv(out_dir / "metrics.csv", state["history"])
    plot_history(out_dir / "metrics.png", state["history"], panels)


def end_run(
    out_dir: Path, net: nn.Module, state: dict[str, Any], panels: Sequence[Panel]
) -> tuple[int, list[dict[str, float]], float]:
    """After the last epoch: ``metrics.csv`` and ``metrics.png`` written again (a run
    stopped between its checkpoint and them), the best epoch's weights loaded into
    ``net`` (eval mode). Returns the best epoch (the last one where none was better),
    the history and the seconds of all epochs."""
    if state["history"]:
        write_csv(out_dir / "metrics.csv", state["history"])
        plot_history(out_dir / "metrics.png", state["history"], panels)
    best = out_dir / BEST
    if best.exists():
        weights, _ = read_safetensors(best, "weights file")
        net.load_state_dict(weights, strict=True)
    net.eval()
    epoch = int(state["best_epoch"]) or int(state["epoch"])
    return epoch, list(state["history"]), float(state["seconds"])


def run_epochs(
    out_dir: Path,
    net: nn.Module,
    opt: torch.optim.Optimizer,
    state: dict[str, Any],
    *,
    epochs: int,
    steps: int,
    progress: bool,
    train_epoch: Callable[[int, Any], dict[str, float]],
    validate: Callable[[], Mapping[str, float]],
    uncounted: Collection[str],
    select: str,
    higher_is_better: bool,
    fmt: str,
    network_format: str,
    panels: Callable[[Mapping[str, float]], Sequence[Panel]],
    summary: Callable[[Mapping[str, float]], str],
    log: Callable[[str], None] | None,
) -> tuple[int, list[dict[str, float]], float]:
    """The epochs of a run from ``state`` (:func:`start_run`) to ``epochs``, then
    :func:`end_run`'s result.

    Each epoch: ``train_epoch(epoch, bar)`` (the network in training mode, ``bar`` its
    :func:`epoch_bar` of ``steps`` batches) returns the epoch's training columns;
    ``validate()`` the validation metrics (recorded as ``val_<name>``, but those named in
    ``uncounted``). The row ``epoch, <training>, val_*, seconds`` goes to
    :func:`finish_epoch` with the row's ``select`` entry as the selection metric and the
    plot's ``panels(row)``; ``log`` receives ``epoch E/N: <summary(row)> (S s)``.
    """
    for epoch in range(int(state["epoch"]), epochs):
        started = time.perf_counter()
        net.train()
        bar = epoch_bar(epoch, epochs, steps, progress)
        with bar:
            columns = train_epoch(epoch, bar)
        metrics = validate()
        seconds = time.perf_counter() - started
        row: dict[str, float] = {
            "epoch": float(epoch + 1),
            **columns,
            **{f"val_{k}": float(v) for k, v in metrics.items() if k not in uncounted},
            "seconds": round(seconds, 3),
        }
        finish_epoch(
            out_dir,
            net,
            opt,
            state,
            row,
            value=row[select],
            higher_is_better=higher_is_better,
            fmt=fmt,
            network_format=network_format,
            panels=panels(row),
        )
        if log:
            log(f"epoch {epoch + 1}/{epochs}: {summary(row)} ({seconds:.1f} s)")
    last = panels(state["history"][0]) if state["history"] else []
    return end_run(out_dir, net, state, last)


def epoch_bar(epoch: int, epochs: int, steps: int, progress: bool) -> Any:
    """A tqdm progress bar over an epoch's ``steps`` batches (shown on a terminal only,
    never without ``progress``; gone when the epoch ends)."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    return tqdm(
        total=steps,
        desc=f"epoch {epoch + 1}/{epochs}",
        unit="batch",
        disable=None if progress else True,
        leave=False,
    )


def finite(value: Any) -> Any:
    """``value`` with NaN and infinities as None, through dicts, lists and tuples (strict
    JSON)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite(v) for v in value]
    return value


# --------------------------------------------------------------------------- outputs


def write_metrics(out_dir: Path, metrics: Mapping[str, Any]) -> dict[str, Any]:
    """``metrics`` with NaN and infinities as None (:func:`finite`), written as
    ``OUT/metrics.json`` (strict JSON). Returns what was written."""
    clean = finite(dict(metrics))
    (out_dir / "metrics.json").write_text(json.dumps(clean, indent=2, allow_nan=False) + "\n")
    return dict(clean)


def data_sources(train: Any, val: Any, test: Any | None) -> dict[str, list[Any]]:
    """The model card's ``data``: each split's dataset sources (``test`` may be None)."""
    return {
        "train": [s.as_dict() for s in train.sources],
        "val": [s.as_dict() for s in val.sources],
        "test": [s.as_dict() for s in test.sources] if test is not None else [],
    }


def card_header(command: str) -> dict[str, Any]:
    """The first entries of a trained network's model card: the command that trained
    it, when (UTC) and heapgrasp's version."""
    import heapgrasp

    return {
        "command": command,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "package_version": heapgrasp.__version__,
    }


# --------------------------------------------------------------------------- metrics files


def write_csv(path: Path, history: list[dict[str, float]]) -> None:
    """One row per epoch (floats to 6 significant digits), written atomically."""
    if not history:
        return
    fields = list(history[0])
    tmp = path.with_name(f".{path.name}.tmp")
    with tmp.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for row in history:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    os.replace(tmp, path)


def plot_history(path: Path, history: list[dict[str, float]], panels: Sequence[Panel]) -> None:
    """One panel per ``(title, [(column, label), ...])``, metric against epoch (PNG,
    written atomically); nothing when ``history`` is empty."""
    if not history:
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    epochs = [row["epoch"] for row in history]
    fig = Figure(figsize=(4.0 * len(panels), 3.2), layout="constrained")
    FigureCanvasAgg(fig)
    for i, (title, series) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), i + 1)
        for key, label in series:
            ax.plot(epochs, [row.get(key, math.nan) for row in history], marker=".", label=label)
        ax.set_title(title)
        ax.set_xlabel("epoch")
        ax.grid(alpha=0.3)
        ax.legend()
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=100)
    os.replace(tmp, path)
