"""``heapgrasp viewsphere bench|data|train``: the active-vision grasp benchmark of
Natarajan et al. (:mod:`heapgrasp.viewsphere`), its supervised policies' dataset and its
learned policies.

``heapgrasp viewsphere bench``: the policies on the viewsphere, success per step
(:mod:`heapgrasp.viewsphere.bench`; docs/viewsphere.md)::

    heapgrasp viewsphere bench --out runs/bench-viewsphere

``heapgrasp viewsphere data``: Natarajan et al.'s supervised viewsphere policies' dataset
(§4.3.1)::

    heapgrasp viewsphere data runs/vs-paths --scenes 2000

Every scene puts a training prism at a random yaw, starts the camera at a random pose
and explores randomly, three paths of up to five moves per direction; the label is the
first direction of the shortest path that found a grasp
(:mod:`heapgrasp.viewsphere.data`).

``heapgrasp viewsphere train``: one of the learned policies (PCA + LR / LDA on those
datasets, or the DQN by playing episodes; :mod:`heapgrasp.viewsphere.training`)::

    heapgrasp viewsphere train --kind pca-lr --data runs/vs-train --val runs/vs-val \\
        --out runs/vs-pca-lr
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import textwrap
from pathlib import Path
from typing import TypeAlias

from heapgrasp.cli.argtypes import add_ray_argument, comma_choices, int_at_least
from heapgrasp.cli.datasets import dataset_parser, generate_command, section
from heapgrasp.cli.training import config_error

__all__ = ["add_bench", "add_data", "add_parser", "add_train"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def _data(args: argparse.Namespace) -> int:
    from heapgrasp.viewsphere.data import ViewspherePathsConfig

    return generate_command(
        args,
        ViewspherePathsConfig,
        objects=args.objects,
        tries=args.tries,
        path_steps=args.path_steps,
        labels=args.labels,
        prefix_steps=args.prefix_steps,
        procedural=args.procedural,
        bfs_max_sets=args.bfs_max_sets,
    )


def _train(args: argparse.Namespace) -> int:
    from heapgrasp.viewsphere import training as vt

    out = Path(args.out)
    try:
        if args.kind == "dqn":
            if args.data or args.val:
                raise config_error("--kind dqn plays episodes; it reads no --data or --val")
            try:
                config = vt.DqnConfig(
                    episodes=args.episodes,
                    seed=args.seed,
                    objects=tuple(args.objects or ()),
                    procedural=args.procedural,
                )
            except ValueError as exc:
                raise config_error(str(exc)) from None
            metrics = vt.train_dqn(
                config,
                out,
                progress=not args.no_progress,
                log=lambda line: print(line, file=sys.stderr),
            )
            metrics = {k: v for k, v in metrics.items() if k != "history"}
        else:
            if not args.data or not args.val:
                raise config_error(f"--kind {args.kind} needs --data DIR and --val DIR")
            try:
                data, val = [Path(p) for p in args.data], [Path(p) for p in args.val]
                metrics = (
                    vt.train_mlp(data, val, out, seed=args.seed)
                    if args.kind == "imitation"
                    else vt.train_linear(
                        args.kind.removeprefix("pca-"), data, val, out, seed=args.seed
                    )
                )
            except (FileNotFoundError, ValueError) as exc:
                raise config_error(str(exc)) from None
    except ImportError as exc:
        raise config_error(str(exc)) from None
    print(json.dumps(metrics, indent=1))
    return 0


def add_bench(sub: SubParsers, name: str = "bench") -> argparse.ArgumentParser:
    """Adds ``viewsphere bench`` (under ``name``)."""
    from heapgrasp.viewsphere import bench
    from heapgrasp.viewsphere.episode import LEARNED, POLICIES, SENSORS
    from heapgrasp.viewsphere.grasps import PERCEPTIONS, ViewsphereConfig
    from heapgrasp.viewsphere.objects import TEST_OBJECTS, TRAIN_OBJECTS

    p = sub.add_parser(
        name,
        help="the active-vision grasp benchmark (Natarajan et al.): policies on the "
        "viewsphere, success per step",
        description=bench.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    some = comma_choices("policy", POLICIES)
    p.add_argument(
        "--policies",
        type=lambda text: POLICIES if text.strip().lower() == "all" else some(text),
        default=POLICIES,
        help=f"comma-separated policies among {', '.join(POLICIES)}, or all (the default)",
    )
    some_objects = comma_choices("object", (*TEST_OBJECTS, *TRAIN_OBJECTS))
    p.add_argument(
        "--objects",
        type=lambda text: (
            tuple(TEST_OBJECTS) if text.strip().lower() == "test" else some_objects(text)
        ),
        default=None,
        metavar="NAMES",
        help="comma-separated objects, or test for the 12 test objects (the default: "
        + ", ".join(TEST_OBJECTS)
        + "; training shapes: "
        + ", ".join(TRAIN_OBJECTS)
        + "). With --object-dir, the objects of DIR that are these protocol objects "
        "(default: every object of DIR)",
    )
    p.add_argument(
        "--object-dir",
        metavar="DIR",
        type=lambda s: str(Path(s).expanduser().absolute()),
        help="your objects instead of the stand-ins: each subfolder of DIR is an object "
        "(its model.urdf, as in pybullet-object-models' ycb_objects/YcbCrackerBox, or "
        "a download's mesh: YCB's 003_cracker_box/google_16k/textured.obj, Google "
        "Scanned Objects' meshes/model.obj), or DIR holds mesh files, in metres. An "
        "object named like a protocol object (003_cracker_box, YcbCrackerBox, "
        "cracker_box) rests as the protocol says whatever its mesh's frame (checked "
        "against its stable poses; a warning where it cannot) and takes its yaw range; "
        "any other rests in its most stable pose, with yaws over 0-359 degrees. An "
        "object that cannot be used is reported and skipped",
    )
    p.add_argument(
        "--poses",
        type=int_at_least(1),
        default=100,
        help="poses per object, the protocol's first N yaws (1-100, default 100)",
    )
    p.add_argument("--seed", type=int, default=0, help="the random policy's seed (default 0)")
    p.add_argument(
        "--sensor",
        choices=SENSORS,
        default="ideal",
        help="ideal depth (the paper's), or our depth sensor's model with the object "
        "opaque, transparent or specular (default ideal)",
    )
    p.add_argument(
        "--perception",
        choices=PERCEPTIONS,
        default="depth",
        help="what the grasp synthesis reads: the depth points (the paper's), the hull "
        "carved from the views' silhouettes (HEAPGrasp's measurement: transparent and "
        "specular objects measured as opaque ones), or fused: the depth inside the hull "
        "beside its surface (default depth)",
    )
    p.add_argument(
        "--no-execute",
        dest="execute",
        action="store_false",
        help="do not execute the found grasps with the simulated hand (faster; only "
        "the paper's success, a grasp found)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a setting of the benchmark: "
        + ", ".join(f"{k} ({v})" for k, v in ViewsphereConfig().to_dict().items()),
    )
    p.add_argument(
        "--workers",
        type=int_at_least(1),
        default=os.cpu_count() or 1,
        help="processes (object poses in parallel; default: every core)",
    )
    add_ray_argument(p, "poses")
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output directory (default runs/bench-viewsphere-<time>); an existing one "
        "with the same settings is continued",
    )
    p.add_argument(
        "--weights",
        action="append",
        default=[],
        metavar="MODEL=FILE",
        help="a learned policy's file instead of the shipped one (MODEL among "
        + ", ".join(LEARNED)
        + "; from heapgrasp viewsphere train)",
    )
    p.add_argument("--no-figures", action="store_true", help="skip the plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=bench.command)
    return p


def add_data(sub: SubParsers, name: str = "data") -> argparse.ArgumentParser:
    """Adds ``viewsphere data`` (under ``name``)."""
    from heapgrasp.viewsphere.data import LABELS, SUPERVISED_OBJECTS
    from heapgrasp.viewsphere.objects import TRAIN_OBJECTS

    p = dataset_parser(
        sub,
        name,
        "Natarajan et al.'s supervised policies' data: random paths on the viewsphere, labelled "
        "with the first direction of the shortest that found a grasp",
        section(__doc__, "viewsphere data"),
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
    p.add_argument(
        "--labels",
        choices=LABELS,
        default="paths",
        help="paths: the paper's (random paths, the first direction of the shortest that "
        "found a grasp); bfs: every first move of a shortest path, by breadth-first "
        "search over the sets of views (within the bfs_max_sets budget; default paths)",
    )
    p.add_argument(
        "--prefix-steps",
        type=int_at_least(0),
        default=0,
        help="with --labels bfs: 0 to this many random moves before the state, so that "
        "states of later steps are learned too (default 0: the start only)",
    )
    p.add_argument(
        "--bfs-max-sets",
        type=int_at_least(1),
        default=300,
        help="with --labels bfs: syntheses per state, at most; a state whose search finds "
        "nothing within them is dropped (default 300; two levels take about 60)",
    )
    p.add_argument(
        "--procedural",
        type=int_at_least(0),
        default=0,
        help="procedural objects of each kind (box, cylinder, bottle, bowl, cup; none of "
        "the benchmark's) beside --objects, resting in their most stable pose (default 0)",
    )
    p.set_defaults(func=_data)
    return p


def add_train(sub: SubParsers, name: str = "train") -> argparse.ArgumentParser:
    """Adds ``viewsphere train`` (under ``name``)."""
    from heapgrasp.viewsphere.objects import TRAIN_OBJECTS
    from heapgrasp.viewsphere.training import DqnConfig

    p = sub.add_parser(
        name,
        help="train Natarajan et al.'s learned viewsphere policies (PCA + LR / LDA, DQN)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=textwrap.dedent(
            """\
            Trains one of Natarajan et al.'s learned viewsphere policies (section 4.3) and writes
            OUT/viewsphere_<model>.onnx, OUT/metrics.json and OUT/metrics.png.

              heapgrasp viewsphere data runs/vs-train --scenes 2000
              heapgrasp viewsphere data runs/vs-val --scenes 200 --seed 1
              heapgrasp viewsphere train --kind pca-lr --data runs/vs-train \\
                  --val runs/vs-val --out runs/vs-pca-lr
              heapgrasp viewsphere train --kind dqn --out runs/vs-dqn

            pca-lr / pca-lda: scikit-learn on the paths datasets (standardise, PCA to 85 %
            of the variance, logistic regression or LDA), folded into one ONNX layer.
            dqn: PyTorch deep Q-learning by playing episodes on the training shapes and
            procedural objects in the simulator (the paper's: --procedural 0 --episodes
            1300; 4 x 128 ReLU, epsilon-greedy, replay, +5 grasp / -1 a move,
            gamma 0.9, learning rate 0.005, batch 64). Needs pip install 'heapgrasp[train]'.
            Copy a file to python/heapgrasp/weights/ to ship it; 'heapgrasp viewsphere
            bench --weights MODEL=FILE' runs one without shipping it.
            """
        ),
    )
    p.add_argument(
        "--kind",
        required=True,
        choices=("pca-lr", "pca-lda", "dqn", "imitation"),
        help="pca-lr, pca-lda, dqn: the paper's; imitation: a perceptron that imitates "
        "the datasets' optimal first moves (beyond the paper: with viewsphere data "
        "--labels bfs)",
    )
    p.add_argument(
        "--data", nargs="+", metavar="DIR", help="paths datasets to fit (pca-*, imitation)"
    )
    p.add_argument(
        "--val", nargs="+", metavar="DIR", help="paths datasets to measure (pca-*, imitation)"
    )
    p.add_argument("--out", required=True, metavar="OUT", help="output directory")
    p.add_argument(
        "--episodes",
        type=int_at_least(1),
        default=DqnConfig.episodes,
        help=f"dqn: episodes (default {DqnConfig.episodes}; the paper's 1300)",
    )
    p.add_argument(
        "--objects",
        type=comma_choices("object", tuple(TRAIN_OBJECTS)),
        default=None,
        help="dqn: training shapes (default all: " + ", ".join(TRAIN_OBJECTS) + ")",
    )
    p.add_argument(
        "--procedural",
        type=int_at_least(0),
        default=DqnConfig.procedural,
        metavar="N",
        help="dqn: also play around N procedural objects of each kind, in turn with the "
        "training shapes (those of 'viewsphere data --procedural'; default "
        f"{DqnConfig.procedural}; 0: the paper's shapes alone)",
    )
    p.add_argument("--seed", type=int_at_least(0), default=0, help="random seed (default 0)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_train)
    return p


def add_parser(commands: SubParsers) -> argparse.ArgumentParser:
    """Adds ``viewsphere`` and its commands ``bench``, ``data`` and ``train``."""
    group = commands.add_parser(
        "viewsphere",
        help="the active-vision grasp benchmark (Natarajan et al.): run it, its policies' "
        "dataset, train them",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    sub = group.add_subparsers(dest="viewsphere_command", metavar="COMMAND", required=True)
    add_bench(sub)
    add_data(sub)
    add_train(sub)
    return group
