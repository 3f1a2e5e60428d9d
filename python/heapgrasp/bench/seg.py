"""``heapgrasp bench seg``: CPU time of the segmentation network per frame, per encoder.

Each encoder's DeepLabV3+ (random weights: the time does not depend on them) is exported
to ONNX as ``heapgrasp seg train`` exports it and run through
:class:`~heapgrasp.perception.segnet.NetworkSegmenter` (onnxruntime) on one random RGB
frame: the median and the fastest of ``--repeats`` runs after 3 warm-up runs, and the
file's size. Needs the ``train`` extra (PyTorch, segmentation-models-pytorch) to build
the networks; nothing is downloaded.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.bench.argtypes import comma_choices, int_at_least

__all__ = ["ENCODERS", "add_parser", "measure"]

ENCODERS = ("resnet50", "resnet18", "mobilenet_v2")


def measure(encoder: str, width: int, height: int, *, threads: int, repeats: int) -> dict[str, Any]:
    """One encoder's size and time per frame (see the module docstring)."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    import torch

    from heapgrasp.nets.segmentation import build_model, export_segmentation
    from heapgrasp.perception.segnet import NetworkSegmenter

    torch.manual_seed(0)
    rgb = np.random.default_rng(0).integers(0, 256, (height, width, 3)).astype(np.uint8)
    with tempfile.TemporaryDirectory() as tmp:
        path = export_segmentation(
            build_model(encoder), Path(tmp) / "seg.onnx", input_size=(height, width)
        )
        size = Path(path).stat().st_size
        net = NetworkSegmenter(path, threads=threads)
        for _ in range(3):
            net.predict(rgb)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            net.predict(rgb)
            times.append(time.perf_counter() - t0)
    return {
        "encoder": encoder,
        "size_mb": size / 1e6,
        "median_ms": 1000 * float(np.median(times)),
        "min_ms": 1000 * float(np.min(times)),
        "threads": threads,
        "frame": f"{width}x{height}",
    }


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark and prints a table (and ``--json``)."""
    width, _, height = args.size.partition("x")
    rows = []
    for enc in args.encoders:
        row = measure(enc, int(width), int(height), threads=args.threads, repeats=args.repeats)
        rows.append(row)
        print(
            f"{enc:13s} {row['size_mb']:6.1f} MB  median {row['median_ms']:7.1f} ms  "
            f"fastest {row['min_ms']:7.1f} ms  ({args.threads} thread(s), {row['frame']})"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2))
    return 0


def _size(text: str) -> str:
    w, sep, h = text.partition("x")
    if not (sep and w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, e.g. 320x240, got {text!r}")
    return text


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Adds ``heapgrasp bench seg``."""
    p = subparsers.add_parser(
        "seg",
        help="CPU time of the segmentation network per frame, per encoder",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--encoders",
        type=comma_choices("encoder", ENCODERS),
        default=ENCODERS,
        help=f"comma-separated encoders (default: {','.join(ENCODERS)})",
    )
    p.add_argument("--size", type=_size, default="320x240", help="frame size (default 320x240)")
    p.add_argument("--threads", type=int_at_least(1), default=1, help="onnxruntime threads")
    p.add_argument("--repeats", type=int_at_least(1), default=20, help="timed runs (default 20)")
    p.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    p.set_defaults(func=run)
    return p
