"""``heapgrasp train views|grasps``: the view network (HEAPGrasp eq. 13) trained on view
datasets, the grasp network (eq. 11, VGN's) on grasp datasets.

::

    heapgrasp data views runs/views-train --split train ...
    heapgrasp data views runs/views-val --split val ...
    heapgrasp train views runs/views-train --val runs/views-val --test runs/views-test \\
        --out runs/view-net --epochs 30

Trains on the ``train`` datasets (:mod:`heapgrasp.nets.train_views`), validates on the
``val`` dataset after every epoch, keeps the best epoch's weights and writes
``OUT/view_network.safetensors`` with its model card ``OUT/view_network.json`` and
``OUT/metrics.json`` (validation and, with ``--test``, test metrics).

::

    heapgrasp data grasps runs/grasps/train --split train ...
    heapgrasp data grasps runs/grasps/val --split val ...
    heapgrasp train grasps runs/grasps --out runs/grasp-net --input occupancy

trains the grasp network (:mod:`heapgrasp.nets.train_grasps`) on every ``train``
dataset found, validates on the ``val`` ones, evaluates the best epoch on the ``test``
ones and writes ``OUT/grasp_network.{safetensors,json,onnx}`` and ``OUT/metrics.json``.
Needs ``pip install 'heapgrasp[train]'``. Bad input exits 2 with a message naming it.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import shlex
import sys
import textwrap
from pathlib import Path
from typing import Any

from heapgrasp.bench.argtypes import float_in, int_at_least

__all__ = ["add_parser"]


def _config_error(message: str) -> Exception:
    """heapgrasp's configuration error (exit status 2, no traceback)."""
    from heapgrasp.loop.config import ConfigError

    return ConfigError(message)


def _require_training(command: str) -> None:
    """A ConfigError naming what to install when PyTorch or safetensors is missing."""
    try:
        importlib.import_module("heapgrasp.nets")
        importlib.import_module("safetensors")
    except ImportError as exc:
        missing = (exc.name or "PyTorch").split(".")[0]
        if missing.startswith("heapgrasp"):
            missing = "torch"
        raise _config_error(
            f"heapgrasp train {command} needs PyTorch and safetensors ({missing} is not "
            "installed): pip install 'heapgrasp[train]'"
        ) from None


def _threads(args: argparse.Namespace) -> int:
    """``--workers`` as PyTorch's thread count (where given); the shard readers' count."""
    import torch

    if args.workers is not None:
        torch.set_num_threads(args.workers)
    return int(args.workers or 1)


def _command(args: argparse.Namespace) -> str:
    """The command line that trained the network, for its model card."""
    return "heapgrasp " + shlex.join(getattr(args, "argv", sys.argv[1:]))


def _views(args: argparse.Namespace) -> int:
    _require_training("views")
    import torch

    from heapgrasp.nets.device import resolve_device
    from heapgrasp.nets.train_views import (
        TrainConfig,
        TrainSetupError,
        save_view_network,
        train,
    )
    from heapgrasp.nets.training import card_header, data_sources, write_metrics
    from heapgrasp.nets.view_data import (
        ViewDataError,
        check_compatible,
        concatenate,
        load_view_dataset,
    )
    from heapgrasp.planning.view_eval import evaluate

    workers = _threads(args)
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
        raise _config_error(str(exc)) from None

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
        raise _config_error(str(exc)) from None

    out = Path(args.out)
    metrics: dict[str, Any] = {
        "best_epoch": result.best_epoch,
        "val": evaluate(result.net, val_data, loss=config.loss, device=device),
    }
    if test_data is not None:
        metrics["test"] = evaluate(result.net, test_data, loss=config.loss, device=device)
    metrics = write_metrics(out, metrics)
    card = {
        **card_header(_command(args)),
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
        export = importlib.import_module("heapgrasp.nets.export")
    except ImportError as exc:  # no exporter in this version, or onnx not installed
        print(f"no ONNX file written ({exc})", file=sys.stderr)
    else:
        onnx_path = out / "view_network.onnx"
        export.export_onnx(result.net, onnx_path, provenance=card)
        written.append(onnx_path)
    print(json.dumps(metrics, indent=2))
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _grasps(args: argparse.Namespace) -> int:
    _require_training("grasps")
    from heapgrasp.nets.device import resolve_device
    from heapgrasp.nets.grasp_data import (
        GraspDataError,
        concatenate,
        find_datasets,
        load_grasp_dataset,
    )
    from heapgrasp.nets.train_grasps import (
        GraspTrainConfig,
        check_datasets,
        train,
        write_outputs,
    )
    from heapgrasp.nets.training import TrainSetupError

    workers = _threads(args)
    try:
        device = resolve_device(args.device)
        dirs = find_datasets(args.data)
        first = load_grasp_dataset(dirs[0], input_kind=args.input, workers=workers)
        config = GraspTrainConfig(
            epochs=args.epochs,
            batch_size=args.batch_size,
            lr=args.lr,
            seed=args.seed,
            input_kind=first.input_kind,
            channels=tuple(args.channels),
            head_kernel=args.head_kernel,
        )
        found = [first] + [
            load_grasp_dataset(d, input_kind=config.input_kind, workers=workers) for d in dirs[1:]
        ]
        split = {s: [d for d in found if d.split == s] for s in ("train", "val", "test")}
        where = ", ".join(args.data)
        for name in ("train", "val"):
            if not split[name]:
                raise TrainSetupError(
                    f"no {name!r} grasp dataset in {where} (found: "
                    + (", ".join(f"{d.sources[0].path} ({d.split})" for d in found) or "none")
                    + f"); write one with 'heapgrasp data grasps DIR --split {name}'"
                )
        train_data, val_data = concatenate(split["train"]), concatenate(split["val"])
        test_data = concatenate(split["test"]) if split["test"] else None
        check_datasets(train_data, val_data, test_data)
        print(
            f"{config.input_kind}: train {train_data.summary()}; val {val_data.summary()}"
            + (f"; test {test_data.summary()}" if test_data is not None else "; no test data")
            + f"; {device}",
            flush=True,
        )
        result = train(
            config,
            train_data,
            val_data,
            args.out,
            device=device,
            resume=args.resume,
            init=args.init,
            progress=not args.no_progress,
        )
    except (GraspDataError, TrainSetupError, ValueError) as exc:
        raise _config_error(str(exc)) from None
    written = write_outputs(
        result,
        config,
        args.out,
        train_data=train_data,
        val_data=val_data,
        test_data=test_data,
        device=device,
        command=_command(args),
        init=args.init,
    )
    print((Path(args.out) / "metrics.json").read_text().rstrip())
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _viewsphere_policy(args: argparse.Namespace) -> int:
    """``heapgrasp train viewsphere-policy``."""
    from heapgrasp.viewsphere import training as vt

    out = Path(args.out)
    try:
        if args.kind == "dqn":
            if args.data or args.val:
                raise _config_error("--kind dqn plays episodes; it reads no --data or --val")
            try:
                config = vt.DqnConfig(
                    episodes=args.episodes, seed=args.seed, objects=tuple(args.objects or ())
                )
            except ValueError as exc:
                raise _config_error(str(exc)) from None
            metrics = vt.train_dqn(
                config,
                out,
                progress=not args.no_progress,
                log=lambda line: print(line, file=sys.stderr),
            )
            metrics = {k: v for k, v in metrics.items() if k != "history"}
        else:
            if not args.data or not args.val:
                raise _config_error(f"--kind {args.kind} needs --data DIR and --val DIR")
            try:
                metrics = vt.train_linear(
                    args.kind.removeprefix("pca-"),
                    [Path(p) for p in args.data],
                    [Path(p) for p in args.val],
                    out,
                    seed=args.seed,
                )
            except (FileNotFoundError, ValueError) as exc:
                raise _config_error(str(exc)) from None
    except ImportError as exc:
        raise _config_error(str(exc)) from None
    print(json.dumps(metrics, indent=1))
    return 0


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Adds ``train views``, ``train grasps`` and ``train viewsphere-policy``."""
    p = subparsers.add_parser(
        "train",
        help="train the learned networks (the view network, the grasp network)",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    sub = p.add_subparsers(dest="train_command", metavar="NETWORK", required=True)
    v = sub.add_parser(
        "views",
        help="train the view network (eq. 13) on view datasets",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            "Trains the view network (HEAPGrasp eq. 13) on datasets of 'heapgrasp data "
            "views': input the occupancy grid (and with --in-channels 2 the region mask), "
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
            "  heapgrasp train views runs/views-train --val runs/views-val \\\n"
            "      --test runs/views-test --out runs/view-net --epochs 30\n"
            "  heapgrasp train views runs/views-train --val runs/views-val \\\n"
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
    _add_run_options(v, seed_help="initial weights, order, symmetries (0)")
    v.add_argument(
        "--in-channels",
        type=int,
        choices=(1, 2, 3),
        default=1,
        help="1: occupancy only (the paper); 2: plus the region mask eq. 14 was counted on; "
        "3: plus the distance of each voxel to the current camera",
    )
    _add_cpu_options(v, "")
    v.set_defaults(func=_views)
    _add_grasps(sub)
    return p


def _add_grasps(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    g = sub.add_parser(
        "grasps",
        help="train the grasp network (eq. 11, VGN's) on grasp datasets",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            "Trains the grasp network (HEAPGrasp eq. 11: VGN's encoder-decoder giving grasp "
            "quality, orientation and opening width at every voxel) on datasets of "
            "'heapgrasp data grasps'. The splits come from the data: every 'train' dataset "
            "found under DATA is trained on, the 'val' ones (held-out objects) validate "
            "after every epoch, the 'test' ones (the benchmark's objects) are evaluated "
            "once at the end with the best epoch's weights. A step reads --batch-size "
            "scenes, each turned by a random quarter turn about z and shifted by up to 4 "
            "voxels, and takes VGN's loss at every labelled voxel: quality BCE, plus on "
            "the successful grasps the orientation (1 - |<q, q_label>|, the nearer of the "
            "label and its finger-swapped twin) and 0.01 x the squared width error in "
            "voxels. Adam at a constant learning rate. After every epoch: "
            "OUT/checkpoint.safetensors, OUT/metrics.csv and OUT/metrics.png (loss "
            "terms; on the validation data precision and recall of quality >= 0.5, 0.8 "
            "and 0.9, average precision, width error (m) and rotation error (degrees) on "
            "the successful grasps); the epoch with the lowest validation loss is kept. "
            "At the end: OUT/grasp_network.safetensors, its model card "
            "OUT/grasp_network.json, OUT/grasp_network.onnx (what 'heapgrasp run "
            "--grasp-weights' loads) and OUT/metrics.json.",
            width=80,
        ),
        epilog=(
            "example:\n"
            "  heapgrasp train grasps runs/grasps --out runs/grasp-net --epochs 20\n"
            "  heapgrasp train grasps runs/vgn-grasps --out runs/vgn-net   # tsdf data\n"
            "  heapgrasp train grasps runs/grasps --out runs/grasp-net --epochs 20 "
            "--resume   # continue after a stop\n"
            "  heapgrasp train grasps runs/grasps --out runs/grasp-net --epochs 30 "
            "--resume   # train a finished run 10 epochs more\n"
            "  heapgrasp train grasps runs/grasps runs/loop-grasps --out runs/dagger-1 "
            "--init models/grasp-network/grasp_network.safetensors   # a DAgger round"
        ),
    )
    g.add_argument(
        "data",
        nargs="+",
        metavar="DATA",
        help="grasp dataset directories, or directories holding them (DATA/train, "
        "DATA/val, DATA/test); their manifests give the splits",
    )
    g.add_argument("--out", required=True, help="output directory")
    g.add_argument(
        "--input",
        choices=("occupancy", "tsdf"),
        default=None,
        help="the grid the network reads: occupancy (S>=lambda, for heapgrasp and no-vp) "
        "or tsdf (for the vgn method); every dataset must hold it (default: the one the "
        "datasets were made with, 'heapgrasp data grasps --input')",
    )
    g.add_argument("--epochs", type=int_at_least(1), default=20, help="epochs (default 20)")
    g.add_argument(
        "--batch-size",
        type=int_at_least(1),
        default=8,
        help="scenes per step, with all their labelled grasps (default 8)",
    )
    g.add_argument(
        "--lr",
        type=float_in(0.0, open_low=True),
        default=3e-4,
        help="Adam's learning rate (default 3e-4, VGN's)",
    )
    g.add_argument(
        "--channels",
        nargs=3,
        type=int_at_least(1),
        default=[8, 16, 32],
        metavar="C",
        help="the encoder's three channel counts, the decoder's are the reverse "
        "(default 8 16 32: with --head-kernel 3, planning in under 30 ms on a 2-core CPU; "
        "VGN's is 16 32 64)",
    )
    g.add_argument(
        "--head-kernel",
        type=int,
        choices=(3, 5),
        default=3,
        help="kernel of the last decoder convolution and the three heads (default 3; "
        "VGN's 5 costs about 4x more at full resolution, where most of the time goes)",
    )
    g.add_argument(
        "--init",
        type=Path,
        default=None,
        metavar="SAFETENSORS",
        help="start from these weights instead of fresh ones (fine-tuning, e.g. a DAgger "
        "round on 'heapgrasp data loop-grasps': models/grasp-network/"
        "grasp_network.safetensors); they must be of the size asked",
    )
    _add_run_options(g, seed_help="initial weights, order, augmentation (0)")
    _add_cpu_options(g, "; 1 is faster while other jobs share the CPU")
    g.set_defaults(func=_grasps)
    _add_viewsphere_policy(sub)


def _add_viewsphere_policy(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from heapgrasp.bench.argtypes import comma_choices
    from heapgrasp.viewsphere.objects import TRAIN_OBJECTS

    p = sub.add_parser(
        "viewsphere-policy",
        help="train seed 001's learned viewsphere policies (PCA + LR / LDA, DQN)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.dedent(
            """\
            Trains one of seed 001's learned viewsphere policies (section 4.3) and writes
            OUT/viewsphere_<model>.onnx, OUT/metrics.json and OUT/metrics.png.

              heapgrasp data viewsphere-paths runs/vs-train --scenes 2000
              heapgrasp data viewsphere-paths runs/vs-val --scenes 200 --seed 1
              heapgrasp train viewsphere-policy --kind pca-lr --data runs/vs-train \\
                  --val runs/vs-val --out runs/vs-pca-lr
              heapgrasp train viewsphere-policy --kind dqn --episodes 1300 --out runs/vs-dqn

            pca-lr / pca-lda: scikit-learn on the paths datasets (standardise, PCA to 85 %
            of the variance, logistic regression or LDA), folded into one ONNX layer.
            dqn: PyTorch deep Q-learning by playing episodes on the training shapes in
            the simulator (4 x 128 ReLU, epsilon-greedy, replay, +5 grasp / -1 a move,
            gamma 0.9, learning rate 0.005, batch 64). Needs pip install 'heapgrasp[train]'.
            Copy a file to python/heapgrasp/weights/ to ship it; 'heapgrasp bench
            viewsphere --weights MODEL=FILE' runs one without shipping it.
            """
        ),
    )
    p.add_argument("--kind", required=True, choices=("pca-lr", "pca-lda", "dqn"))
    p.add_argument("--data", nargs="+", metavar="DIR", help="paths datasets to fit (pca-*)")
    p.add_argument("--val", nargs="+", metavar="DIR", help="paths datasets to measure (pca-*)")
    p.add_argument("--out", required=True, metavar="OUT", help="output directory")
    p.add_argument(
        "--episodes", type=int_at_least(1), default=1300, help="dqn: episodes (default 1300)"
    )
    p.add_argument(
        "--objects",
        type=comma_choices("object", tuple(TRAIN_OBJECTS)),
        default=None,
        help="dqn: training shapes (default all: " + ", ".join(TRAIN_OBJECTS) + ")",
    )
    p.add_argument("--seed", type=int_at_least(0), default=0, help="random seed (default 0)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_viewsphere_policy)


def _add_run_options(p: argparse.ArgumentParser, *, seed_help: str) -> None:
    """``--device``, ``--resume`` and ``--seed`` (what it draws: ``seed_help``)."""
    p.add_argument(
        "--device",
        default="cpu",
        help="cpu, cuda, cuda:N or auto (cuda where present) (default cpu)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue OUT's checkpoint (same data and settings; else exit 2)",
    )
    p.add_argument("--seed", type=int_at_least(0), default=0, help=seed_help)


def _add_cpu_options(p: argparse.ArgumentParser, workers_note: str) -> None:
    """``--workers`` (its default's help followed by ``workers_note``) and
    ``--no-progress``."""
    p.add_argument(
        "--workers",
        type=int_at_least(1),
        default=None,
        help=f"CPU threads of PyTorch and of reading the shards (default: PyTorch's{workers_note})",
    )
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bar (one line per epoch)"
    )
