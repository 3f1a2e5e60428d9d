"""The segmentation network at run time: an RGB frame → per-pixel class ids → the
silhouette (HEAPGrasp §V: DeepLabv3+ with a ResNet-50 encoder, four classes).

The paper segments every RGB image into *background*, *transparent*, *specular* and
*opaque* (IoU 0.93 / 0.95 / 0.94 on its 40 validation images, mIoU 0.94) and carves
with the union of the three object classes. :class:`NetworkSegmenter` runs such a
network from its ONNX file with onnxruntime, like the other shipped networks
(:mod:`heapgrasp.inference`; no PyTorch at run time). ``heapgrasp seg train``
(:mod:`heapgrasp.nets.segmentation`) writes the file.

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
:class:`~heapgrasp.geometry.errors.WeightsError` whose message starts with the path.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.errors import WeightsError
from heapgrasp.inference import (
    FORMAT_VERSION,
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_SHA256,
    META_VERSION,
    content_digest,
    resolve_device,
)
from heapgrasp.perception.frames import Frame

__all__ = ["CLASSES", "SEG_KIND", "NetworkSegmenter", "class_fractions", "colorize"]

#: ``heapgrasp.kind`` of a segmentation network file.
SEG_KIND: Final = "segmentation-network"
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


def _ort() -> Any:
    try:
        import onnxruntime
    except ImportError as exc:  # pragma: no cover - a default dependency
        raise ImportError(
            "running the segmentation network needs onnxruntime, a dependency of heapgrasp: "
            "reinstall heapgrasp, or `pip install onnxruntime` (onnxruntime-gpu for CUDA)"
        ) from exc
    return onnxruntime


def _detail(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    text = re.sub(r"^\[ONNXRuntimeError\] : \d+ : \w+ : ", "", text)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


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
        p = Path(path)
        if not p.exists():
            raise FileNotFoundError(f"segmentation network file not found: {p}")
        if not p.is_file():
            raise WeightsError(p, "not a file (expected an ONNX segmentation network)")
        try:
            data = p.read_bytes()
        except OSError as exc:
            raise WeightsError(p, f"unreadable: {exc.strerror or _detail(exc)}") from exc
        self._open(p, data, device, threads)

    @classmethod
    def from_bytes(
        cls, data: bytes, *, device: str = "cpu", threads: int | None = None, name: str = "<bytes>"
    ) -> NetworkSegmenter:
        """A segmenter from a serialised model, checked as a file is; errors name ``name``."""
        self = cls.__new__(cls)
        self._open(Path(name), bytes(data), device, threads)
        return self

    # ------------------------------------------------------------------ checks
    def _open(self, p: Path, data: bytes, device: str, threads: int | None) -> None:
        self.path = p
        self.device = resolve_device(device)
        if threads is not None and (
            isinstance(threads, bool) or not isinstance(threads, int) or threads < 1
        ):
            raise ValueError(f"threads must be an integer >= 1 or None, got {threads!r}")
        if not data:
            raise WeightsError(p, "empty file (0 bytes), not an ONNX model")
        session = self._session(p, data, threads)
        meta = dict(session.get_modelmeta().custom_metadata_map)
        kind = meta.get(META_KIND)
        if kind is None:
            raise WeightsError(
                p, f"an ONNX model but not a heapgrasp network: metadata {META_KIND!r} missing"
            )
        if kind != SEG_KIND:
            raise WeightsError(p, f"holds a {kind!r} ({META_KIND}), expected a {SEG_KIND!r}")
        version = meta.get(META_VERSION, "")
        if not re.fullmatch(r"[0-9]+", version) or not 1 <= int(version) <= FORMAT_VERSION:
            raise WeightsError(p, f"unsupported or missing {META_VERSION} {version!r}")
        digest = meta.get(META_SHA256)
        if digest is None:
            raise WeightsError(p, f"metadata {META_SHA256!r} missing")
        if content_digest(data) != digest:
            raise WeightsError(
                p, f"garbled: the model's bytes do not match their SHA-256 ({META_SHA256})"
            )
        hp = self._json(meta, META_HPARAMS, p)
        self.provenance = self._json(meta, META_PROVENANCE, p)
        classes = hp.get("classes")
        if (
            not isinstance(classes, list)
            or len(classes) < 2
            or not all(isinstance(c, str) for c in classes)
            or classes[0] != "background"
        ):
            raise WeightsError(
                p,
                f"metadata {META_HPARAMS}: 'classes' is {classes!r}, not a list of >= 2 "
                f"names starting with 'background'",
            )
        pad = hp.get("pad_multiple")
        if isinstance(pad, bool) or not isinstance(pad, int) or not 1 <= pad <= 256:
            raise WeightsError(p, f"metadata {META_HPARAMS}: 'pad_multiple' is {pad!r}")
        self.hparams = hp
        self.classes: tuple[str, ...] = tuple(classes)
        self.mean = _triple(hp, "mean", p, positive=False)
        self.std = _triple(hp, "std", p, positive=True)
        self.pad_multiple = int(pad)
        self.encoder = str(hp.get("encoder", "?"))
        self._check_io(p, session)
        self._session_ = session
        x = np.zeros((1, 3, self.pad_multiple * 2, self.pad_multiple * 2), np.float32)
        try:
            out = np.asarray(session.run(["logits"], {"image": x})[0])
        except Exception as exc:
            raise WeightsError(p, f"a forward pass fails: {_detail(exc)}") from exc
        if out.shape != (1, len(self.classes), *x.shape[2:]):
            raise WeightsError(
                p,
                f"'logits' of a {x.shape} input has shape {out.shape}, expected "
                f"{(1, len(self.classes), *x.shape[2:])}",
            )
        if not np.isfinite(out).all():
            raise WeightsError(p, "'logits' hold NaN or infinity on an all-zero input")

    @staticmethod
    def _json(meta: Mapping[str, str], key: str, p: Path) -> dict[str, Any]:
        try:
            value = json.loads(meta[key])
        except KeyError:
            raise WeightsError(p, f"metadata {key!r} missing") from None
        except json.JSONDecodeError as exc:
            raise WeightsError(p, f"metadata {key!r} is not valid JSON ({exc})") from None
        if not isinstance(value, dict):
            raise WeightsError(p, f"metadata {key!r} is not a JSON object")
        return value

    def _session(self, p: Path, data: bytes, threads: int | None) -> Any:
        ort = _ort()
        options = ort.SessionOptions()
        options.log_severity_level = 3
        if threads is None:
            env = os.environ.get("HEAPGRASP_NUM_THREADS", "")
            threads = int(env) if env.isdigit() and int(env) >= 1 else None
        if threads is not None:
            options.intra_op_num_threads = threads
        providers: list[Any] = ["CPUExecutionProvider"]
        if self.device != "cpu":
            index = int(self.device.partition(":")[2] or 0)
            providers.insert(0, ("CUDAExecutionProvider", {"device_id": index}))
        try:
            return ort.InferenceSession(data, sess_options=options, providers=providers)
        except Exception as exc:
            if data[:4] == b"PK\x03\x04":
                raise WeightsError(
                    p,
                    "a zip archive (a PyTorch checkpoint?), not an ONNX model; export with "
                    "heapgrasp seg train",
                ) from exc
            raise WeightsError(
                p, f"not a valid ONNX model (corrupt, truncated or another format): {_detail(exc)}"
            ) from exc

    def _check_io(self, p: Path, session: Any) -> None:
        inputs, outputs = session.get_inputs(), session.get_outputs()
        if [i.name for i in inputs] != ["image"]:
            raise WeightsError(p, f"inputs are {[i.name for i in inputs]}, expected ['image']")
        if [o.name for o in outputs] != ["logits"]:
            raise WeightsError(p, f"outputs are {[o.name for o in outputs]}, expected ['logits']")
        for arg, channels in ((inputs[0], 3), (outputs[0], len(self.classes))):
            shape = list(arg.shape)
            if arg.type != "tensor(float)" or len(shape) != 4:
                raise WeightsError(
                    p,
                    f"{arg.name!r} is {arg.type} of rank {len(shape)}, expected a float "
                    f"(B, {channels}, H, W) tensor",
                )
            if shape[1] != channels:
                raise WeightsError(
                    p,
                    f"{arg.name!r} has {shape[1]} channels, expected {channels} "
                    f"(metadata {META_HPARAMS})",
                )
            fixed = [s for s in (shape[0], shape[2], shape[3]) if isinstance(s, int)]
            if fixed:
                raise WeightsError(
                    p,
                    f"{arg.name!r} has shape {shape}: the batch and image axes must be "
                    f"dynamic (export with dynamic axes 0, 2 and 3)",
                )

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
        out = self._session_.run(["logits"], {"image": x})[0]
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
