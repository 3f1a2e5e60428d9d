"""``heapgrasp seg data|train|eval|predict|coco``: the 4-class segmentation network of
HEAPGrasp §V (DeepLabv3+; background, transparent, specular, opaque).

::

    heapgrasp seg data runs/seg-synth --scenes 500 --views 8       # or your own images
    heapgrasp seg train runs/seg-synth --out runs/seg-net --encoder resnet50 --epochs 30
    heapgrasp seg eval runs/seg-net/segmentation.onnx runs/seg-heldout
    heapgrasp seg predict runs/seg-net/segmentation.onnx photo1.png photo2.jpg --out preds
    heapgrasp seg coco labels.json --images photos/ --out runs/seg-real \\
        --class transparent=glass,bottle --class specular=can --class opaque=box

``DATA_DIR`` holds ``images/*.png|jpg`` and ``masks/*.png`` of the same stems, masks
holding class ids 0..3 (:mod:`heapgrasp.training.segmentation`). ``train`` writes
``OUT/segmentation.onnx`` (run by ``segmenter = "network"``, ``seg_weights = ...``),
``metrics.json`` (per-class IoU, mIoU, pixel accuracy on the validation split),
``metrics.csv``, ``metrics.png`` and a checkpoint per epoch (``--resume`` continues).
Training and ``eval`` need ``pip install 'heapgrasp[train]'``; ``predict`` runs the
ONNX file with onnxruntime only. Nothing is downloaded: the encoder starts from random
weights, or from ``--encoder-weights FILE`` (a local ImageNet checkpoint). Bad
arguments exit 2 with a message naming them. See docs/segmentation.md.

``heapgrasp seg data``: the segmentation network's dataset (docs/segmentation.md)::

    heapgrasp seg data runs/seg-synth --scenes 500 --views 8 --size 320x240

Rendered RGB images of random scenes and their exact 4-class masks, as ``images/`` and
``masks/`` PNGs that ``heapgrasp seg train`` reads (:mod:`heapgrasp.data.seg`).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path
from typing import Any, TypeAlias

from heapgrasp.cli.argtypes import float_in, int_at_least
from heapgrasp.cli.datasets import dataset_parser, generate_command, section

__all__ = ["add_data", "add_parser", "size_arg"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"

ENCODERS = ("resnet50", "resnet18", "mobilenet_v2")


def _error(message: str) -> int:
    print(f"heapgrasp: error: {message}", file=sys.stderr)
    return 2


def size_arg(text: str) -> tuple[int, int]:
    """``WxH`` → ``(H, W)``."""
    w, sep, h = text.lower().partition("x")
    try:
        width, height = int(w), int(h)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not WIDTHxHEIGHT: {text!r}") from None
    if not sep or width < 16 or height < 16:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, each >= 16; got {text!r}")
    return height, width


def _training() -> Any:
    try:
        from heapgrasp.training import segmentation
    except ImportError as exc:
        raise ImportError(f"{exc} (pip install 'heapgrasp[train]')") from None
    return segmentation


def _train(args: argparse.Namespace) -> int:
    data = Path(args.data)
    if not data.is_dir():
        return _error(f"DATA_DIR {str(data)!r} is not a directory")
    if args.encoder_weights is not None and not Path(args.encoder_weights).is_file():
        return _error(f"--encoder-weights {args.encoder_weights!r}: file not found")
    try:
        seg = _training()
    except ImportError as exc:
        return _error(str(exc))
    try:
        config = seg.SegTrainConfig(
            encoder=args.encoder,
            epochs=args.epochs,
            batch=args.batch,
            lr=args.lr,
            val_fraction=args.val_fraction,
            seed=args.seed,
            size=args.size,
            encoder_weights=args.encoder_weights,
            device=args.device,
        )
    except ValueError as exc:
        return _error(str(exc))
    if args.threads is not None:
        import torch

        torch.set_num_threads(args.threads)
    command = "heapgrasp " + shlex.join(getattr(args, "argv", sys.argv[1:]))
    log = None if args.quiet else (lambda m: print(m, file=sys.stderr))
    try:
        result = seg.train(
            data,
            args.out,
            config,
            resume=args.resume,
            progress=not args.quiet,
            log=log,
            command=command,
        )
    except (FileNotFoundError, ValueError) as exc:  # the data, a checkpoint, the weights
        return _error(str(exc))
    from heapgrasp.perception.segnet import NetworkSegmenter

    NetworkSegmenter(result.onnx)  # the file as the loop opens it
    val = result.metrics["val"]
    print(_table(val))
    summary = {"out": str(args.out), "onnx": str(result.onnx), "best_epoch": result.best_epoch}
    print(json.dumps({**summary, "miou": val["miou"]}))
    return 0


def _fmt(value: Any) -> str:
    return "  n/a" if value is None or value != value else f"{value:.3f}"


def _table(metrics: dict[str, Any]) -> str:
    """Per-class IoU, mIoU and pixel accuracy as a text table."""
    from heapgrasp.perception.segnet import CLASSES

    lines = [f"{'class':<14} {'IoU':>6}"]
    lines += [f"{c:<14} {_fmt(metrics.get(f'iou_{c}')):>6}" for c in CLASSES]
    for key, label in (
        ("miou", "mIoU"),
        ("miou_objects", "mIoU objects"),
        ("silhouette_iou", "silhouette IoU"),
        ("pixel_accuracy", "pixel accuracy"),
    ):
        lines.append(f"{label:<14} {_fmt(metrics.get(key)):>6}")
    return "\n".join(lines)


def _open_segmenter(path: str, device: str) -> Any:
    from heapgrasp.perception.segnet import NetworkSegmenter

    return NetworkSegmenter(path, device=device)


def _eval(args: argparse.Namespace) -> int:
    data = Path(args.data)
    if not data.is_dir():
        return _error(f"DATA_DIR {str(data)!r} is not a directory")
    try:
        net = _open_segmenter(args.weights, args.device)
    except (FileNotFoundError, ValueError) as exc:
        return _error(str(exc))
    try:
        seg = _training()
        folder = seg.SegFolder.open(data)
    except (ImportError, FileNotFoundError, ValueError) as exc:
        return _error(str(exc))
    metrics = seg.evaluate(net.predict, folder, progress=not args.quiet)
    from heapgrasp.training.common import finite

    print(_table(metrics))
    doc = finite({"weights": str(args.weights), "data": str(data), **metrics})
    text = json.dumps(doc, indent=2)
    if args.json:
        Path(args.json).write_text(text + "\n")
    else:
        print(text)
    return 0


def _predict(args: argparse.Namespace) -> int:
    import numpy as np
    from PIL import Image, UnidentifiedImageError
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    from heapgrasp.perception.segnet import class_fractions, colorize

    missing = [p for p in args.images if not Path(p).is_file()]
    if missing:
        return _error(f"image not found: {missing[0]!r}")
    try:
        net = _open_segmenter(args.weights, args.device)
    except (FileNotFoundError, ValueError) as exc:
        return _error(str(exc))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {"weights": str(args.weights), "classes": list(net.classes)}
    images: dict[str, Any] = {}
    for name in tqdm(args.images, unit="image", disable=True if args.quiet else None):
        p = Path(name)
        try:
            with Image.open(p) as im:
                rgb = np.asarray(im.convert("RGB"))
        except (OSError, UnidentifiedImageError) as exc:
            return _error(f"{p}: not a readable image ({exc})")
        labels = net.predict(rgb)
        Image.fromarray(labels).save(out / f"{p.stem}_labels.png")
        Image.fromarray(colorize(labels)).save(out / f"{p.stem}_mask.png")
        images[str(p)] = class_fractions(labels, net.classes)
    report["images"] = images
    (out / "predictions.json").write_text(json.dumps(report, indent=2) + "\n")
    print(json.dumps({"out": str(out), "images": len(images)}))
    return 0


def _data(args: argparse.Namespace) -> int:
    from heapgrasp.data.seg import SegDataConfig

    height, width = args.size
    return generate_command(
        args, SegDataConfig, views=args.views, width=width, height=height, out_dir=args.out
    )


def _coco(args: argparse.Namespace) -> int:
    from heapgrasp.data.coco import CocoError, convert, parse_class_map

    try:
        summary = convert(
            args.annotations,
            args.images,
            args.out,
            parse_class_map(args.class_ or []),
            unmapped=args.unmapped,
        )
    except CocoError as exc:
        return _error(str(exc))
    print(
        f"wrote {summary['images']} images and masks ({summary['annotations']} annotations) "
        f"to {args.out}; pixels per class: {summary['pixels']}"
    )
    if summary["unmapped_as_background"]:
        print(f"categories left as background: {', '.join(summary['unmapped_as_background'])}")
    return 0


def add_data(sub: SubParsers, name: str = "data") -> argparse.ArgumentParser:
    """Adds ``seg data`` (under ``name``)."""
    p = dataset_parser(
        sub,
        name,
        "segmentation data: rendered RGB images and exact 4-class masks (images/, masks/)",
        section(__doc__, "seg data"),
        scenes=100,
        shard_size=10,
    )
    p.add_argument("--views", type=int_at_least(1), default=8, help="images per scene (8)")
    p.add_argument("--size", type=size_arg, default=(240, 320), metavar="WxH", help="(320x240)")
    p.set_defaults(func=_data)
    return p


def add_parser(commands: SubParsers) -> argparse.ArgumentParser:
    """Adds ``seg`` and its commands."""
    group = commands.add_parser(
        "seg",
        help="the 4-class segmentation network: its data, train, eval, predict; COCO labels "
        "to masks",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = group.add_subparsers(dest="seg_command", metavar="COMMAND", required=True)
    add_data(sub)
    t = sub.add_parser("train", help="train DeepLabv3+ on images and label masks")
    t.add_argument("data", metavar="DATA_DIR", help="folder of images/ and masks/")
    t.add_argument("--out", required=True, metavar="RUN_DIR", help="output directory")
    t.add_argument(
        "--encoder",
        choices=ENCODERS,
        default="resnet50",
        help="resnet50 (the paper's), resnet18 or mobilenet_v2 (CPU-only machines)",
    )
    t.add_argument("--epochs", type=int_at_least(1), default=30, help="epochs (default 30)")
    t.add_argument("--batch", type=int_at_least(2), default=8, help="batch size (default 8)")
    t.add_argument(
        "--lr", type=float_in(0.0, 1.0, open_low=True), default=1e-4, help="Adam's (1e-4)"
    )
    t.add_argument(
        "--val-fraction",
        type=float_in(0.0, 0.9, open_low=True),
        default=0.1,
        help="share of image groups held out for validation (default 0.1)",
    )
    t.add_argument("--seed", type=int_at_least(0), default=0, help="random seed (default 0)")
    t.add_argument(
        "--size",
        type=size_arg,
        default=None,
        metavar="WxH",
        help="training image size (default: the first image's; others are resized)",
    )
    t.add_argument(
        "--encoder-weights",
        metavar="FILE",
        default=None,
        help="a local ImageNet state dict of the encoder (.pth or .safetensors); "
        "default: random (nothing is downloaded)",
    )
    t.add_argument(
        "--device",
        default="auto",
        help="PyTorch device: cpu, cuda, cuda:N or auto (default auto)",
    )
    t.add_argument("--threads", type=int_at_least(1), default=None, help="PyTorch CPU threads")
    t.add_argument("--resume", action="store_true", help="continue RUN_DIR's checkpoint")
    t.add_argument("--quiet", action="store_true", help="no progress bars or epoch lines")
    t.set_defaults(func=_train)

    e = sub.add_parser("eval", help="per-class IoU and mIoU of an ONNX file on a folder")
    e.add_argument("weights", metavar="WEIGHTS.onnx")
    e.add_argument("data", metavar="DATA_DIR", help="folder of images/ and masks/")
    e.add_argument("--device", default="cpu", help="onnxruntime device (default cpu)")
    e.add_argument("--json", metavar="FILE", help="write the JSON here instead of stdout")
    e.add_argument("--quiet", action="store_true", help="no progress bar")
    e.set_defaults(func=_eval)

    p = sub.add_parser("predict", help="colour-coded masks and class fractions of images")
    p.add_argument("weights", metavar="WEIGHTS.onnx")
    p.add_argument("images", nargs="+", metavar="IMAGE")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--device", default="cpu", help="onnxruntime device (default cpu)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_predict)

    c = sub.add_parser(
        "coco",
        help="COCO polygon annotations to the images/ + masks/ folder seg train reads",
        description="Rasterises a COCO instance file (polygons, uncompressed RLE) into "
        "class-id masks: every COCO category is mapped to transparent, specular, opaque or "
        "background with --class; smaller objects are drawn over larger ones.",
    )
    c.add_argument("annotations", metavar="ANNOTATIONS.json")
    c.add_argument("--images", required=True, metavar="DIR", help="where file_name is found")
    c.add_argument("--out", required=True, metavar="DIR", help="output folder")
    c.add_argument(
        "--class",
        dest="class_",
        action="append",
        metavar="CLASS=NAME[,NAME]",
        help="map COCO categories to a class, e.g. --class transparent=glass,bottle (repeatable)",
    )
    c.add_argument(
        "--unmapped",
        choices=("error", "background"),
        default="error",
        help="what a category mapped to no class becomes (default: an error naming it)",
    )
    c.set_defaults(func=_coco)
    return group
