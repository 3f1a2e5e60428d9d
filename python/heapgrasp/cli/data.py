"""``heapgrasp data``: the learned planners' datasets.

``heapgrasp data views``: the view network's (HEAPGrasp Algorithm 1)::

    heapgrasp data views runs/views-train --scenes 6000 --split train
    heapgrasp data views runs/views-val --scenes 600 --split val --seed 1
    heapgrasp data views runs/views-test --scenes 400 --split test --seed 2

Every scene is a fresh pile or packed scene of 1 to N_ob objects, captured along
k ~ U{0..L−1} random view waypoints, and labelled with the exact eq. 14 score of all
U × V candidates (:mod:`heapgrasp.data.views`).

``heapgrasp data grasps``: the grasp network's (VGN's scheme)::

    heapgrasp data grasps runs/grasps-train --scenes 4000 --split train
    heapgrasp data grasps runs/grasps-val --scenes 400 --split val --seed 1

Every scene is a fresh pile or packed scene of Poisson(4) + 1 objects (at most N_ob):
the grid the loop feeds the grasp network (Ŝ≥λ after Algorithm 1's random view
waypoints or no-vp's circle, and the VGN baseline's TSDF), and VGN's grasps labelled on
the exact geometry, balanced (:mod:`heapgrasp.data.grasps`).

``heapgrasp data loop-grasps``: the grasp network's, on the closed loop's own phases
(on-policy; DAgger's rounds)::

    heapgrasp data loop-grasps runs/loop-grasps/train --scenes 300 --split train
    heapgrasp data loop-grasps runs/loop-grasps/val --scenes 40 --split val --seed 1

Every scene is a pile or packed scene of 5 objects run through the clutter-removal
protocol, the grasp network executing its own best grasps (``--driver network``; or the
method's default planner); every phase gives the grid the network read, its top
candidates labelled on the true meshes (whatever the label) and VGN's balanced grasps on
that grid, in ``data grasps``' format (:mod:`heapgrasp.data.loop_grasps`). The summary
prints the network's precision@k on those phases.

``heapgrasp data seg``: the segmentation network's (docs/segmentation.md)::

    heapgrasp data seg runs/seg-synth --scenes 500 --views 8 --size 320x240

Rendered RGB images of random scenes and their exact 4-class masks, as ``images/`` and
``masks/`` PNGs that ``heapgrasp seg train`` reads (:mod:`heapgrasp.data.seg`).

``heapgrasp data viewsphere-paths``: seed 001's supervised viewsphere policies'
(§4.3.1)::

    heapgrasp data viewsphere-paths runs/vs-paths --scenes 2000

Every scene puts a training prism at a random yaw, starts the camera at a random pose
and explores randomly, three paths of up to five moves per direction; the label is the
first direction of the shortest path that found a grasp
(:mod:`heapgrasp.viewsphere.data`).

Shards are written whole or not at all; running the same command again continues where
it stopped (finished shards are kept) and adding scenes (a larger ``--scenes``) adds
shards; other settings than the dataset's are refused. Scenes run on a process pool
(``--workers``, default: every core) or on Ray (``--ray`` starts a local cluster,
``--ray ADDRESS`` joins one).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from heapgrasp.bench.argtypes import add_ray_argument, float_in, int_at_least

__all__ = ["add_parser"]


def _generate(args: argparse.Namespace, dataset: str, **settings: Any) -> int:
    """Generates the dataset (``views`` or ``grasps``) the options ask for."""
    from heapgrasp.data.grasps import GraspDataConfig
    from heapgrasp.data.loop_grasps import LoopGraspDataConfig
    from heapgrasp.data.seg import SegDataConfig
    from heapgrasp.data.shards import ShardFailure, generate
    from heapgrasp.data.views import ViewDataConfig
    from heapgrasp.viewsphere.data import ViewspherePathsConfig

    kinds = {"views": ViewDataConfig, "grasps": GraspDataConfig, "seg": SegDataConfig}
    common = {
        "scenes": args.scenes,
        "root_seed": args.seed,
        "split": args.split,
        "shard_size": args.shard_size,
    }
    try:
        if dataset == "viewsphere-paths":
            config: Any = ViewspherePathsConfig(**common, **settings)
        elif dataset == "loop-grasps":
            config = LoopGraspDataConfig(**common, **settings)
        else:
            config = kinds[dataset](**common, max_objects=args.max_objects, **settings)
    except ValueError as exc:
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    try:
        manifest = generate(
            config, out, workers=args.workers, ray_address=args.ray, progress=not args.quiet
        )
    except ShardFailure as exc:
        print(
            f"heapgrasp: error: {exc}\nthe other shards are written; run again to retry",
            file=sys.stderr,
        )
        return 1
    except ImportError as exc:  # --ray without Ray
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # refused: a dataset of other settings, stray shard files
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    keys = ("split", "samples", "dropped", "grasps", "complete")
    summary = {"out": str(out), **{k: manifest[k] for k in keys if k in manifest}}
    if dataset == "loop-grasps":
        from heapgrasp.data.loop_grasps import top_precision

        summary["network_on_these_phases"] = top_precision(out)
    print(json.dumps(summary))
    return 0


def _views(args: argparse.Namespace) -> int:
    return _generate(args, "views", region_fraction=args.region_fraction)


def _grasps(args: argparse.Namespace) -> int:
    return _generate(args, "grasps", input=args.input, gripper=args.gripper)


def _loop_grasps(args: argparse.Namespace) -> int:
    weights = None if args.weights is None else str(args.weights)
    return _generate(
        args,
        "loop-grasps",
        objects=args.objects,
        method=args.method,
        driver=args.driver,
        weights=weights,
        top=args.top,
        points=args.points,
    )


def _seg(args: argparse.Namespace) -> int:
    height, width = args.size
    return _generate(args, "seg", views=args.views, width=width, height=height, out_dir=args.out)


def _viewsphere_paths(args: argparse.Namespace) -> int:
    return _generate(
        args,
        "viewsphere-paths",
        objects=args.objects,
        tries=args.tries,
        path_steps=args.path_steps,
    )


def _describe(name: str) -> str:
    """The module doc's paragraphs on ``heapgrasp data NAME``, and the closing one on
    shards and resuming, which every dataset shares."""
    paragraphs = (__doc__ or "").strip().split("\n\n")
    own: list[str] = []
    for k, para in enumerate(paragraphs[1:-1], start=1):
        if para.startswith("``heapgrasp data "):
            if own:
                break
            if para.startswith(f"``heapgrasp data {name}``"):
                own = paragraphs[k : k + 3]
    if not own:
        return __doc__ or ""
    return "\n\n".join([*own, paragraphs[-1]])


def _dataset_parser(
    sub: argparse._SubParsersAction[argparse.ArgumentParser],
    name: str,
    help: str,
    *,
    scenes: int,
    shard_size: int,
    max_objects: bool = True,
) -> argparse.ArgumentParser:
    """A ``data`` subcommand with the options every dataset has; its help describes
    that dataset alone (:func:`_describe`)."""
    p = sub.add_parser(
        name,
        help=help,
        description=_describe(name),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("out", metavar="OUT", help="dataset directory (created; resumed if present)")
    p.add_argument(
        "--scenes",
        type=int_at_least(1),
        default=scenes,
        help=f"scenes to run (default {scenes})",
    )
    p.add_argument(
        "--seed", type=int_at_least(0), default=0, help="root seed of every scene (default 0)"
    )
    p.add_argument(
        "--split",
        choices=("train", "val", "test"),
        default="train",
        help="objects: train, val (train objects held out for validation) or test (the "
        "benchmark's held-out objects, for measuring only); default train",
    )
    p.add_argument(
        "--shard-size",
        type=int_at_least(1),
        default=shard_size,
        help=f"scenes per shard (default {shard_size})",
    )
    if max_objects:
        p.add_argument(
            "--max-objects", type=int_at_least(1), default=5, help="N_ob (Table I; default 5)"
        )
    p.add_argument(
        "--workers",
        type=int_at_least(1),
        default=os.cpu_count() or 1,
        help="processes of the local pool (default: every core)",
    )
    add_ray_argument(p, "shards")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Adds ``data`` and its subcommands."""
    group = commands.add_parser(
        "data",
        help="generate the networks' datasets",
        description="Generate the learned planners' datasets (sharded, resumable).",
    )
    sub = group.add_subparsers(dest="data_command", metavar="DATASET", required=True)
    p = _dataset_parser(
        sub,
        "views",
        "view-network data: Algorithm 1 with exact eq. 14 labels",
        scenes=1000,
        shard_size=50,
    )
    p.add_argument(
        "--region-fraction",
        type=float_in(0.0, 1.0),
        default=0.5,
        help="share of k >= 1 samples labelled on a target's column (default 0.5)",
    )
    p.set_defaults(func=_views)
    p = _dataset_parser(
        sub,
        "grasps",
        "grasp-network data: VGN's grasps on the loop's grids, exact-geometry labels",
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
    p.set_defaults(func=_grasps)
    p = _dataset_parser(
        sub,
        "loop-grasps",
        "grasp-network data on the closed loop's own phases: its grids and the network's "
        "top grasps, labelled (on-policy, DAgger)",
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
    p.set_defaults(func=_loop_grasps)
    p = _dataset_parser(
        sub,
        "seg",
        "segmentation data: rendered RGB images and exact 4-class masks (images/, masks/)",
        scenes=100,
        shard_size=10,
    )
    p.add_argument("--views", type=int_at_least(1), default=8, help="images per scene (8)")
    from heapgrasp.cli.seg import size_arg

    p.add_argument("--size", type=size_arg, default=(240, 320), metavar="WxH", help="(320x240)")
    p.set_defaults(func=_seg)
    from heapgrasp.bench.argtypes import comma_choices
    from heapgrasp.viewsphere.data import SUPERVISED_OBJECTS
    from heapgrasp.viewsphere.objects import TRAIN_OBJECTS

    p = _dataset_parser(
        sub,
        "viewsphere-paths",
        "seed 001's supervised policies' data: random paths on the viewsphere, labelled "
        "with the first direction of the shortest that found a grasp",
        scenes=2000,
        shard_size=20,
        max_objects=False,
    )
    p.add_argument(
        "--objects",
        type=comma_choices("object", tuple(TRAIN_OBJECTS)),
        default=SUPERVISED_OBJECTS,
        help="training shapes the scenes take in turn (default: the paper's "
        + ", ".join(SUPERVISED_OBJECTS)
        + "; any of "
        + ", ".join(TRAIN_OBJECTS)
        + ")",
    )
    p.add_argument(
        "--tries", type=int_at_least(1), default=3, help="random paths per direction (default 3)"
    )
    p.add_argument(
        "--path-steps",
        type=int_at_least(1),
        default=5,
        help="moves per path, at most (default 5)",
    )
    p.set_defaults(func=_viewsphere_paths)
