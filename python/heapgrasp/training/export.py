"""Trained networks → the ONNX files heapgrasp runs (:mod:`heapgrasp.inference`).

:func:`export_onnx` writes a :class:`~heapgrasp.training.models.ViewNet` or
:class:`~heapgrasp.training.models.GraspNet` with PyTorch's ONNX exporter (``torch.export``
based; needs ``onnx`` and ``onnxscript``, the ``train`` extra) and the metadata
:class:`~heapgrasp.inference.OnnxNetwork` checks: kind, format version, hyper-parameters
(the architecture, ``resolution``, ``in_channels``) and provenance (command, date,
machine, data, metrics). The batch axis is dynamic. The file is written atomically
(a temporary file, then a rename), loaded back and run on random grids before it
replaces anything: its outputs must match PyTorch's.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import shlex
import sys
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from heapgrasp.inference import (
    FORMAT_VERSION,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_VERSION,
    Kind,
    OnnxNetwork,
    seal,
    write_atomically,
)
from heapgrasp.training.models import GraspNet, ViewNet

__all__ = ["EXPORT_ATOL", "OPSET", "describe_machine", "export_onnx", "onnx_outputs"]

#: ONNX opset of the exported files (≥ 17: LayerNorm-era operators, onnxruntime ≥ 1.14).
OPSET = 18
#: Largest difference between PyTorch and onnxruntime outputs an export accepts.
EXPORT_ATOL = 1e-4


def onnx_outputs(net: nn.Module) -> list[str]:
    """Names of the network's outputs in the ONNX file."""
    if isinstance(net, ViewNet):
        return ["scores"]
    if isinstance(net, GraspNet):
        return ["quality", "rotation", "width"]
    raise TypeError(f"export needs a ViewNet or a GraspNet, got {type(net).__name__}")


def describe_machine() -> str:
    """This machine in a few words: CPU model and cores, and the CUDA device PyTorch
    sees (recorded in the provenance of exported weights)."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    text = f"{cpu}, {os.cpu_count()} cores, {platform.system()}"
    if torch.cuda.is_available():
        text += f"; {torch.cuda.get_device_name(0)}"
    return text


def _json(value: Any, what: str) -> str:
    try:
        return json.dumps(value, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be plain JSON (no NaN): {exc}") from exc


def export_onnx(
    net: nn.Module,
    path: str | os.PathLike[str],
    *,
    provenance: Mapping[str, Any],
    hparams: Mapping[str, Any] | None = None,
    opset: int = OPSET,
) -> Path:
    """Writes ``net`` (a :class:`ViewNet` or :class:`GraspNet`) to ``path`` as a
    heapgrasp ONNX network file (:mod:`heapgrasp.inference`).

    Parameters
    ----------
    net : ViewNet or GraspNet
        The network (any device; exported from the CPU, in eval mode, left as it was).
    path : path-like
        Destination; parent folders are created, an existing file is replaced
        atomically.
    provenance : mapping
        What made the weights (plain JSON): ``data`` and ``metrics`` (held-out results)
        as the model card reports them, and anything else. ``command`` (default: this
        process's command line), ``created`` (default: now, UTC) and ``machine``
        (default: :func:`describe_machine`) are filled in where missing.
    hparams : mapping, optional
        Entries added to the file's hyper-parameters (plain JSON), e.g. the grasp
        network's ``input_kind`` (``occupancy`` or ``tsdf``); the architecture's own
        entries cannot be replaced.
    opset : int
        ONNX opset (≥ 17).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``net`` is neither network.
    ValueError
        ``provenance`` is not plain JSON, ``opset`` < 17, or the exported file's outputs
        differ from PyTorch's by more than :data:`EXPORT_ATOL`.
    """
    outputs = onnx_outputs(net)
    assert isinstance(net, ViewNet | GraspNet)
    if opset < 17:
        raise ValueError(f"opset must be >= 17, got {opset}")
    try:
        import onnx  # noqa: F401 (checked first: export_sealed uses it after the export)
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "exporting networks needs onnx and onnxscript: pip install 'heapgrasp[train]'"
        ) from exc
    kind: Kind = "view-network" if isinstance(net, ViewNet) else "grasp-network"
    in_channels = int(getattr(net, "in_channels", net.encoder.in_channels))
    arch = {**net.hparams(), "in_channels": in_channels}
    clash = sorted(set(arch) & set(hparams or {}))
    if clash:
        raise ValueError(f"hparams may not replace the architecture's {', '.join(clash)}")
    all_hparams = {**arch, **dict(hparams or {})}
    r = net.resolution
    was_training = net.training
    device = next(net.parameters()).device
    cpu_net = net.to("cpu").eval()
    example = torch.zeros(2, in_channels, r, r, r)
    try:
        data = export_sealed(
            cpu_net,
            example,
            kind=kind,
            hparams=all_hparams,
            provenance=provenance,
            input_name="grid",
            output_names=outputs,
            dynamic_shapes=({0: torch.export.Dim("batch")},),
            opset=opset,
        )
        _compare(cpu_net, OnnxNetwork.from_bytes(data, kind=kind, name=str(path)), r, in_channels)
    finally:
        net.to(device).train(was_training)
    return write_atomically(data, path)


def export_sealed(
    cpu_net: nn.Module,
    example: torch.Tensor,
    *,
    kind: Kind,
    hparams: Mapping[str, Any],
    provenance: Mapping[str, Any],
    input_name: str,
    output_names: list[str],
    dynamic_shapes: tuple[dict[int, Any], ...],
    opset: int,
) -> bytes:
    """``cpu_net`` (on the CPU, in eval mode) exported with ``torch.onnx.export`` (dynamo)
    as a heapgrasp network file's bytes: its metadata (``kind``, the format version,
    ``hparams``, ``provenance`` with ``command``, ``created``, ``machine``, ``data`` and
    ``metrics`` filled in where missing; plain JSON, else ValueError) replacing any the
    exporter wrote, checked by ``onnx.checker`` and sealed with its SHA-256
    (:func:`heapgrasp.inference.seal`)."""
    import onnx

    prov = {
        "command": shlex.join([Path(sys.argv[0]).name, *sys.argv[1:]]) if sys.argv else "",
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
        "machine": describe_machine(),
        "data": None,
        "metrics": None,
        **dict(provenance),
    }
    meta = {
        META_KIND: kind,
        META_VERSION: str(FORMAT_VERSION),
        META_HPARAMS: _json(dict(hparams), "hparams"),
        META_PROVENANCE: _json(prov, "provenance"),
    }
    with torch.no_grad(), warnings.catch_warnings():
        # The exporter's own notices (deprecations inside torch.export) are not ours.
        warnings.simplefilter("ignore")
        program = torch.onnx.export(
            cpu_net,
            (example,),
            None,
            dynamo=True,
            input_names=[input_name],
            output_names=output_names,
            dynamic_shapes=dynamic_shapes,
            opset_version=opset,
            verbose=False,
        )
    assert program is not None
    model = program.model_proto
    del model.metadata_props[:]
    for key, value in meta.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model)
    return seal(model.SerializeToString())


def _compare(net: nn.Module, onnx_net: OnnxNetwork, r: int, channels: int) -> None:
    """The exported graph gives PyTorch's outputs on two random occupancy grids."""
    gen = torch.Generator().manual_seed(0)
    x = (torch.rand(2, channels, r, r, r, generator=gen) > 0.8).float()
    with torch.no_grad():
        ref = net(x)
    refs = [ref] if isinstance(ref, torch.Tensor) else list(ref)
    got = onnx_net.run(x.numpy())
    for name, a, b in zip(onnx_net.output_names, got, refs, strict=True):
        diff = float(np.max(np.abs(a - b.numpy())))
        if not diff <= EXPORT_ATOL:
            raise ValueError(
                f"the exported {onnx_net.kind}'s {name!r} differs from PyTorch's by {diff:.3g} "
                f"(more than {EXPORT_ATOL:g}): not written"
            )
