"""``heapgrasp grasps data|loop-data|train``: the grasp network's datasets (VGN's scheme,
and the closed loop's own phases) and the grasp network (eq. 11, VGN's) trained on them.

``heapgrasp grasps data``: the grasp network's dataset (VGN's scheme)::

    heapgrasp grasps data runs/grasps-train --scenes 4000 --split train
    heapgrasp grasps data runs/grasps-val --scenes 400 --split val --seed 1

Every scene is a fresh pile or packed scene of Poisson(4) + 1 objects (at most N_ob):
the grid the loop feeds the grasp network (Ŝ≥λ after Algorithm 1's random view
waypoints or no-vp's circle, and the VGN baseline's TSDF), and VGN's grasps labelled on
the exact geometry, balanced (:mod:`heapgrasp.data.grasps`).

``heapgrasp grasps loop-data``: the grasp network's dataset on the closed loop's own
phases (on-policy; DAgger's rounds)::

    heapgrasp grasps loop-data runs/loop-grasps/train --scenes 300 --split train
    heapgrasp grasps loop-data runs/loop-grasps/val --scenes 40 --split val --seed 1

Every scene is a pile or packed scene of 5 objects run through the clutter-removal
protocol, the grasp network executing its own best grasps (``--driver network``; or the
method's default planner); every phase gives the grid the network read, its top
candidates labelled on the true meshes (whatever the label) and VGN's balanced grasps on
that grid, in the format of ``grasps data`` (:mod:`heapgrasp.data.loop_grasps`). The summary
prints the network's precision@k on those phases.

``heapgrasp grasps train``: the grasp network trained on those datasets::

    heapgrasp grasps data runs/grasps/train --split train ...
    heapgrasp grasps data runs/grasps/val --split val ...
    heapgrasp grasps train runs/grasps --out runs/grasp-net --input occupancy

trains the grasp network (:mod:`heapgrasp.training.train_grasps`) on every ``train``
dataset found, validates on the ``val`` ones, evaluates the best epoch on the ``test``
ones and writes ``OUT/grasp_network.{safetensors,json,onnx}`` and ``OUT/metrics.json``.
Needs ``pip install 'heapgrasp[train]'``. Bad input exits 2 with a message naming it.
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path
from typing import TypeAlias

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

__all__ = ["add_data", "add_loop_data", "add_parser", "add_train"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def _data(args: argparse.Namespace) -> int:
    from heapgrasp.data.grasps import GraspDataConfig

    return generate_command(args, GraspDataConfig, input=args.input, gripper=args.gripper)


def _loop_data(args: argparse.Namespace) -> int:
    from heapgrasp.data.loop_grasps import LoopGraspDataConfig, top_precision

    weights = None if args.weights is None else str(args.weights)
    return generate_command(
        args,
        LoopGraspDataConfig,
        report=top_precision,
        objects=args.objects,
        method=args.method,
        driver=args.driver,
        weights=weights,
        top=args.top,
        points=args.points,
    )


def _train(args: argparse.Namespace) -> int:
    require_training("grasps train")
    from heapgrasp.training.common import TrainSetupError
    from heapgrasp.training.device import resolve_device
    from heapgrasp.training.grasp_data import (
        GraspDataError,
        concatenate,
        find_datasets,
        load_grasp_dataset,
    )
    from heapgrasp.training.train_grasps import (
        GraspTrainConfig,
        check_datasets,
        train,
        write_outputs,
    )

    workers = threads(args)
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
                    + f"); write one with 'heapgrasp grasps data DIR --split {name}'"
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
        raise config_error(str(exc)) from None
    written = write_outputs(
        result,
        config,
        args.out,
        train_data=train_data,
        val_data=val_data,
        test_data=test_data,
        device=device,
        command=command_line(args),
        init=args.init,
    )
    print((Path(args.out) / "metrics.json").read_text().rstrip())
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def add_data(sub: SubParsers, name: str = "data") -> argparse.ArgumentParser:
    """Adds ``grasps data`` (under ``name``)."""
    p = dataset_parser(
        sub,
        name,
        "grasp-network data: VGN's grasps on the loop's grids, exact-geometry labels",
        section(__doc__, "grasps data"),
        scenes=1000,
        shard_size=25,
    )
    p.add_argument(
        "--input",
        choices=("occupancy", "tsdf"),
        default="occupancy",
        help="the network input the samples hold: occupancy = the silhouette grid Ŝ≥λ "
        "(HEAPGrasp, no-vp; ~0.4 s a scene), tsdf = the VGN baseline's TSDF from sensor "
        "depth (~8 s a scene)",
    )
    p.add_argument(
        "--gripper",
        choices=("panda", "robotiq-2f140"),
        default="panda",
        help="the hand the grasps are labelled for: panda (VGN's; the shipped networks) or "
        "robotiq-2f140 (the real robot's, 14 cm; a network trained on it plans for it)",
    )
    p.set_defaults(func=_data)
    return p


def add_loop_data(sub: SubParsers, name: str = "loop-data") -> argparse.ArgumentParser:
    """Adds ``grasps loop-data`` (under ``name``)."""
    p = dataset_parser(
        sub,
        name,
        "grasp-network data on the closed loop's own phases: its grids and the network's "
        "top grasps, labelled (on-policy, DAgger)",
        section(__doc__, "grasps loop-data"),
        scenes=300,
        shard_size=5,
        max_objects=False,
    )
    p.add_argument(
        "--objects", type=int_at_least(1), default=5, help="objects per scene (default 5)"
    )
    p.add_argument(
        "--method",
        choices=("heapgrasp", "no-vp", "vgn"),
        default="heapgrasp",
        help="whose views carve the grids (vgn: the TSDF network's data); default heapgrasp",
    )
    p.add_argument(
        "--driver",
        choices=("network", "default"),
        default="network",
        help="who executes the grasps: the grasp network (DAgger; default) or the "
        "method's default planner",
    )
    p.add_argument(
        "--weights",
        type=Path,
        default=None,
        metavar="ONNX",
        help="the grasp network ranked and driven (default: the one that ships for the "
        "method's grid)",
    )
    p.add_argument(
        "--top",
        type=int_at_least(1),
        default=8,
        help="the network's best candidates labelled per phase (default 8)",
    )
    p.add_argument(
        "--points",
        type=int_at_least(0),
        default=300,
        help="VGN's surface points labelled per phase (default 300)",
    )
    p.set_defaults(func=_loop_data)
    return p


def add_train(sub: SubParsers, name: str = "train") -> argparse.ArgumentParser:
    """Adds ``grasps train`` (under ``name``)."""
    g = sub.add_parser(
        name,
        help="train the grasp network (eq. 11, VGN's) on grasp datasets",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.fill(
            "Trains the grasp network (HEAPGrasp eq. 11: VGN's encoder-decoder giving grasp "
            "quality, orientation and opening width at every voxel) on datasets of "
            "'heapgrasp grasps data'. The splits come from the data: every 'train' dataset "
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
            "  heapgrasp grasps train runs/grasps --out runs/grasp-net --epochs 20\n"
            "  heapgrasp grasps train runs/vgn-grasps --out runs/vgn-net   # tsdf data\n"
            "  heapgrasp grasps train runs/grasps --out runs/grasp-net --epochs 20 "
            "--resume   # continue after a stop\n"
            "  heapgrasp grasps train runs/grasps --out runs/grasp-net --epochs 30 "
            "--resume   # train a finished run 10 epochs more\n"
            "  heapgrasp grasps train runs/grasps runs/loop-grasps --out runs/dagger-1 "
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
        "datasets were made with, 'heapgrasp grasps data --input')",
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
        "round on 'heapgrasp grasps loop-data': models/grasp-network/"
        "grasp_network.safetensors); they must be of the size asked",
    )
    add_run_options(g, seed_help="initial weights, order, augmentation (0)")
    add_cpu_options(g, "; 1 is faster while other jobs share the CPU")
    g.set_defaults(func=_train)
    return g


def add_parser(commands: SubParsers) -> argparse.ArgumentParser:
    """Adds ``grasps`` and its commands ``data``, ``loop-data`` and ``train``."""
    group = commands.add_parser(
        "grasps",
        help="the grasp network: its datasets (VGN's scheme, the loop's phases), its "
        "training (eq. 11)",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    sub = group.add_subparsers(dest="grasps_command", metavar="COMMAND", required=True)
    add_data(sub)
    add_loop_data(sub)
    add_train(sub)
    return group
