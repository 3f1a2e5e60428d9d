"""The one way every shipped network runs: an ONNX file, checked whole, run with
onnxruntime (no PyTorch at run time).

The view network (eq. 13), the grasp network (eq. 11) and the grasp critic are trained
with PyTorch (``pip install heapgrasp[train]``) and shipped as ONNX files
(:func:`heapgrasp.training.export_onnx`, :mod:`heapgrasp.training.critic_net`).
:class:`OnnxNetwork` opens one, checks it before any use and runs it on the CPU, or on a
CUDA device where onnxruntime has the CUDA execution provider (``onnxruntime-gpu``).

**The file.** An ONNX model (opset ≥ 17) with one float32 input whose first axis (the
batch) is dynamic, and these ``metadata_props``:

=============================  ==========================================================
``heapgrasp.kind``             ``"view-network"``, ``"grasp-network"``, ``"grasp-critic"``,
                               ``"viewsphere-policy"`` or ``"segmentation-network"``
``heapgrasp.format_version``   ``"1"`` (:data:`FORMAT_VERSION`)
``heapgrasp.hparams``          JSON object: the architecture and what the input must be
                               (``resolution``, ``in_channels``, ``view_shape``, ...)
``heapgrasp.provenance``       JSON object: ``command``, ``created``, ``machine``,
                               ``data``, ``metrics`` (the model card's facts)
``heapgrasp.sha256``           SHA-256 of the model without its metadata
                               (:func:`content_digest`; :func:`seal` appends it)
=============================  ==========================================================

Inputs and outputs by kind (``B`` the batch, ``R`` = ``hparams["resolution"]``,
``C`` = ``hparams["in_channels"]``):

* ``view-network``: ``grid`` ``(B, C, R, R, R)`` → ``scores`` ``(B, U, V)``,
  ``(U, V)`` = ``hparams["view_shape"]``;
* ``grasp-network``: ``grid`` ``(B, C, R, R, R)`` → ``quality`` ``(B, 1, R, R, R)``,
  ``rotation`` ``(B, 4, R, R, R)``, ``width`` ``(B, 1, R, R, R)``;
* ``grasp-critic``: ``features`` ``(B, F)`` → ``logits`` ``(B,)``,
  ``F`` = ``hparams["n_features"]``;
* ``viewsphere-policy``: ``state`` ``(B, F)`` → ``scores`` ``(B, 8)`` (one per direction
  of Natarajan et al.'s viewsphere), ``F`` = ``hparams["n_features"]``;
* ``segmentation-network``: ``image`` ``(B, 3, H, W)`` → ``logits`` ``(B, K, H, W)``,
  ``H``, ``W`` dynamic (fully convolutional), ``K`` = ``len(hparams["classes"])``
  (:class:`heapgrasp.perception.segnet.NetworkSegmenter` checks the rest).

**Errors.** A missing file raises :class:`FileNotFoundError` naming it. Any other bad
file raises :class:`~heapgrasp.inference.errors.WeightsError` whose message starts with
the file's path and says what is wrong: not a file, unreadable, empty, not an ONNX model
(truncated, garbage, a PyTorch or numpy archive), an ONNX model that is not a heapgrasp
network (metadata missing or malformed), garbled bytes (the SHA-256 differs: onnxruntime
would run altered weights without a word), another kind of network, inputs or outputs of
other names, types or shapes than its ``hparams`` say, a fixed batch axis, or a forward
pass on an all-zero input that fails or gives NaN or infinity (weights holding NaN).

The package: :mod:`~heapgrasp.inference.network` (:class:`OnnxNetwork`,
:func:`resolve_device`), :mod:`~heapgrasp.inference.files` (the kinds, metadata keys,
shipped files, atomic writes), :mod:`~heapgrasp.inference.checksum` (the content
checksum), :mod:`~heapgrasp.inference.errors` (:class:`WeightsError`, the archive check).
"""

from heapgrasp.inference.checksum import content_digest, seal
from heapgrasp.inference.errors import WeightsError, check_archive
from heapgrasp.inference.files import (
    FORMAT_VERSION,
    KINDS,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_SHA256,
    META_VERSION,
    SHIPPED_FILES,
    SHIPPED_GRASP_NETWORKS,
    SHIPPED_VIEWSPHERE_POLICIES,
    Kind,
    require_onnx,
    shipped_grasp_network,
    shipped_weights,
    weights_dir,
    write_atomically,
)
from heapgrasp.inference.network import OnnxNetwork, resolve_device

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
    "OnnxNetwork",
    "WeightsError",
    "check_archive",
    "content_digest",
    "require_onnx",
    "resolve_device",
    "seal",
    "shipped_grasp_network",
    "shipped_weights",
    "weights_dir",
    "write_atomically",
]
