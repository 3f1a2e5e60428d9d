"""The segmentation network at run time: an RGB frame → per-pixel class ids → the
silhouette (HEAPGrasp §V: DeepLabv3+ with a ResNet-50 encoder, four classes).

The paper segments every RGB image into *background*, *transparent*, *specular* and
*opaque* (IoU 0.93 / 0.95 / 0.94 on its 40 validation images, mIoU 0.94) and carves
with the union of the three object classes. :class:`NetworkSegmenter` runs such a
network from its ONNX file with onnxruntime, like the other shipped networks
(:mod:`heapgrasp.inference`; no PyTorch at run time). ``heapgrasp seg train``
(:mod:`heapgrasp.training.segmentation`) writes the file.

**The file.** An ONNX model with the metadata of :mod:`heapgrasp.inference`
(``heapgrasp.kind`` = ``"segmentation-network"``, ``heapgrasp.format_version``,
``heapgrasp.hparams``, ``heapgrasp.provenance``, ``heapgrasp.sha256``), one input
``image`` ``(B, 3, H, W)`` float32 whose batch and image axes are dynamic (the network
is fully convolutional) and one output ``logits`` ``(B, C, H, W)``. ``hparams`` holds
``classes`` (``C`` names, ``background`` first), ``mean`` and ``std`` (per RGB channel,
on [0, 1] values: the input is ``(rgb / 255 − mean) / std``), ``encoder``,
``pad_multiple`` (``H`` and ``W`` must be multiples of it: a frame is padded by
reflection to the next multiple and the labels cropped back) and ``input_size`` (the
``[H, W]`` it was trained at, for information).

Errors: a missing file raises :class:`FileNotFoundError`; any other bad file a
:class:`~heapgrasp.inference.errors.WeightsError` whose message starts with the path.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from heapgrasp.inference import META_HPARAMS, Kind, OnnxNetwork
from heapgrasp.inference.errors import WeightsError
from heapgrasp.perception.frames import Frame

__all__ = ["CLASSES", "SEG_KIND", "NetworkSegmenter", "class_fractions", "colorize"]

#: ``heapgrasp.kind`` of a segmentation network file.
SEG_KIND: Final[Kind] = "segmentation-network"
#: The paper's four classes, in class-id order (0 = background).
CLASSES: Final = ("background", "transparent", "specular", "opaque")
#: Display colour (RGB) of each class id in :func:`colorize`.
PALETTE: Final = np.array(
    [[0, 0, 0], [0, 170, 255], [255, 200, 0], [220, 40, 60]] + [[128, 128, 128]] * 252,
    dtype=np.uint8,
)

U8 = npt.NDArray[np.uint8]
F32 = npt.NDArray[np.float32]


def colorize(labels: npt.NDArray[np.integer[Any]]) -> U8:
    """``(H, W)`` class ids as an ``(H, W, 3)`` RGB image (:data:`PALETTE`)."""
    return PALETTE[np.clip(np.asarray(labels), 0, 255).astype(np.uint8)]


def class_fractions(
    labels: npt.NDArray[np.integer[Any]], classes: tuple[str, ...]
) -> dict[str, float]:
    """Share of the pixels of each class (by name)."""
    counts = np.bincount(np.asarray(labels).ravel(), minlength=len(classes))
    total = max(int(counts.sum()), 1)
    return {name: float(counts[i]) / total for i, name in enumerate(classes)}


def _triple(hp: Mapping[str, Any], key: str, p: Path, *, positive: bool) -> F32:
    value = hp.get(key)
    ok = (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        and all(math.isfinite(v) and (v > 0 or not positive) for v in value)
    )
    if not ok:
        need = "three finite numbers > 0" if positive else "three finite numbers"
        raise WeightsError(p, f"metadata {META_HPARAMS}: {key!r} is {value!r}, not {need}")
    return np.asarray(value, dtype=np.float32)


class NetworkSegmenter:
    """The 4-class segmentation network of an ONNX file (module docstring) as a
    :class:`~heapgrasp.perception.segmenters.Segmenter`: ``segment`` is every pixel
    whose class is not background.

    Parameters
    ----------
    path : path-like
        The ``.onnx`` file (``heapgrasp seg train`` writes ``OUT/segmentation.onnx``).
    device : str
        ``cpu`` (default), ``cuda``, ``cuda:N`` or ``auto``
        (:func:`heapgrasp.inference.resolve_device`).
    threads : int, optional
        onnxruntime's intra-op threads; default ``HEAPGRASP_NUM_THREADS`` where set,
        else onnxruntime's.

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    WeightsError
        Anything else wrong with the file; the message starts with ``path``.
    """

    name = "network"

    def __init__(
        self, path: str | os.PathLike[str], *, device: str = "cpu", threads: int | None = None
    ) -> None:
        self._adopt(OnnxNetwork(path, kind=SEG_KIND, device=device, threads=threads))

    @classmethod
    def from_bytes(
        cls, data: bytes, *, device: str = "cpu", threads: int | None = None, name: str = "<bytes>"
    ) -> NetworkSegmenter:
        """A segmenter from a serialised model, checked as a file is; errors name ``name``."""
        self = cls.__new__(cls)
        net = OnnxNetwork.from_bytes(data, kind=SEG_KIND, device=device, threads=threads, name=name)
        self._adopt(net)
        return self

    def _adopt(self, net: OnnxNetwork) -> None:
        """Checks what only a segmentation network's metadata holds (the file, its
        metadata, inputs, outputs and a forward pass were checked by
        :class:`~heapgrasp.inference.OnnxNetwork`)."""
        p, hp = net.path, net.hparams
        classes: list[Any] = list(hp["classes"])  # a list of >= 2 (OnnxNetwork checked it)
        if not all(isinstance(c, str) for c in classes) or classes[0] != "background":
            raise WeightsError(
                p,
                f"metadata {META_HPARAMS}: 'classes' is {classes!r}, not names starting "
                f"with 'background'",
            )
        pad = hp.get("pad_multiple")
        if isinstance(pad, bool) or not isinstance(pad, int) or not 1 <= pad <= 256:
            raise WeightsError(p, f"metadata {META_HPARAMS}: 'pad_multiple' is {pad!r}")
        self.network = net
        self.classes: tuple[str, ...] = tuple(classes)
        self.mean = _triple(hp, "mean", p, positive=False)
        self.std = _triple(hp, "std", p, positive=True)
        self.pad_multiple = int(pad)
        self.encoder = str(hp.get("encoder", "?"))

    @property
    def path(self) -> Path:
        """The file (or the name of the bytes) it was read from."""
        return self.network.path

    @property
    def device(self) -> str:
        """Where it runs (``cpu`` or ``cuda[:N]``)."""
        return self.network.device

    @property
    def hparams(self) -> dict[str, Any]:
        """The file's hyper-parameters."""
        return self.network.hparams

    @property
    def provenance(self) -> dict[str, Any]:
        """What made the weights (the model card's facts)."""
        return self.network.provenance

    # ------------------------------------------------------------------ use
    def logits(self, rgb: npt.ArrayLike) -> F32:
        """``(C, H, W)`` class scores of an ``(H, W, 3)`` uint8 RGB image."""
        img = np.asarray(rgb)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise ValueError(
                f"the segmentation network reads (H, W, 3) uint8 RGB images, got "
                f"{img.dtype} {img.shape}"
            )
        h, w = img.shape[:2]
        if h < 1 or w < 1:
            raise ValueError(f"empty image {img.shape}")
        m = self.pad_multiple
        ph, pw = -h % m, -w % m
        x: F32 = ((img.astype(np.float32) / 255.0 - self.mean) / self.std).astype(np.float32)
        if ph or pw:
            if h > ph and w > pw:
                x = np.pad(x, ((0, ph), (0, pw), (0, 0)), mode="reflect")
            else:
                x = np.pad(x, ((0, ph), (0, pw), (0, 0)), mode="edge")
        x = np.ascontiguousarray(x.transpose(2, 0, 1)[None])
        (out,) = self.network.run(x)
        return np.asarray(out[0, :, :h, :w], dtype=np.float32)

    def predict(self, rgb: npt.ArrayLike) -> U8:
        """``(H, W)`` uint8 class ids (index into :attr:`classes`) of an RGB image."""
        labels: U8 = self.logits(rgb).argmax(axis=0).astype(np.uint8)
        return labels

    def labels(self, frame: Frame) -> U8:
        """``(H, W)`` uint8 class ids of ``frame``'s RGB image."""
        if frame.rgb is None:
            raise ValueError(
                "the network segmenter needs RGB frames, and this frame has none (the camera "
                "must deliver colour: a simulated camera with rgb=True)"
            )
        return self.predict(frame.rgb)

    def segment(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The silhouette: every pixel of an object class (not background)."""
        mask: npt.NDArray[np.bool_] = self.labels(frame) != 0
        return mask

    def __repr__(self) -> str:
        return f"NetworkSegmenter({str(self.path)!r}, encoder={self.encoder!r})"
