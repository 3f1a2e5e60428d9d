"""Training: everything that fits, trains or exports a learned part of heapgrasp, and
nothing that runs at grasp time (``pip install heapgrasp[train]``).

The networks of HEAPGrasp §IV-B and §V (need PyTorch):

* :class:`GraspNet` — encoder-decoder 3-D CNN predicting per-voxel grasp quality,
  orientation and width (eq. 11, VGN architecture); its data and trainer
  :mod:`~heapgrasp.training.grasp_data`, :mod:`~heapgrasp.training.train_grasps`;
* :class:`ViewNet` — the same 3-D encoder, z-compression and 2-D decoder predicting the
  ``U × V`` view scores of eq. 13; :mod:`~heapgrasp.training.view_data`,
  :mod:`~heapgrasp.training.train_views`, and :mod:`~heapgrasp.training.view_eval` (how
  often eq. 18 on its scores picks the oracle's view);
* :mod:`~heapgrasp.training.segmentation` — the 4-class segmentation network;
* :func:`export_onnx` — a trained network as the ONNX file heapgrasp runs
  (:mod:`heapgrasp.inference`, onnxruntime, no PyTorch);
* :func:`save_weights`, :func:`load_grasp_net`, :func:`load_view_net` — PyTorch weights
  files (training checkpoints) with their architecture and provenance;
* :func:`resolve_device` — ``cpu``, ``cuda``, ``cuda:N`` or ``auto``, checked against the
  devices PyTorch sees;
* :mod:`~heapgrasp.training.common` — what the trainers share (checkpoints and their
  exact resume, metrics, model cards).

The grasp critic (:mod:`heapgrasp.planning.critic` runs it):
:mod:`~heapgrasp.training.train_critic` (design matrix, fitting, saving,
cross-validation) and :mod:`~heapgrasp.training.critic_net` (the ONNX graphs; the
``cnn`` model's PyTorch training). The ``linear`` critic and the ONNX graphs need only
numpy and the ``onnx`` package, so importing this package does not import PyTorch: the
network names above are imported when first used, and :func:`require_torch` raises an
:class:`ImportError` naming the extra when PyTorch is missing.

The planners, :class:`heapgrasp.planning.grasp_network.NetworkGraspPlanner`,
:class:`heapgrasp.planning.view_network.NetworkViewScorer` and
:class:`heapgrasp.planning.critic.GraspCritic`, run the exported ONNX files and never
import this package (an import-linter contract in ``pyproject.toml``), so nothing but
training needs PyTorch.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from heapgrasp.training.device import resolve_device
    from heapgrasp.training.export import export_onnx
    from heapgrasp.training.models import (
        DEFAULT_RESOLUTION,
        DEFAULT_VIEW_SHAPE,
        Encoder3d,
        GraspNet,
        ViewNet,
    )
    from heapgrasp.training.weights import (
        default_weights_dir,
        find_default,
        load_grasp_net,
        load_view_net,
        read_metadata,
        save_weights,
    )

__all__ = [
    "DEFAULT_RESOLUTION",
    "DEFAULT_VIEW_SHAPE",
    "Encoder3d",
    "GraspNet",
    "ViewNet",
    "default_weights_dir",
    "export_onnx",
    "find_default",
    "load_grasp_net",
    "load_view_net",
    "read_metadata",
    "require_torch",
    "resolve_device",
    "save_weights",
]

#: The network names this package exports, by the module that defines them (all need
#: PyTorch).
_NETWORK_NAMES = {
    "resolve_device": "device",
    "export_onnx": "export",
    "DEFAULT_RESOLUTION": "models",
    "DEFAULT_VIEW_SHAPE": "models",
    "Encoder3d": "models",
    "GraspNet": "models",
    "ViewNet": "models",
    "default_weights_dir": "weights",
    "find_default": "weights",
    "load_grasp_net": "weights",
    "load_view_net": "weights",
    "read_metadata": "weights",
    "save_weights": "weights",
}


def require_torch() -> None:
    """Raises :class:`ImportError` naming the ``train`` extra when PyTorch is not
    installed."""
    try:
        import torch  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            "heapgrasp.training needs PyTorch, which is not installed: install "
            "heapgrasp[train] (PyTorch, onnx, onnxscript), e.g. `pip install 'heapgrasp[train]'`"
        ) from exc


def __getattr__(name: str) -> Any:
    """The network names (:data:`_NETWORK_NAMES`), imported on first use."""
    module = _NETWORK_NAMES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    require_torch()
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)
