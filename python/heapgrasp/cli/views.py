"""``heapgrasp views data|train``: the view network's dataset (HEAPGrasp Algorithm 1) and
the view network (eq. 13) trained on it.

``heapgrasp views data``: the view network's dataset (HEAPGrasp Algorithm 1)::

    heapgrasp views data runs/views-train --scenes 6000 --split train
    heapgrasp views data runs/views-val --scenes 600 --split val --seed 1
    heapgrasp views data runs/views-test --scenes 400 --split test --seed 2

Every scene is a fresh pile or packed scene of 1 to N_ob objects, captured along
k ~ U{0..L−1} random view waypoints, and labelled with the exact eq. 14 score of all
U × V candidates (:mod:`heapgrasp.data.views`).

``heapgrasp views train``: the view network trained on those datasets::

    heapgrasp views train runs/views-train --val runs/views-val --test runs/views-test \\
        --out runs/view-net --epochs 30

Trains on the ``train`` datasets (:mod:`heapgrasp.training.train_views`), validates on the
``val`` dataset after every epoch, keeps the best epoch's weights and writes
``OUT/view_network.safetensors`` with its model card ``OUT/view_network.json`` and
``OUT/metrics.json`` (validation and, with ``--test``, test metrics). Needs
``pip install 'heapgrasp[train]'``. Bad input exits 2 with a message naming it.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import sys
import textwrap
from pathlib import Path
from typing import Any, TypeAlias

from heapgrasp.cli.argtypes import float_in, int_at_least
from heapgrasp.cli.datasets import dataset_parser, generate_command, section
from heapgrasp.cli.training import (
    add_cpu_options,
    add_run_options,
    command_line,
    config_error,
    require_training,
    threads,
)

__all__ = ["add_data", "add_parser", "add_train"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def _data(args: argparse.Namespace) -> int:
    from heapgrasp.data.views import ViewDataConfig

    return generate_command(args, ViewDataConfig, region_fraction=args.region_fraction)


def _train(args: argparse.Namespace) -> int:
    require_training("views train")
    import torch

    from heapgrasp.training.common import card_header, data_sources, write_metrics
    from heapgrasp.training.device import resolve_device
    from heapgrasp.training.train_views import (
        TrainConfig,
        TrainSetupError,
        save_view_network,
        train,
    )
    from heapgrasp.training.view_data import (
        ViewDataError,
        check_compatible,
        concatenate,
        load_view_dataset,
    )
    from heapgrasp.training.view_eval import evaluate

    workers = threads(args)
    try:
        device = resolve_device(args.device)
        config = TrainConfig(
            epochs=args.epochs,
            batch_size=args.batch_size,
            lr=args.lr,
            loss=args.loss,
            seed=args.seed,
            in_channels=args.in_channels,
        )
        train_sets = [load_view_dataset(d, workers=workers) for d in args.data]
        for d in train_sets:
            if d.split != "train":
                raise TrainSetupError(
                    f"{d.sources[0].path} is a {d.split!r} dataset; only 'train' datasets "
                    "are trained on (give a 'val' one to --val, a 'test' one to --test)"
                )
        train_data = concatenate(train_sets)
        val_data = load_view_dataset(args.val, workers=workers)
        test_data = load_view_dataset(args.test, workers=workers) if args.test else None
        if test_data is not None:
            if test_data.split != "test":
                raise TrainSetupError(
                    f"--test {args.test}: a {test_data.split!r} dataset, not a 'test' one"
                )
            check_compatible(train_data, test_data)
            shared = train_data.objects & test_data.objects
            if shared:
                raise TrainSetupError(
                    f"--test {args.test} shares objects with the training data "
                    f"({', '.join(sorted(shared)[:5])})"
                )
        print(
            f"{len(train_data)} training samples from {len(train_sets)} dataset(s), "
            f"{len(val_data)} validation samples"
            + (f", {len(test_data)} test samples" if test_data is not None else "")
            + f"; {device}",
            flush=True,
        )

    except (ViewDataError, TrainSetupError, ValueError) as exc:
        raise config_error(str(exc)) from None

    def evaluator(net: Any, data: Any) -> dict[str, float]:
        return evaluate(net, data, loss=config.loss, device=device)

    try:
        result = train(
            config,
            train_data,
            val_data,
            args.out,
            device=device,
            resume=args.resume,
            evaluator=evaluator,
            progress=not args.no_progress,
        )
    except (ViewDataError, TrainSetupError) as exc:
        raise config_error(str(exc)) from None

    out = Path(args.out)
    metrics: dict[str, Any] = {
        "best_epoch": result.best_epoch,
        "val": evaluate(result.net, val_data, loss=config.loss, device=device),
    }
    if test_data is not None:
        metrics["test"] = evaluate(result.net, test_data, loss=config.loss, device=device)
    metrics = write_metrics(out, metrics)
    card = {
        **card_header(command_line(args)),
        "machine": {
            "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "torch": torch.__version__,
            "device": device,
            "device_name": (
                torch.cuda.get_device_name(torch.device(device))
                if device.startswith("cuda")
                else platform.processor() or platform.machine()
            ),
            "threads": torch.get_num_threads(),
        },
        "input": (
            "channel 0: occupancy segmented/visible (0 where unseen), float32 (B, C, R, R, R) "
            "indexed [x, y, z]"
            + (
                "; channel 1: eq. 14's region, x-y column mask broadcast along z"
                if config.in_channels >= 2
                else ""
            )
            + (
                "; channel 2: each voxel centre's distance to the current camera / 0.5 m"
                if config.in_channels == 3
                else ""
            )
        ),
        "output": "sigmoid (B, U, V): row u = azimuth 2 pi u / U, column v = theta_max v / V",
        "geometry": {
            k: getattr(train_data.geometry, k)
            for k in ("resolution", "U", "V", "theta_max", "cube_size", "radius", "lam")
        },
        "data": data_sources(train_data, val_data, test_data),
        "training": {
            **config.as_dict(),
            "device": device,
            "best_epoch": result.best_epoch,
            "seconds": round(result.seconds, 1),
            "seconds_per_epoch": round(result.seconds / max(len(result.history), 1), 2),
            "selection": "best epoch by validation median Spearman rho",
            "symmetries": "8: quarter turns about z (u + k U/4) x mirror y -> -y (u -> -u)",
        },
        "metrics": metrics,
    }
    weights, meta = save_view_network(result.net, out / "view_network.safetensors", card)
    written = [weights, meta, out / "metrics.json"]
    try:
        export = importlib.import_module("heapgrasp.training.export")
    except ImportError as exc:  # no exporter in this version, or onnx not installed
        print(f"no ONNX file written ({exc})", file=sys.stderr)
    else:
        onnx_path = out / "view_network.onnx"
        export.export_onnx(result.net, onnx_path, provenance=card)
        written.append(onnx_path)
    print(json.dumps(metrics, indent=2))
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def add_data(sub: SubParsers, name: str = "data") -> argparse.ArgumentParser:
    """Adds ``views data`` (under ``name``)."""
    p = dataset_parser(
        sub,
        name,
        "view-network data: Algorithm 1 with exact eq. 14 labels",
        section(__doc__, "views data"),
        scenes=1000,
        shard_size=50,
    )
    p.add_argument(
        "--region-fraction",
        type=float_in(0.0, 1.0),
        default=0.5,
        help="share of k >= 1 samples labelled on a target's column (default 0.5)",
    )
    p.set_defaults(func=_data)
    return p


def add_train(sub: SubParsers, name: str = "train") -> argparse.ArgumentParser:
    """Adds ``views train`` (under ``name``)."""
    v = sub.add_parser(
        name,
        help="train the view network (eq. 13) on view datasets",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            "Trains the view network (HEAPGrasp eq. 13) on datasets of 'heapgrasp views "
            "data': input the occupancy grid (and with --in-channels 2 the region mask), "
            "target the exact eq. 14 scores of the U x V candidates. Each batch is turned "
            "by one of the problem's 8 symmetries (quarter turns about z shift u by U/4; "
            "the mirror y -> -y sends u to -u). Adam with a cosine learning rate; after "
            "every epoch: validation, OUT/checkpoint.safetensors, OUT/metrics.csv and "
            "OUT/metrics.png; the best epoch by validation median Spearman rho is kept "
            "(OUT/best.safetensors). At the end: OUT/view_network.safetensors, its model "
            "card OUT/view_network.json and OUT/metrics.json (loss, Spearman rho, top-1 "
            "regret, eq. 18 agreement with the oracle at gamma2 = 0 and 0.35 on the "
            "validation and test data).",
            width=80,
        ),
        epilog=(
            "example:\n"
            "  heapgrasp views train runs/views-train --val runs/views-val \\\n"
            "      --test runs/views-test --out runs/view-net --epochs 30\n"
            "  heapgrasp views train runs/views-train --val runs/views-val \\\n"
            "      --out runs/view-net --epochs 30 --resume   # continue after a stop"
        ),
    )
    v.add_argument("data", nargs="+", metavar="DATA_DIR", help="training datasets (split 'train')")
    v.add_argument("--out", required=True, help="output directory")
    v.add_argument("--val", required=True, metavar="DIR", help="validation dataset (split 'val')")
    v.add_argument(
        "--test",
        metavar="DIR",
        help="test dataset (split 'test', held-out objects), evaluated once at the end",
    )
    v.add_argument("--epochs", type=int_at_least(1), default=30, help="epochs (default 30)")
    v.add_argument(
        "--batch-size", type=int_at_least(1), default=32, help="samples per step (default 32)"
    )
    v.add_argument(
        "--lr",
        type=float_in(0.0, open_low=True),
        default=1e-3,
        help="Adam's initial learning rate, cosine-annealed to 0 (default 1e-3)",
    )
    v.add_argument(
        "--loss",
        choices=("bce", "mse"),
        default="bce",
        help="loss on the U x V map, labels clipped to [0, 1] (default bce; mse through "
        "the sigmoid can stall with every output saturated)",
    )
    add_run_options(v, seed_help="initial weights, order, symmetries (0)")
    v.add_argument(
        "--in-channels",
        type=int,
        choices=(1, 2, 3),
        default=1,
        help="1: occupancy only (the paper); 2: plus the region mask eq. 14 was counted on; "
        "3: plus the distance of each voxel to the current camera",
    )
    add_cpu_options(v, "")
    v.set_defaults(func=_train)
    return v


def add_parser(commands: SubParsers) -> argparse.ArgumentParser:
    """Adds ``views`` and its commands ``data`` and ``train``."""
    group = commands.add_parser(
        "views",
        help="the view network: its dataset (Algorithm 1), its training (eq. 13)",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    sub = group.add_subparsers(dest="views_command", metavar="COMMAND", required=True)
    add_data(sub)
    add_train(sub)
    return group
