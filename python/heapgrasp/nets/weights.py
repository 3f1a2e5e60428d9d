"""Weights files of the grasp network (eq. 11) and the view network (eq. 13).

One file = one ``torch.save`` of a plain dictionary::

    {
        "format": "heapgrasp-weights", "version": 1,
        "kind": "grasp" | "view",
        "architecture": {...},   # the network's constructor arguments (hparams())
        "resolution": 40,        # grid side R the network reads
        "command": "...",        # the command line that wrote the file
        "created": "2026-...Z",  # UTC, ISO 8601
        "metadata": {...},       # free-form, plain types (dataset, epochs, losses, ...)
        "state_dict": {...},     # tensors
    }

It is read back with ``torch.load(..., weights_only=True)``, so nothing in it but
tensors and plain Python values (no pickled classes, no code execution on load).

Errors: a missing file raises :class:`FileNotFoundError` (naming the path; weights are
written by the training command, none ship with this version); a corrupt or truncated
file, a file of the other kind, or an architecture that does not match the stored
tensors raises :class:`ValueError` naming the file and the problem.
"""

from __future__ import annotations

import datetime as _dt
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
from torch import nn

import heapgrasp
from heapgrasp.nets.models import GraspNet, ViewNet

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "Kind",
    "default_weights_dir",
    "find_default",
    "load_grasp_net",
    "load_view_net",
    "read_metadata",
    "save_weights",
]

Kind = Literal["grasp", "view"]
#: ``"format"`` entry of every weights file.
FORMAT = "heapgrasp-weights"
#: ``"version"`` entry written by this module.
FORMAT_VERSION = 1
_CLASSES: dict[str, type[nn.Module]] = {"grasp": GraspNet, "view": ViewNet}
_NAMES = {"grasp": "grasp-network", "view": "view-network"}
_SUFFIXES = (".pt", ".pth")


def default_weights_dir() -> Path:
    """Where shipped weights live: ``<heapgrasp package>/weights``."""
    return Path(heapgrasp.__file__).parent / "weights"


def find_default(kind: Kind) -> Path | None:
    """The shipped weights file of ``kind`` (``weights/<kind>.pt`` or ``.pth``), or
    None when none ships (the case for this version)."""
    _check_kind(kind)
    folder = default_weights_dir()
    for suffix in _SUFFIXES:
        p = folder / f"{kind}{suffix}"
        if p.is_file():
            return p
    return None


def _check_kind(kind: str) -> None:
    if kind not in _CLASSES:
        raise ValueError(f"kind must be 'grasp' or 'view', got {kind!r}")


def _plain(value: Any, where: str) -> Any:
    """``value`` as plain types loadable with ``weights_only=True`` (tuples → lists)."""
    if value is None:
        return None
    # Exact builtin types: subclasses (np.float64, str enums) would not load with
    # weights_only=True.
    for typ in (bool, int, float, str):
        if isinstance(value, typ):
            return typ(value)
    if isinstance(value, np.generic):
        return _plain(value.item(), where)
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise TypeError(f"{where}: keys must be str, got {type(k).__name__} {k!r}")
            out[k] = _plain(v, f"{where}.{k}")
        return out
    if isinstance(value, list | tuple):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(
        f"{where}: {type(value).__name__} is not a plain type (None, bool, int, float, str, "
        f"list, dict with str keys)"
    )


def save_weights(
    model: nn.Module,
    path: str | os.PathLike[str],
    *,
    kind: Kind,
    metadata: Mapping[str, Any] | None = None,
    command: str | None = None,
) -> Path:
    """Writes ``model``'s weights and their description to ``path`` (see the module
    docstring for the layout).

    Parameters
    ----------
    model : GraspNet or ViewNet
        The network; its ``hparams()`` are stored as ``"architecture"``.
    path : path-like
        Destination (parent folders are created; an existing file is replaced).
    kind : {"grasp", "view"}
        Must match the model's class.
    metadata : mapping, optional
        Free-form description (dataset, epochs, losses, ...): plain types only.
    command : str, optional
        The command that produced the weights; default: this process's command line.

    Returns
    -------
    Path
        ``path``.
    """
    _check_kind(kind)
    cls = _CLASSES[kind]
    if not isinstance(model, cls) or not isinstance(model, GraspNet | ViewNet):
        raise ValueError(f"kind={kind!r} needs a {cls.__name__}, got {type(model).__name__}")
    arch = _plain(model.hparams(), "architecture")
    payload = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "kind": kind,
        "architecture": arch,
        "resolution": int(arch["resolution"]),
        "command": command if command is not None else " ".join([sys.executable, *sys.argv]),
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "metadata": _plain(dict(metadata or {}), "metadata"),
        "state_dict": {k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
    }
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    try:
        torch.save(payload, tmp)
        tmp.replace(out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def _read(path: str | os.PathLike[str], kind: Kind | None) -> dict[str, Any]:
    p = Path(path)
    what = _NAMES[kind] if kind is not None else "network"
    if not p.exists():
        raise FileNotFoundError(
            f"{what} weights file not found: {p}. Weights files are written by the network "
            f"training command (heapgrasp.nets.weights.save_weights); none ship with this "
            f"version"
        )
    if not p.is_file():
        raise ValueError(f"{p}: not a file (expected {what} weights)")
    try:
        data = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for bad archives
        raise ValueError(
            f"{p}: corrupt or truncated weights file, or not a heapgrasp weights file "
            f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"
        ) from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{p}: not a heapgrasp weights file (no format={FORMAT!r} entry)")
    version = data.get("version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ValueError(
            f"{p}: unsupported weights format version {version!r} (this heapgrasp reads "
            f"versions up to {FORMAT_VERSION})"
        )
    stored = data.get("kind")
    if stored not in _CLASSES:
        raise ValueError(f"{p}: unknown network kind {stored!r} (expected 'grasp' or 'view')")
    if kind is not None and stored != kind:
        raise ValueError(
            f"{p}: holds {_NAMES[stored]} weights (kind={stored!r}), expected {what} "
            f"weights (kind={kind!r})"
        )
    for key, typ in (("architecture", dict), ("state_dict", dict), ("metadata", dict)):
        if not isinstance(data.get(key), typ):
            raise ValueError(f"{p}: missing or malformed {key!r} entry")
    return data


def read_metadata(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Everything stored in a weights file except the tensors (``kind``,
    ``architecture``, ``resolution``, ``command``, ``created``, ``metadata``, ...)."""
    data = _read(path, None)
    return {k: v for k, v in data.items() if k != "state_dict"}


def _build(path: str | os.PathLike[str], kind: Kind, device: str | torch.device) -> nn.Module:
    data = _read(path, kind)
    arch = data["architecture"]
    cls = _CLASSES[kind]
    try:
        model = cls(**arch)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{Path(path)}: architecture {arch} is invalid: {exc}") from exc
    state = data["state_dict"]
    if not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise ValueError(f"{Path(path)}: state_dict holds non-tensor entries")
    if any(v.is_floating_point() and not bool(torch.isfinite(v).all()) for v in state.values()):
        raise ValueError(f"{Path(path)}: weights hold NaN or infinity")
    try:
        model.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        detail = " ".join(str(exc).split())
        raise ValueError(
            f"{Path(path)}: weights do not match the stored architecture {arch}: {detail}"
        ) from exc
    return model.to(device).eval()


def load_grasp_net(
    path: str | os.PathLike[str],
    device: str | torch.device = "cpu",
    *,
    resolution: int | None = None,
) -> GraspNet:
    """The :class:`GraspNet` stored in ``path``, on ``device``, in eval mode.

    ``resolution``: when given, the stored grid side must equal it (``ValueError``)."""
    model = _build(path, "grasp", device)
    assert isinstance(model, GraspNet)
    _check_res(path, model.resolution, resolution)
    return model


def load_view_net(
    path: str | os.PathLike[str],
    device: str | torch.device = "cpu",
    *,
    resolution: int | None = None,
) -> ViewNet:
    """The :class:`ViewNet` stored in ``path``, on ``device``, in eval mode.

    ``resolution``: when given, the stored grid side must equal it (``ValueError``)."""
    model = _build(path, "view", device)
    assert isinstance(model, ViewNet)
    _check_res(path, model.resolution, resolution)
    return model


def _check_res(path: str | os.PathLike[str], stored: int, wanted: int | None) -> None:
    if wanted is not None and stored != wanted:
        raise ValueError(f"{Path(path)}: network reads {stored}³ grids, the grid here is {wanted}³")
