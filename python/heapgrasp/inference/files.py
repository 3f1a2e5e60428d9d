"""The network files' names: the kinds, the metadata keys of the format
(:mod:`heapgrasp.inference`'s docstring), the shipped files and where they live, and the
atomic write every exporter uses."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final, Literal

__all__ = [
    "FORMAT_VERSION",
    "KINDS",
    "META_HPARAMS",
    "META_KIND",
    "META_PROVENANCE",
    "META_SHA256",
    "META_VERSION",
    "SHIPPED_FILES",
    "SHIPPED_GRASP_NETWORKS",
    "SHIPPED_VIEWSPHERE_POLICIES",
    "Kind",
    "check_kind",
    "require_onnx",
    "shipped_grasp_network",
    "shipped_weights",
    "weights_dir",
    "write_atomically",
]

Kind = Literal[
    "view-network", "grasp-network", "grasp-critic", "viewsphere-policy", "segmentation-network"
]
#: Every kind of network file.
KINDS: Final = (
    "view-network",
    "grasp-network",
    "grasp-critic",
    "viewsphere-policy",
    "segmentation-network",
)
#: ``heapgrasp.format_version`` written by this version (files of versions 1 … this load).
FORMAT_VERSION: Final = 1
META_KIND: Final = "heapgrasp.kind"
META_VERSION: Final = "heapgrasp.format_version"
META_HPARAMS: Final = "heapgrasp.hparams"
META_PROVENANCE: Final = "heapgrasp.provenance"
META_SHA256: Final = "heapgrasp.sha256"
#: The shipped file of each kind, under :func:`weights_dir`.
SHIPPED_FILES: Final[Mapping[str, str]] = {
    "view-network": "view_network.onnx",
    "grasp-network": "grasp_network.onnx",
    "grasp-critic": "critic.onnx",
}

#: The shipped viewsphere policies (Natarajan et al.'s learned policies), by model.
SHIPPED_VIEWSPHERE_POLICIES: Final[Mapping[str, str]] = {
    "pca-lr": "viewsphere_pca_lr.onnx",
    "pca-lda": "viewsphere_pca_lda.onnx",
    "dqn": "viewsphere_dqn.onnx",
    "imitation": "viewsphere_imitation.onnx",
}

#: The shipped grasp network of each input kind (``hparams["input_kind"]``): the
#: silhouette methods' ``Ŝ≥λ`` and the VGN baseline's TSDF.
SHIPPED_GRASP_NETWORKS: Final[Mapping[str, str]] = {
    "occupancy": "grasp_network.onnx",
    "tsdf": "grasp_network_tsdf.onnx",
}


def weights_dir() -> Path:
    """Where shipped weights live: ``<heapgrasp package>/weights``."""
    return Path(__file__).resolve().parent.parent / "weights"


def write_atomically(data: bytes, path: str | os.PathLike[str]) -> Path:
    """Writes a weights file's bytes to ``path`` through a temporary file and a rename, so
    the file is whole or absent (the exporters and the critic's writers use it)."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def require_onnx(purpose: str) -> Any:
    """The ``onnx`` package (building network files), or an ImportError saying
    ``purpose`` needs it and how to install it."""
    try:
        import onnx
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            f"{purpose} needs the onnx package: pip install 'heapgrasp[train]'"
        ) from exc
    return onnx


def shipped_weights(kind: Kind) -> Path | None:
    """The shipped file of ``kind`` (:data:`SHIPPED_FILES`), or None when none ships
    (viewsphere policies: :data:`SHIPPED_VIEWSPHERE_POLICIES`)."""
    check_kind(kind)
    if kind not in SHIPPED_FILES:
        return None
    p = weights_dir() / SHIPPED_FILES[kind]
    return p if p.is_file() else None


def shipped_grasp_network(input_kind: str) -> Path | None:
    """The shipped grasp network that reads ``input_kind`` grids
    (:data:`SHIPPED_GRASP_NETWORKS`), or None when none ships."""
    if input_kind not in SHIPPED_GRASP_NETWORKS:
        raise ValueError(
            f"input_kind must be one of {', '.join(SHIPPED_GRASP_NETWORKS)}; got {input_kind!r}"
        )
    p = weights_dir() / SHIPPED_GRASP_NETWORKS[input_kind]
    return p if p.is_file() else None


def check_kind(kind: str) -> None:
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}; got {kind!r}")
