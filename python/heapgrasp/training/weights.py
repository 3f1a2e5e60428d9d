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
written by the training command, none ship with this version). Every other bad file
raises :class:`~heapgrasp.inference.errors.WeightsError` (a ``ValueError``) whose message
starts with the file's path and says what is wrong; a file is checked whole when it is
loaded, before any network runs:

* the file: not a regular file, unreadable, empty, not a zip archive (``torch.save``'s
  format; a truncated one has lost its end), a member whose bytes fail the archive's
  CRC-32 (garbled), or a payload ``torch.load(weights_only=True)`` refuses;
* the description: ``format``, ``version`` (an integer 1 … :data:`FORMAT_VERSION`),
  ``kind``, ``architecture`` (a dict with str keys the network accepts), ``resolution``
  (the architecture's), ``command`` and ``created`` (str), ``metadata`` (a dict);
* the tensors (:func:`load_grasp_net`, :func:`load_view_net`): exactly the network's names,
  each with the network's shape and dtype, and every value finite.
"""

from __future__ import annotations

import datetime as _dt
import os
import re
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeGuard

import numpy as np
import torch
from torch import nn

import heapgrasp
from heapgrasp.inference.errors import WeightsError, check_archive
from heapgrasp.training.models import GraspNet, ViewNet

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "Kind",
    "WeightsError",
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


def _load_payload(p: Path) -> object:
    """``torch.load`` of ``p`` after checking the file itself (WeightsError otherwise)."""
    check_archive(p, "weights file")
    try:
        return torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types for bad archives
        raise WeightsError(
            p,
            f"corrupt or truncated weights file, or not a heapgrasp weights file ({_detail(exc)})",
        ) from exc


def _detail(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else ""
    text = re.sub(r"\x1b\[[0-9;]*m", "", text).strip()  # torch's messages carry ANSI bold
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _is_int(value: object) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


def _read(path: str | os.PathLike[str], kind: Kind | None) -> dict[str, Any]:
    p = Path(path)
    what = _NAMES[kind] if kind is not None else "network"
    if not p.exists():
        raise FileNotFoundError(
            f"{what} weights file not found: {p}. Weights files are written by the network "
            f"training command (heapgrasp.training.weights.save_weights); none ship with this "
            f"version"
        )
    if not p.is_file():
        raise WeightsError(p, f"not a file (expected {what} weights)")
    data = _load_payload(p)
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise WeightsError(p, f"not a heapgrasp weights file (no format={FORMAT!r} entry)")
    version = data.get("version")
    if not _is_int(version) or not 1 <= version <= FORMAT_VERSION:
        raise WeightsError(
            p,
            f"unsupported weights format version {version!r} (this heapgrasp reads "
            f"versions 1 to {FORMAT_VERSION})",
        )
    stored = data.get("kind")
    if stored not in _CLASSES:
        raise WeightsError(p, f"unknown network kind {stored!r} (expected 'grasp' or 'view')")
    if kind is not None and stored != kind:
        raise WeightsError(
            p,
            f"holds {_NAMES[stored]} weights (kind={stored!r}), expected {what} "
            f"weights (kind={kind!r})",
        )
    for key, typ in (
        ("architecture", dict),
        ("metadata", dict),
        ("command", str),
        ("created", str),
        ("state_dict", dict),
    ):
        label = "entry" if key == "state_dict" else "metadata field"
        if key not in data:
            raise WeightsError(p, f"{label} {key!r} missing")
        if not isinstance(data[key], typ):
            raise WeightsError(
                p, f"{label} {key!r} is a {type(data[key]).__name__}, not a {typ.__name__}"
            )
    arch = data["architecture"]
    bad_keys = [k for k in arch if not isinstance(k, str)]
    if bad_keys:
        raise WeightsError(p, f"metadata field 'architecture' has non-str keys {bad_keys!r}")
    resolution = data.get("resolution")
    if not _is_int(resolution) or resolution < 1:
        raise WeightsError(
            p, f"metadata field 'resolution' is {resolution!r}, not a grid side (an integer)"
        )
    return data


def read_metadata(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Everything stored in a weights file except the tensors (``kind``,
    ``architecture``, ``resolution``, ``command``, ``created``, ``metadata``, ...)."""
    data = _read(path, None)
    return {k: v for k, v in data.items() if k != "state_dict"}


def _shape(t: torch.Tensor) -> tuple[int, ...]:
    return tuple(int(n) for n in t.shape)


def _check_state(
    p: Path, state: dict[Any, Any], expected: Mapping[str, torch.Tensor], arch: Any
) -> None:
    """``state`` holds exactly ``expected``'s names, shapes and dtypes, all finite."""
    mismatch = f"weights do not match the stored architecture {arch}"
    odd = [k for k, v in state.items() if not isinstance(k, str) or not isinstance(v, torch.Tensor)]
    if odd:
        raise WeightsError(p, f"state_dict holds non-tensor entries: {odd[:5]!r}")
    missing = [k for k in expected if k not in state]
    if missing:
        raise WeightsError(p, f"{mismatch}: missing tensor(s) {', '.join(map(repr, missing))}")
    unexpected = [k for k in state if k not in expected]
    if unexpected:
        raise WeightsError(
            p, f"{mismatch}: unexpected tensor(s) {', '.join(map(repr, unexpected))}"
        )
    for name, want in expected.items():
        got = state[name]
        if _shape(got) != _shape(want):
            raise WeightsError(
                p,
                f"{mismatch}: size mismatch for {name!r}: shape {_shape(got)} in the file, "
                f"{_shape(want)} in the network",
            )
        if got.dtype != want.dtype:
            raise WeightsError(
                p, f"dtype of {name!r} is {got.dtype}, the network's is {want.dtype}"
            )
        if got.is_floating_point() or got.is_complex():
            for label, bad in (("NaN", torch.isnan(got)), ("infinity", torch.isinf(got))):
                count = int(bad.sum())
                if count:
                    raise WeightsError(
                        p,
                        f"weights hold {label} in {name!r} ({count} of {got.numel()} values)",
                    )


def _build(path: str | os.PathLike[str], kind: Kind, device: str | torch.device) -> nn.Module:
    p = Path(path)
    data = _read(p, kind)
    arch = data["architecture"]
    cls = _CLASSES[kind]
    try:
        model = cls(**arch)
    except (TypeError, ValueError) as exc:
        raise WeightsError(p, f"architecture {arch} is invalid: {exc}") from exc
    _check_state(p, data["state_dict"], model.state_dict(), arch)
    if data["resolution"] != model.resolution:
        raise WeightsError(
            p,
            f"metadata field 'resolution' is {data['resolution']}, the architecture's is "
            f"{model.resolution}",
        )
    try:
        model.load_state_dict(data["state_dict"], strict=True)
    except RuntimeError as exc:  # pragma: no cover - _check_state finds these first
        detail = " ".join(str(exc).split())
        raise WeightsError(
            p, f"weights do not match the stored architecture {arch}: {detail}"
        ) from exc
    return model.to(device).eval()


def load_grasp_net(
    path: str | os.PathLike[str],
    device: str | torch.device = "cpu",
    *,
    resolution: int | None = None,
) -> GraspNet:
    """The :class:`GraspNet` stored in ``path``, on ``device``, in eval mode.

    ``resolution``: when given, the stored grid side must equal it. A bad file raises
    :class:`~heapgrasp.inference.errors.WeightsError` (module docstring)."""
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

    ``resolution``: when given, the stored grid side must equal it. A bad file raises
    :class:`~heapgrasp.inference.errors.WeightsError` (module docstring)."""
    model = _build(path, "view", device)
    assert isinstance(model, ViewNet)
    _check_res(path, model.resolution, resolution)
    return model


def _check_res(path: str | os.PathLike[str], stored: int, wanted: int | None) -> None:
    if wanted is not None and stored != wanted:
        raise WeightsError(path, f"network reads {stored}³ grids, the grid here is {wanted}³")
