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

__all__ = ["ENCODERS", "measure"]

ENCODERS = ("resnet50", "resnet18", "mobilenet_v2")


def measure(encoder: str, width: int, height: int, *, threads: int, repeats: int) -> dict[str, Any]:
    """One encoder's size and time per frame (see the module docstring)."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    import torch

    from heapgrasp.perception.segnet import NetworkSegmenter
    from heapgrasp.training.segmentation import build_model, export_segmentation

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
