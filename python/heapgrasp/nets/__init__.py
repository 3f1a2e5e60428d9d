"""The learned parts of HEAPGrasp §IV-B, for training (needs PyTorch:
``pip install heapgrasp[train]``).

* :class:`GraspNet` — encoder-decoder 3-D CNN predicting per-voxel grasp quality,
  orientation and width (eq. 11, VGN architecture);
* :class:`ViewNet` — the same 3-D encoder, z-compression and 2-D decoder predicting the
  ``U × V`` view scores of eq. 13;
* :func:`export_onnx` — a trained network as the ONNX file heapgrasp runs
  (:mod:`heapgrasp.inference`, onnxruntime, no PyTorch);
* :func:`save_weights`, :func:`load_grasp_net`, :func:`load_view_net` — PyTorch weights
  files (training checkpoints) with their architecture and provenance;
* :func:`resolve_device` — ``cpu``, ``cuda``, ``cuda:N`` or ``auto``, checked against the
  devices PyTorch sees.

The planners that use them, :class:`heapgrasp.planning.grasp_network.NetworkGraspPlanner` and
:class:`heapgrasp.planning.view_network.NetworkViewScorer`, run the exported ONNX files and
never import this package, so nothing but training needs PyTorch.
"""

from __future__ import annotations

try:
    import torch as _torch  # noqa: F401
except ImportError as _exc:  # pragma: no cover - exercised by a sys.modules patch in tests
    raise ImportError(
        "heapgrasp.nets needs PyTorch, which is not installed: install heapgrasp[train] "
        "(PyTorch, onnx, onnxscript), e.g. `pip install 'heapgrasp[train]'`"
    ) from _exc

from heapgrasp.nets.device import resolve_device
from heapgrasp.nets.export import export_onnx
from heapgrasp.nets.models import (
    DEFAULT_RESOLUTION,
    DEFAULT_VIEW_SHAPE,
    Encoder3d,
    GraspNet,
    ViewNet,
)
from heapgrasp.nets.weights import (
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
    "resolve_device",
    "save_weights",
]
