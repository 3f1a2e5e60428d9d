"""The segmentation network of HEAPGrasp §V, for training: DeepLabv3+ (Chen et al., 2018)
with a ResNet-50 encoder and four classes — background, transparent, specular, opaque
(the paper: IoU 0.93 / 0.95 / 0.94, mIoU 0.94 on 40 validation images after
fine-tuning an ImageNet-pretrained model on 427 real images).

* :func:`build_model` — ``segmentation_models_pytorch.DeepLabV3Plus`` built offline
  (``encoder_weights=None``: nothing is downloaded, ever); ``resnet50`` (the paper's),
  ``resnet18`` or ``mobilenet_v2`` (CPU-only machines); an ImageNet-pretrained encoder
  is loaded from a local file (:func:`load_encoder_weights`) when the user has one;
* :class:`SegFolder` — the user's data: ``images/*.png|jpg`` and ``masks/*.png`` of the
  same stem, masks holding class ids 0..3 (checked when the folder is opened);
* :func:`train` — Adam on the cross-entropy, flips and colour jitter, every epoch
  checkpointed (``checkpoint.safetensors``, resumable bit for bit:
  :mod:`heapgrasp.training.common`), the best epoch by validation mIoU kept, then
  ``segmentation.onnx`` (:func:`export_segmentation`), ``metrics.json`` and
  ``metrics.png``;
* :func:`confusion`, :func:`iou_metrics`, :func:`evaluate` — per-class IoU, mIoU (all
  classes, and the paper's three object classes), pixel accuracy and the binary
  silhouette IoU (what Shape from Silhouette consumes) on a validation split.

The ONNX file runs without PyTorch in
:class:`heapgrasp.perception.segnet.NetworkSegmenter`.
"""

from __future__ import annotations

import hashlib
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt
import torch
from torch import Tensor, nn

from heapgrasp.inference import Kind, OnnxNetwork, write_atomically
from heapgrasp.inference.errors import WeightsError
from heapgrasp.training.common import (
    TrainSetupError,
    card_header,
    check_lr,
    evaluating,
    require_int,
    run_epochs,
    start_run,
    write_metrics,
)
from heapgrasp.training.device import resolve_device

__all__ = [
    "CLASSES",
    "ENCODERS",
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "PAD_MULTIPLE",
    "SEG_KIND",
    "SegFolder",
    "SegNet",
    "SegTrainConfig",
    "TrainSetupError",
    "WeightsError",
    "build_model",
    "confusion",
    "evaluate",
    "export_segmentation",
    "iou_metrics",
    "load_encoder_weights",
    "train",
]

U8 = npt.NDArray[np.uint8]
I64 = npt.NDArray[np.int64]

#: The paper's classes in class-id order (:data:`heapgrasp.perception.segnet.CLASSES`).
CLASSES: Final = ("background", "transparent", "specular", "opaque")
#: ``heapgrasp.kind`` of the exported file (:data:`heapgrasp.perception.segnet.SEG_KIND`).
SEG_KIND: Final[Kind] = "segmentation-network"
ENCODERS: Final = ("resnet50", "resnet18", "mobilenet_v2")
IMAGENET_MEAN: Final = (0.485, 0.456, 0.406)
IMAGENET_STD: Final = (0.229, 0.224, 0.225)
#: DeepLabv3+'s output stride: image sides are padded to multiples of it.
PAD_MULTIPLE: Final = 16
#: Mask value ignored by the loss (the padding of a training batch).
IGNORE: Final = 255
IMAGE_SUFFIXES: Final = (".png", ".jpg", ".jpeg")
_CKPT_FORMAT = "heapgrasp-seg-checkpoint"
_NET_FORMAT = "heapgrasp-seg-network"
OPSET = 18
#: Largest difference between PyTorch's and onnxruntime's logits an export accepts.
EXPORT_ATOL = 1e-3


def _smp() -> Any:
    try:
        import segmentation_models_pytorch as smp
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "the segmentation network needs segmentation-models-pytorch: "
            "pip install 'heapgrasp[train]'"
        ) from exc
    return smp


# --------------------------------------------------------------------------- model


class SegNet(nn.Module):
    """DeepLabv3+ of ``encoder`` with ``classes`` outputs: ``(B, 3, H, W)`` normalised RGB
    → ``(B, classes, H, W)`` logits (``H``, ``W`` multiples of :data:`PAD_MULTIPLE`)."""

    def __init__(self, encoder: str = "resnet50", classes: int = len(CLASSES)) -> None:
        super().__init__()
        if encoder not in ENCODERS:
            raise ValueError(f"encoder must be one of {', '.join(ENCODERS)}; got {encoder!r}")
        require_int("classes", classes, 2)
        self.encoder_name = encoder
        self.classes = classes
        self.model = _smp().DeepLabV3Plus(
            encoder_name=encoder, encoder_weights=None, in_channels=3, classes=classes
        )

    def hparams(self) -> dict[str, Any]:
        """The constructor's arguments."""
        return {"encoder": self.encoder_name, "classes": self.classes}

    def forward(self, x: Tensor) -> Tensor:
        out: Tensor = self.model(x)
        return out


def build_model(
    encoder: str = "resnet50",
    *,
    classes: int = len(CLASSES),
    encoder_weights_file: str | os.PathLike[str] | None = None,
) -> SegNet:
    """A :class:`SegNet` with random weights, or with its encoder's from
    ``encoder_weights_file`` (:func:`load_encoder_weights`). Never downloads."""
    net = SegNet(encoder, classes)
    if encoder_weights_file is not None:
        load_encoder_weights(net, encoder_weights_file)
    return net


def load_encoder_weights(net: SegNet, path: str | os.PathLike[str]) -> None:
    """Loads a local state dict into ``net``'s encoder: a torchvision / timm ImageNet
    checkpoint of the same architecture (``resnet50-*.pth``, ``mobilenet_v2-*.pth``; a
    ``.safetensors`` file too), its classifier ignored; keys may carry an ``encoder.``
    prefix or sit under ``state_dict``. FileNotFoundError when missing; WeightsError
    naming the file and the first mismatching keys otherwise."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"encoder weights file not found: {p}")
    try:
        if p.suffix == ".safetensors":
            from safetensors.torch import load_file

            state: Any = load_file(str(p))
        else:
            state = torch.load(p, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch / safetensors raise many types for bad files
        raise WeightsError(p, f"not a readable state dict ({type(exc).__name__}: {exc})") from None
    if isinstance(state, Mapping) and isinstance(state.get("state_dict"), Mapping):
        state = state["state_dict"]
    if not isinstance(state, Mapping) or not all(isinstance(v, Tensor) for v in state.values()):
        raise WeightsError(p, "not a state dict (a mapping of names to tensors)")
    clean = {str(k).removeprefix("module.").removeprefix("encoder."): v for k, v in state.items()}
    drop = ("fc.", "classifier.", "head.")
    clean = {k: v for k, v in clean.items() if not k.startswith(drop)}
    encoder = net.model.encoder
    want = encoder.state_dict()
    missing = [k for k in want if k not in clean]
    unexpected = [k for k in clean if k not in want]
    shapes = [
        f"{k} {tuple(clean[k].shape)} vs {tuple(v.shape)}"
        for k, v in want.items()
        if k in clean and clean[k].shape != v.shape
    ]
    if missing or unexpected or shapes:
        parts = []
        if missing:
            parts.append(f"{len(missing)} missing (e.g. {', '.join(missing[:3])})")
        if unexpected:
            parts.append(f"{len(unexpected)} unexpected (e.g. {', '.join(unexpected[:3])})")
        if shapes:
            parts.append(f"shape mismatches ({'; '.join(shapes[:3])})")
        raise WeightsError(
            p,
            f"not {net.encoder_name} encoder weights: {', '.join(parts)} — pass the ImageNet "
            f"checkpoint of the same architecture as --encoder",
        )
    nn.Module.load_state_dict(encoder, clean, strict=True)


# --------------------------------------------------------------------------- data


def read_image(path: Path) -> U8:
    """An image file as ``(H, W, 3)`` uint8 RGB (ValueError naming it when unreadable)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"), dtype=np.uint8)
    except (OSError, UnidentifiedImageError) as exc:
        raise ValueError(f"{path}: not a readable image ({exc})") from None


def read_mask(path: Path, classes: int = len(CLASSES)) -> U8:
    """A label mask as ``(H, W)`` uint8 class ids; ValueError naming the file when it is
    unreadable, has colour channels that differ, or holds an id >= ``classes``."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            if im.mode == "P":  # a palette PNG: the indices are the class ids
                a = np.asarray(im, dtype=np.uint8)
            else:
                a = np.asarray(im)
    except (OSError, UnidentifiedImageError) as exc:
        raise ValueError(f"{path}: not a readable mask ({exc})") from None
    if a.ndim == 3:
        if not (a[..., :3] == a[..., :1]).all():
            raise ValueError(
                f"{path}: a colour mask; masks hold one class id per pixel (a grey or palette "
                f"PNG with values 0..{classes - 1})"
            )
        a = a[..., 0]
    if a.dtype != np.uint8 and a.size and (a.min() < 0 or a.max() > 255):
        raise ValueError(f"{path}: mask values outside 0..255")
    a = a.astype(np.uint8)
    if a.size and int(a.max()) >= classes:
        raise ValueError(
            f"{path}: class id {int(a.max())} in the mask; ids must be 0..{classes - 1} "
            f"({', '.join(f'{i} {n}' for i, n in enumerate(CLASSES[:classes]))})"
        )
    return a


def _image_size(path: Path) -> tuple[int, int]:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return int(im.height), int(im.width)
    except (OSError, UnidentifiedImageError) as exc:
        raise ValueError(f"{path}: not a readable image ({exc})") from None


def split_group(stem: str) -> str:
    """The part of an image's stem that the split keeps together: the text before
    ``__`` (``scene000012__v03`` → ``scene000012``: views of a scene stay together)."""
    return stem.split("__", 1)[0]


def _unit(text: str) -> float:
    digest = hashlib.sha256(f"heapgrasp-seg:{text}".encode()).digest()
    return int.from_bytes(digest[:8], "big") / 2**64


@dataclass(frozen=True)
class SegFolder:
    """A folder of ``images/`` and ``masks/`` (module docstring), checked when opened."""

    root: Path
    stems: tuple[str, ...]
    images: tuple[Path, ...]
    masks: tuple[Path, ...]
    classes: int = len(CLASSES)

    @classmethod
    def open(cls, root: str | os.PathLike[str], *, classes: int = len(CLASSES)) -> SegFolder:
        """Opens and checks ``root``: every image has a mask of the same stem and size
        holding ids < ``classes``. ValueError (FileNotFoundError for a missing folder)
        naming the first file at fault."""
        r = Path(root)
        if not r.is_dir():
            raise FileNotFoundError(f"segmentation data folder not found: {r}")
        img_dir, mask_dir = r / "images", r / "masks"
        for d in (img_dir, mask_dir):
            if not d.is_dir():
                raise FileNotFoundError(
                    f"{r}: no {d.name}/ folder (expected images/*.png|jpg and masks/*.png)"
                )
        images = sorted(
            p for p in img_dir.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()
        )
        if not images:
            raise ValueError(f"{img_dir}: no images (*.png, *.jpg)")
        stems = [p.stem for p in images]
        dup = sorted({s for s in stems if stems.count(s) > 1})
        if dup:
            raise ValueError(f"{img_dir}: several images named {dup[0]!r} (one per stem)")
        masks = []
        for img in images:
            m = mask_dir / f"{img.stem}.png"
            if not m.is_file():
                raise ValueError(f"{img}: no mask {m}")
            mask = read_mask(m, classes)
            if mask.shape != _image_size(img):
                raise ValueError(
                    f"{m}: mask is {mask.shape[1]}x{mask.shape[0]}, its image {img.name} is "
                    f"{_image_size(img)[1]}x{_image_size(img)[0]} (width x height)"
                )
            masks.append(m)
        return cls(r, tuple(stems), tuple(images), tuple(masks), classes)

    def __len__(self) -> int:
        return len(self.stems)

    def read(self, i: int) -> tuple[U8, U8]:
        """Image ``i`` (RGB) and its mask."""
        return read_image(self.images[i]), read_mask(self.masks[i], self.classes)

    def split(self, val_fraction: float) -> tuple[list[int], list[int]]:
        """``(train, val)`` indices: a stable hash of each image's :func:`split_group`
        puts ``val_fraction`` of the groups in ``val`` (where that leaves either side
        empty, the groups of the lowest hashes go to ``val``, at least one, and at least
        one stays in ``train``)."""
        if not (math.isfinite(val_fraction) and 0.0 < val_fraction < 1.0):
            raise ValueError(f"val_fraction must be in (0, 1), got {val_fraction!r}")
        groups = sorted({split_group(s) for s in self.stems})
        if len(groups) < 2:
            raise TrainSetupError(
                f"{self.root}: one image group ({groups[0]!r}); a validation split needs "
                f"at least two images of different stems"
            )
        val_groups = {g for g in groups if _unit(g) < val_fraction}
        if not val_groups or len(val_groups) == len(groups):
            ranked = sorted(groups, key=_unit)
            n = min(max(1, round(val_fraction * len(groups))), len(groups) - 1)
            val_groups = set(ranked[:n])
        val = [i for i, s in enumerate(self.stems) if split_group(s) in val_groups]
        train = [i for i, s in enumerate(self.stems) if split_group(s) not in val_groups]
        return train, val

    def identity(self, indices: Sequence[int]) -> list[list[Any]]:
        """What a resumed run must find again: each image's stem and its files' sizes."""
        return [
            [self.stems[i], self.images[i].stat().st_size, self.masks[i].stat().st_size]
            for i in indices
        ]


# --------------------------------------------------------------------------- metrics


def confusion(pred: npt.ArrayLike, truth: npt.ArrayLike, classes: int = len(CLASSES)) -> I64:
    """``(classes, classes)`` pixel counts, row = true class, column = predicted;
    pixels whose truth is :data:`IGNORE` are left out."""
    p = np.asarray(pred).astype(np.int64).ravel()
    t = np.asarray(truth).astype(np.int64).ravel()
    if p.shape != t.shape:
        raise ValueError(f"prediction and truth differ in size: {p.size} vs {t.size}")
    keep = t != IGNORE
    p, t = p[keep], t[keep]
    if p.size and (p.min() < 0 or p.max() >= classes or t.min() < 0 or t.max() >= classes):
        raise ValueError(f"class ids must be in 0..{classes - 1}")
    return np.bincount(t * classes + p, minlength=classes * classes).reshape(classes, classes)


def iou_metrics(cm: npt.ArrayLike, names: Sequence[str] = CLASSES) -> dict[str, float]:
    """From a :func:`confusion` matrix: ``iou_<class>`` (TP / (TP + FP + FN); NaN for a
    class neither present nor predicted), ``miou`` (mean over the classes with an IoU),
    ``miou_objects`` (over the object classes: the paper's mIoU), ``pixel_accuracy``
    and ``silhouette_iou`` (object vs background: what carving sees)."""
    m = np.asarray(cm, dtype=np.float64)
    tp = np.diag(m)
    union = m.sum(0) + m.sum(1) - tp
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0, tp / union, np.nan)
    out = {f"iou_{n}": float(v) for n, v in zip(names, iou, strict=True)}

    def mean(values: npt.NDArray[np.float64]) -> float:
        ok = values[np.isfinite(values)]
        return float(ok.mean()) if ok.size else math.nan

    out["miou"] = mean(iou)
    out["miou_objects"] = mean(iou[1:])
    total = m.sum()
    out["pixel_accuracy"] = float(tp.sum() / total) if total > 0 else math.nan
    obj_tp = m[1:, 1:].sum()
    obj_union = m[1:, :].sum() + m[:, 1:].sum() - obj_tp
    out["silhouette_iou"] = float(obj_tp / obj_union) if obj_union > 0 else math.nan
    return out


def evaluate(
    predict: Callable[[U8], npt.NDArray[np.integer[Any]]],
    folder: SegFolder,
    indices: Iterable[int] | None = None,
    *,
    progress: bool = False,
) -> dict[str, Any]:
    """:func:`iou_metrics` of ``predict`` (RGB image → class ids) over ``folder``'s
    images ``indices`` (default all), with ``images`` and the ``confusion`` matrix."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    idx = list(range(len(folder)) if indices is None else indices)
    cm = np.zeros((folder.classes, folder.classes), np.int64)
    for i in tqdm(idx, desc="evaluating", unit="image", disable=None if progress else True):
        rgb, mask = folder.read(i)
        pred = np.asarray(predict(rgb))
        if pred.shape != mask.shape:
            raise ValueError(f"{folder.images[i]}: prediction {pred.shape}, mask {mask.shape}")
        cm += confusion(pred, mask, folder.classes)
    return {
        **iou_metrics(cm, CLASSES[: folder.classes]),
        "images": len(idx),
        "confusion": cm.tolist(),
    }


# --------------------------------------------------------------------------- training


@dataclass(frozen=True)
class SegTrainConfig:
    """``heapgrasp seg train``'s settings."""

    encoder: str = "resnet50"
    epochs: int = 30
    batch: int = 8
    lr: float = 1e-4
    val_fraction: float = 0.1
    seed: int = 0
    size: tuple[int, int] | None = None
    """Training image size ``(H, W)``; None: the first image's. Others are resized."""
    encoder_weights: str | None = None
    """Local ImageNet weights of the encoder (:func:`load_encoder_weights`)."""
    device: str = "auto"
    jitter: float = 0.25
    """Colour jitter: brightness, contrast and saturation scaled by U(1 ± jitter)."""
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.encoder not in ENCODERS:
            raise ValueError(f"encoder must be one of {', '.join(ENCODERS)}; got {self.encoder!r}")
        require_int("epochs", self.epochs, 1)
        require_int("batch", self.batch, 2)
        require_int("seed", self.seed, 0)
        check_lr(self.lr)
        if not (math.isfinite(self.val_fraction) and 0.0 < self.val_fraction < 1.0):
            raise ValueError(f"val_fraction must be in (0, 1), got {self.val_fraction!r}")
        if self.size is not None and (len(self.size) != 2 or min(self.size) < PAD_MULTIPLE):
            raise ValueError(f"size must be (H, W) of at least {PAD_MULTIPLE}, got {self.size!r}")
        if not (0.0 <= self.jitter < 1.0):
            raise ValueError(f"jitter must be in [0, 1), got {self.jitter!r}")


def _resize(img: U8, size: tuple[int, int], *, nearest: bool) -> U8:
    if img.shape[:2] == size:
        return img
    from PIL import Image

    method = Image.Resampling.NEAREST if nearest else Image.Resampling.BILINEAR
    return np.asarray(Image.fromarray(img).resize((size[1], size[0]), method), dtype=np.uint8)


def _normalise(rgb: npt.NDArray[np.floating[Any]] | U8) -> npt.NDArray[np.float32]:
    x = np.asarray(rgb, dtype=np.float32) / np.float32(255.0)
    mean = np.asarray(IMAGENET_MEAN, np.float32)
    std = np.asarray(IMAGENET_STD, np.float32)
    out: npt.NDArray[np.float32] = ((x - mean) / std).astype(np.float32)
    return out


def _pad_to(h: int, w: int) -> tuple[int, int]:
    return -h % PAD_MULTIPLE, -w % PAD_MULTIPLE


def _augment(rgb: U8, mask: U8, rng: np.random.Generator, jitter: float) -> tuple[Any, U8]:
    """Flips and colour jitter (brightness, contrast, saturation) drawn from ``rng``."""
    x = rgb.astype(np.float32)
    m = mask
    if rng.random() < 0.5:
        x, m = x[:, ::-1], m[:, ::-1]
    if rng.random() < 0.5:
        x, m = x[::-1], m[::-1]
    b, c, s = rng.uniform(1.0 - jitter, 1.0 + jitter, size=3)
    x = x * b
    x = (x - x.mean()) * c + x.mean()
    grey = x.mean(axis=2, keepdims=True)
    x = (x - grey) * s + grey
    return np.clip(x, 0.0, 255.0), np.ascontiguousarray(m)


def _batch(
    items: Sequence[tuple[Any, U8]],
) -> tuple[Tensor, Tensor]:
    """Normalised, padded (reflection; masks with :data:`IGNORE`) batch tensors."""
    xs, ys = [], []
    for rgb, mask in items:
        h, w = mask.shape
        ph, pw = _pad_to(h, w)
        x = _normalise(rgb)
        if ph or pw:
            x = np.pad(x, ((0, ph), (0, pw), (0, 0)), mode="reflect")
            mask = np.pad(mask, ((0, ph), (0, pw)), constant_values=IGNORE)
        xs.append(x.transpose(2, 0, 1))
        ys.append(mask.astype(np.int64))
    return torch.from_numpy(np.ascontiguousarray(np.stack(xs))), torch.from_numpy(np.stack(ys))


def torch_predict(net: nn.Module, device: str = "cpu") -> Callable[[U8], U8]:
    """``net`` as an RGB image → class ids function, preprocessing as the ONNX
    segmenter does (normalised, reflection-padded to :data:`PAD_MULTIPLE`, cropped)."""

    def predict(rgb: U8) -> U8:
        h, w = rgb.shape[:2]
        x, _ = _batch([(rgb, np.zeros((h, w), np.uint8))])
        with evaluating(net):
            logits = net(x.to(device))[0, :, :h, :w]
        labels: U8 = logits.argmax(0).to("cpu").numpy().astype(np.uint8)
        return labels

    return predict


def _batches(order: Sequence[int], size: int) -> list[list[int]]:
    """``order`` in batches of ``size``; a last batch of one joins the one before
    (DeepLabv3+'s pooled branch needs two samples to normalise in training)."""
    out = [list(order[i : i + size]) for i in range(0, len(order), size)]
    if len(out) > 1 and len(out[-1]) == 1:
        out[-2] += out.pop()
    return out


@dataclass
class SegResult:
    """What :func:`train` returns."""

    net: SegNet
    best_epoch: int
    history: list[dict[str, float]]
    metrics: dict[str, Any]
    onnx: Path


def train(
    data: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    config: SegTrainConfig,
    *,
    resume: bool = False,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
    command: str = "",
) -> SegResult:
    """Trains on ``data`` (a :class:`SegFolder`), keeps the best epoch by validation
    mIoU and writes ``OUT/segmentation.onnx``, ``metrics.json``, ``metrics.csv``,
    ``metrics.png``, ``best.safetensors`` and ``checkpoint.safetensors`` (``resume``
    continues it; other settings or data are refused, naming what differs)."""
    folder = SegFolder.open(data)
    train_idx, val_idx = folder.split(config.val_fraction)
    if len(train_idx) < 2:
        raise TrainSetupError(f"{folder.root}: {len(train_idx)} training image(s); need >= 2")
    size = config.size or _image_size(folder.images[train_idx[0]])
    device = resolve_device(config.device)
    out = Path(out_dir)
    torch.manual_seed(config.seed)
    net = build_model(config.encoder, encoder_weights_file=config.encoder_weights).to(device)
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    settings = {k: v for k, v in asdict(config).items() if k not in ("epochs", "device", "extra")}
    settings["size"] = list(size)
    identity = {
        "config": settings,
        "train": folder.identity(train_idx),
        "val": folder.identity(val_idx),
        "geometry": {"classes": list(CLASSES)},
    }
    state = start_run(
        out,
        net,
        opt,
        identity,
        resume=resume,
        fmt=_CKPT_FORMAT,
        what="segmentation",
        epochs=config.epochs,
        log=log,
    )
    loss_fn = nn.CrossEntropyLoss(ignore_index=IGNORE)
    steps = len(_batches(train_idx, config.batch))

    def train_epoch(epoch: int, bar: Any) -> dict[str, float]:
        rng = np.random.default_rng([config.seed, epoch])
        order = [train_idx[i] for i in rng.permutation(len(train_idx))]
        total, n = 0.0, 0
        for batch in _batches(order, config.batch):
            items = []
            for i in batch:
                rgb, mask = folder.read(i)
                rgb, mask = _resize(rgb, size, nearest=False), _resize(mask, size, nearest=True)
                items.append(_augment(rgb, mask, rng, config.jitter))
            x, y = _batch(items)
            x, y = x.to(device), y.to(device)
            opt.zero_grad(set_to_none=True)
            loss = loss_fn(net(x), y)
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(batch)
            n += len(batch)
            bar.update(1)
            bar.set_postfix(loss=f"{total / n:.4f}")
        return {"train_loss": total / max(n, 1)}

    def validate() -> dict[str, float]:
        res = evaluate(torch_predict(net, device), folder, val_idx)
        return {k: float(v) for k, v in res.items() if k != "confusion"}

    def panels(row: Mapping[str, float]) -> list[tuple[str, list[tuple[str, str]]]]:
        ious = [(f"val_iou_{c}", c) for c in CLASSES]
        return [
            ("training loss", [("train_loss", "cross-entropy")]),
            ("validation IoU", [("val_miou", "mIoU"), *ious]),
        ]

    started = time.perf_counter()
    best_epoch, history, seconds = run_epochs(
        out,
        net,
        opt,
        state,
        epochs=config.epochs,
        steps=steps,
        progress=progress,
        train_epoch=train_epoch,
        validate=validate,
        uncounted=("images",),
        select="val_miou",
        higher_is_better=True,
        fmt=_CKPT_FORMAT,
        network_format=_NET_FORMAT,
        panels=panels,
        summary=lambda r: (
            f"loss {r['train_loss']:.4f}, val mIoU {r['val_miou']:.3f} "
            f"(objects {r['val_miou_objects']:.3f}, silhouette {r['val_silhouette_iou']:.3f})"
        ),
        log=log,
    )
    val = evaluate(torch_predict(net, device), folder, val_idx)
    metrics = {
        **card_header(command),
        "encoder": config.encoder,
        "encoder_weights": config.encoder_weights,
        "data": str(folder.root),
        "train_images": len(train_idx),
        "val_images": len(val_idx),
        "input_size": list(size),
        "best_epoch": best_epoch,
        "epochs": config.epochs,
        "seconds": round(seconds, 1),
        "seconds_this_call": round(time.perf_counter() - started, 1),
        "val": val,
        "classes": list(CLASSES),
        "settings": settings,
    }
    prov_metrics = {k: v for k, v in val.items() if k != "confusion"}
    onnx_path = export_segmentation(
        net,
        out / "segmentation.onnx",
        input_size=size,
        provenance={
            "command": command,
            "data": {"folder": str(folder.root), "train": len(train_idx), "val": len(val_idx)},
            "metrics": prov_metrics,
        },
    )
    write_metrics(out, metrics)
    return SegResult(net, best_epoch, history, metrics, onnx_path)


# --------------------------------------------------------------------------- export


def export_segmentation(
    net: SegNet,
    path: str | os.PathLike[str],
    *,
    input_size: Sequence[int],
    provenance: Mapping[str, Any] | None = None,
    opset: int = OPSET,
) -> Path:
    """Writes ``net`` as the ONNX file :class:`~heapgrasp.perception.segnet.NetworkSegmenter`
    reads (module docstring there): dynamic batch and image axes, the metadata, sealed;
    written atomically after its logits match PyTorch's on a random image
    (:data:`EXPORT_ATOL`). Returns ``path``."""
    try:
        import onnx  # noqa: F401 (export_sealed needs it)
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "exporting the segmentation network needs onnx and onnxscript: "
            "pip install 'heapgrasp[train]'"
        ) from exc
    from heapgrasp.training.export import export_sealed

    hparams = {
        **net.hparams(),
        "classes": list(CLASSES[: net.classes]),
        "in_channels": 3,
        "mean": list(IMAGENET_MEAN),
        "std": list(IMAGENET_STD),
        "pad_multiple": PAD_MULTIPLE,
        "input_size": [int(s) for s in input_size],
    }
    was_training = net.training
    device = next(net.parameters()).device
    cpu_net = net.to("cpu").eval()
    m = PAD_MULTIPLE
    dims = {
        0: torch.export.Dim("batch", max=1024),
        2: torch.export.Dim("height", min=2 * m, max=8192),
        3: torch.export.Dim("width", min=2 * m, max=8192),
    }
    try:
        data = export_sealed(
            cpu_net,
            torch.zeros(2, 3, 4 * m, 6 * m),
            kind=SEG_KIND,
            hparams=hparams,
            provenance=dict(provenance or {}),
            input_name="image",
            output_names=["logits"],
            dynamic_shapes=(dims,),
            opset=opset,
        )
        onnx_net = OnnxNetwork.from_bytes(data, kind=SEG_KIND, name=str(path))
        gen = torch.Generator().manual_seed(0)
        x = torch.randn(1, 3, 3 * m, 5 * m, generator=gen)
        with torch.no_grad():
            ref = cpu_net(x).numpy()
        (got,) = onnx_net.run(x.numpy())
        diff = float(np.max(np.abs(got - ref)))
        if not diff <= EXPORT_ATOL:
            raise ValueError(
                f"the exported segmentation network's logits differ from PyTorch's by "
                f"{diff:.3g} (more than {EXPORT_ATOL:g}): not written"
            )
    finally:
        net.to(device).train(was_training)
    return write_atomically(data, path)
