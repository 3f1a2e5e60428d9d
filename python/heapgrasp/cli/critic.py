"""``heapgrasp critic data|train|eval|convert``: the grasp critic's data, weights and
evaluation.

::

    heapgrasp critic data --scenes 240 --workers 2 --out runs/critic-data
    heapgrasp critic train runs/critic-data --model cnn --out python/heapgrasp/weights/critic.onnx
    heapgrasp critic eval python/heapgrasp/weights/critic.onnx runs/other-data
    heapgrasp critic convert old-critic.npz critic.onnx

``data`` runs HEAPGrasp's phases on train-split scenes and tries every candidate in the
simulator (:mod:`heapgrasp.data.critic`); an interrupted run continues where it
stopped. ``train`` cross-validates by scene (:mod:`heapgrasp.training.train_critic`),
fits on all scenes, and writes the critic with its command and the cross-validated
measurements, plus ``FILE.json`` with the same report. ``eval`` scores a critic file on
scene files without refitting and prints the same report. ``convert`` turns a critic
of the former ``.npz`` format into the ONNX file heapgrasp runs
(:func:`heapgrasp.training.critic_net.convert_npz`).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

from heapgrasp.cli.argtypes import float_in, int_at_least

__all__ = ["add_parser"]


def _data(args: argparse.Namespace) -> int:
    from heapgrasp.data.critic import CriticDataConfig, generate
    from heapgrasp.loop.config import parse_sets

    config = CriticDataConfig(
        scenes=args.scenes,
        seed=args.seed,
        epsilon=args.epsilon,
        max_candidates=args.max_candidates,
        max_phases=args.max_phases,
        method=args.method,
        critic=args.critic,
        object_seeds=tuple(args.object_seeds),
        split=args.split,
        overrides=tuple(parse_sets(args.set).items()),
    )
    paths = generate(config, Path(args.out), workers=args.workers)
    print(f"{len(paths)} scene files in {args.out}")
    return 0


def _seed_list(text: str) -> tuple[int, ...]:
    try:
        seeds = tuple(int(t) for t in text.split(",") if t.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seeds like 1,2, got {text!r}") from None
    if not seeds or any(s < 1 for s in seeds):
        raise argparse.ArgumentTypeError(f"seeds must be integers >= 1, got {text!r}")
    return seeds


def _scene_files(folders: list[Path]) -> list[Path]:
    paths: list[Path] = []
    for data in folders:
        found = sorted(data.glob("scene_*.npz"))
        if not found:
            raise ValueError(
                f"no scene_*.npz files in {data} (write them with 'heapgrasp critic data')"
            )
        paths.extend(found)
    return paths


def _evaluate(args: argparse.Namespace) -> int:
    from heapgrasp.data.critic import load_dataset
    from heapgrasp.geometry.grid import GridFrame
    from heapgrasp.planning.critic import GraspCritic
    from heapgrasp.training.train_critic import design_matrix, evaluation_report

    critic = GraspCritic.load(args.critic)
    paths = _scene_files([Path(d) for d in args.data])
    design = design_matrix(
        load_dataset(paths), GridFrame((0.0, 0.0, 0.0), args.cube_size, args.resolution)
    )
    thresholds = sorted({*args.report_thresholds, critic.threshold})
    report = {
        "critic": str(args.critic),
        "scenes": len(paths),
        **evaluation_report(design, critic.probability(design.features), thresholds, args.epsilon),
    }
    print(json.dumps(report, indent=2))
    return 0


def _train(args: argparse.Namespace) -> int:
    from heapgrasp.data.critic import load_dataset
    from heapgrasp.geometry.grid import GridFrame
    from heapgrasp.training.train_critic import (
        cross_validate,
        design_matrix,
        fit_critic,
        save_critic,
    )

    folders = [Path(d) for d in args.data]
    paths = _scene_files(folders)
    scenes = load_dataset(paths, training=True)
    design = design_matrix(scenes, GridFrame((0.0, 0.0, 0.0), args.cube_size, args.resolution))
    print(f"{len(design)} candidates from {len(paths)} scenes; cross-validating ...", flush=True)
    model = {
        "model": args.model,
        "components": args.components,
        "l2": args.l2,
        "epochs": args.epochs,
        "weight_decay": args.weight_decay,
        "seed": args.seed,
    }
    report = cross_validate(
        design,
        thresholds=sorted({*args.report_thresholds, args.threshold}),
        epsilon=args.epsilon,
        folds=args.folds,
        **model,
    )
    critic = fit_critic(
        design.features,
        design.labels,
        threshold=args.threshold,
        candidate_epsilon=args.candidate_epsilon,
        **model,
    )
    command = "heapgrasp " + shlex.join(getattr(args, "argv", sys.argv[1:]))
    meta = {
        "data": " ".join(str(d) for d in folders),
        "scenes": len(paths),
        "seeds": [int(s["seed"]) for s in scenes],
        **model,
        "cross_validation": report,
    }
    out = Path(args.out)
    save_critic(critic, out, command=command, metadata=meta)
    out.with_suffix(".json").write_text(json.dumps({"command": command, **meta}, indent=2) + "\n")
    print(json.dumps(report, indent=2))
    print(f"wrote {out} and {out.with_suffix('.json')}")
    return 0


def _convert(args: argparse.Namespace) -> int:
    from heapgrasp.planning.critic import GraspCritic
    from heapgrasp.training.critic_net import convert_npz

    command = "heapgrasp " + shlex.join(getattr(args, "argv", sys.argv[1:]))
    out = convert_npz(args.src, args.dst, command=command)
    critic = GraspCritic.load(out)
    print(f"wrote {out} ({critic.model} critic, threshold {critic.threshold:g})")
    return 0


def _report_arguments(parser: argparse.ArgumentParser) -> None:
    """The report's options, shared by ``train`` and ``eval``."""
    parser.add_argument(
        "--report-thresholds",
        type=lambda s: [float_in(0.0, 1.0)(v) for v in s.split(",")],
        default=[0.5, 0.6, 0.7, 0.8],
        help="thresholds the report evaluates (comma-separated; the critic's own is added)",
    )
    parser.add_argument("--epsilon", type=float_in(0.0, 1.0), default=0.4, help="deployed ε (0.4)")
    parser.add_argument("--cube-size", type=float_in(0.0, open_low=True), default=0.30)
    parser.add_argument("--resolution", type=int_at_least(8), default=40)


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Adds ``critic data``, ``critic train``, ``critic eval`` and ``critic convert``."""
    p = subparsers.add_parser(
        "critic",
        help="the learned grasp critic: generate its data, train it, evaluate it",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    sub = p.add_subparsers(dest="critic_command", metavar="STEP", required=True)
    d = sub.add_parser(
        "data",
        help="try grasp candidates of HEAPGrasp phases on train-split scenes",
        description=(
            "Runs HEAPGrasp (or no-vp) phases with antipodal grasps on train-split scenes, "
            "even scenes from above, odd ones from the default start, and executes every "
            "candidate from a saved physics state. One OUT/scene_SEED.npz per scene; "
            "existing files are kept, so a rerun continues."
        ),
    )
    d.add_argument("--scenes", type=int_at_least(1), default=240, help="scenes (default 240)")
    d.add_argument(
        "--seed", type=int_at_least(0), default=1000, help="seed of scene 0 (default 1000)"
    )
    d.add_argument(
        "--epsilon",
        type=float_in(0.0, 1.0),
        default=0.2,
        help="candidate threshold for the data, below the deployed 0.4 (default 0.2)",
    )
    d.add_argument(
        "--max-candidates", type=int_at_least(1), default=12, help="tried per phase (12)"
    )
    d.add_argument("--max-phases", type=int_at_least(1), default=4, help="phases per scene (4)")
    d.add_argument(
        "--method",
        choices=("heapgrasp", "no-vp"),
        default="heapgrasp",
        help="whose hulls: HEAPGrasp's oracle views or no-vp's circle (heapgrasp)",
    )
    d.add_argument(
        "--critic",
        default="none",
        help=(
            "critic steering the phases' views: none, default (the shipped one) or a file; "
            "the tried candidates are the planner's own either way (none)"
        ),
    )
    d.add_argument(
        "--object-seeds",
        type=_seed_list,
        default=(),
        help=(
            "comma-separated seeds >= 1 of extra procedural objects (16 per kind each, all "
            "used) beside the benchmark library's train split; they share no mesh with "
            "its test objects (default: none)"
        ),
    )
    d.add_argument(
        "--split",
        choices=("train", "test"),
        default="train",
        help=(
            "objects of the benchmark library's train split (default), or test to measure "
            "a critic on the benchmark's objects with 'critic eval' ('critic train' "
            "refuses such files)"
        ),
    )
    d.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help=(
            "another RunConfig field of the phases (repeatable), e.g. "
            "roof_radius=0: the files then tell how often any candidate holds "
            "on that setting's hulls"
        ),
    )
    d.add_argument("--workers", type=int_at_least(1), default=1, help="processes (default 1)")
    d.add_argument("--out", required=True, help="folder of the scene files")
    d.set_defaults(func=_data)

    t = sub.add_parser(
        "train",
        help="cross-validate and fit the critic on scene files",
        description=(
            "Cross-validates by scene, fits the model (PCA + logistic regression, or the "
            "3-D CNN with --model cnn, which needs PyTorch) on all scenes and writes the "
            "critic (.onnx) and its report (.json)."
        ),
    )
    t.add_argument("data", nargs="+", help="folders of scene files from 'heapgrasp critic data'")
    t.add_argument("--out", required=True, help="critic file to write (.onnx)")
    t.add_argument(
        "--model",
        choices=("linear", "cnn"),
        default="linear",
        help="linear: PCA + logistic regression (numpy); cnn: small 3-D CNN (PyTorch)",
    )
    t.add_argument("--components", type=int_at_least(1), default=16, help="PCA components (16)")
    t.add_argument("--l2", type=float_in(0.0), default=10.0, help="linear: L2 penalty (10)")
    t.add_argument("--epochs", type=int_at_least(1), default=30, help="cnn: epochs (30)")
    t.add_argument(
        "--weight-decay", type=float_in(0.0), default=0.01, help="cnn: AdamW weight decay (0.01)"
    )
    t.add_argument("--seed", type=int, default=0, help="cnn: random seed (0)")
    t.add_argument(
        "--threshold",
        type=float_in(0.0, 1.0),
        default=0.7,
        help="probability below which candidates are dropped: the critic's ε (0.7)",
    )
    _report_arguments(t)
    t.add_argument(
        "--candidate-epsilon",
        type=float_in(0.0, 1.0),
        default=0.2,
        help="ε of the planner's candidates the critic sees: the data's --epsilon (0.2)",
    )
    t.add_argument("--folds", type=int_at_least(2), default=5, help="folds (5)")
    t.set_defaults(func=_train)
    e = sub.add_parser(
        "eval",
        help="evaluate a critic file on scene files it was not trained on",
        description=(
            "Scores every tried candidate of the scene files with the critic and prints, as "
            "JSON, the AUC of the critic and of the planner's score and, per start, what "
            "each would pick (the report of 'critic train', without refitting)."
        ),
    )
    e.add_argument("critic", help="critic file (.onnx), e.g. python/heapgrasp/weights/critic.onnx")
    e.add_argument("data", nargs="+", help="folders of scene files from 'heapgrasp critic data'")
    _report_arguments(e)
    e.set_defaults(func=_evaluate)
    c = sub.add_parser(
        "convert",
        help="convert a critic of the former .npz format to ONNX",
        description=(
            "Reads a critic .npz file (checked whole) and writes the same model, "
            "standardisation and thresholds as the ONNX file heapgrasp runs."
        ),
    )
    c.add_argument("src", help="critic file of the former format (.npz)")
    c.add_argument("dst", help="ONNX critic file to write")
    c.set_defaults(func=_convert)
    return p
