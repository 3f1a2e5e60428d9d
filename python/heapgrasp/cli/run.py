"""``heapgrasp run``: simulated pick-and-place runs from the command line.

Parameters come from the defaults (HEAPGrasp Table I), then ``--config FILE`` (TOML),
then the flags; ``--set KEY=VALUE`` reaches every :class:`~heapgrasp.loop.config.RunConfig`
field.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from heapgrasp.cli.argtypes import OBJECT_DIR_HELP, object_dir
from heapgrasp.loop.config import (
    CATEGORIES,
    GRASP_PLANNERS,
    LAYOUTS,
    METHODS,
    MOUNTS,
    VIEW_PLANNERS,
    ConfigError,
    ConfigFile,
    RunConfig,
    compose,
    parse_sets,
    presets,
)
from heapgrasp.results.records import CONFIG_FILE, RunDir

__all__ = ["add_parser", "config_from_args", "run_command"]

_FLAGS = {
    "method": "method",
    "view_planner": "view_planner",
    "grasp_planner": "grasp_planner",
    "grasp_weights": "grasp_weights",
    "view_weights": "view_weights",
    "layout": "layout",
    "category": "category",
    "objects": "objects",
    "scenes": "scenes",
    "seed": "seed",
    "noise": "noise",
    "mount": "mount",
    "object_dir": "object_dir",
}


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Adds ``heapgrasp run`` to the CLI."""
    p = subparsers.add_parser(
        "run",
        help="simulated pick-and-place: HEAPGrasp or a baseline on seeded scenes",
        description="Run HEAPGrasp (or a baseline) on seeded simulated scenes until each "
        "is cleared, two consecutive grasps fail, or no grasp is found (HEAPGrasp §VI-C). "
        "With no arguments: one mixed 5-object scene with the shipped view network "
        "planning the views and the analytic antipodal grasp planner. Writes "
        "OUT/config.json, OUT/scenes.jsonl (one record per finished scene, written as it "
        "ends) and OUT/results.json, and prints "
        "a summary table. Defaults: Table I of the paper plus the extensions measured to "
        "help (docs/running.md; --config paper turns them off); precedence: defaults < "
        "--config < flags < --set.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="methods: heapgrasp = view planning (eq. 12-19) + SfS; no-vp = once around a "
        "circle of L waypoints + SfS; vgn = circle + depth/TSDF (simulated depth failures on "
        "transparent and specular objects); hemisphere6 = GraspNeRF's six views + SfS.\n"
        "example: heapgrasp run --method no-vp --category transparent --scenes 5 --out runs/t",
    )
    p.add_argument("--method", choices=METHODS, help="method (default heapgrasp)")
    p.add_argument(
        "--view-planner",
        choices=VIEW_PLANNERS,
        help="view planner of heapgrasp (default network: the shipped view network, eq. 13; "
        "oracle: exact eq. 14 from the true meshes, an upper bound that needs the simulator)",
    )
    p.add_argument(
        "--grasp-planner",
        choices=("auto", *GRASP_PLANNERS),
        help="grasp planner (default auto: the analytic planner for heapgrasp, no-vp and "
        "hemisphere6, VGN's network for vgn; antipodal: analytic, needs no training; "
        "network: the grasp network of eq. 11, its grasps checked against the hull, or for "
        "vgn VGN's network on the TSDF, checked against the TSDF)",
    )
    p.add_argument(
        "--grasp-weights",
        help="grasp-network weights file (--grasp-planner network; default: the shipped "
        "occupancy network, or for vgn the shipped TSDF network)",
    )
    p.add_argument("--view-weights", help="view-network weights file (--view-planner network)")
    p.add_argument("--layout", choices=LAYOUTS, help="scene layout (default pile)")
    p.add_argument("--category", choices=CATEGORIES, help="scene group (default mixed)")
    p.add_argument("--objects", type=int, help="objects per scene (default 5)")
    p.add_argument("--scenes", type=int, help="number of scenes (default 1)")
    p.add_argument("--seed", type=int, help="seed of scene 0; scene i uses seed + i (default 0)")
    p.add_argument("--noise", type=float, help="mask pixel-flip probability (Table V; default 0)")
    p.add_argument("--mount", choices=MOUNTS, help="free-flying hand (default) or Panda arm")
    p.add_argument("--object-dir", metavar="DIR", type=object_dir, help=OBJECT_DIR_HELP)
    p.add_argument(
        "--config",
        metavar="FILE|PRESET",
        help="TOML file of RunConfig fields, or a shipped preset: " + ", ".join(presets()),
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set any RunConfig field (VALUE parsed as JSON, else a string), e.g. --set L=4",
    )
    p.add_argument("--out", type=Path, help="output directory (default runs/<time>-<method>)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out")
    p.add_argument("--workers", type=int, default=1, help="scenes in parallel (processes)")
    p.add_argument("--gui", action="store_true", help="show the PyBullet GUI (workers = 1)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--viz",
        action="store_true",
        help="record every phase to OUT/viz/scene-NNN.rrd for the Rerun viewer "
        "(needs rerun-sdk: pip install 'heapgrasp[viz]'; see also heapgrasp show)",
    )
    p.add_argument(
        "--print-config", action="store_true", help="print the resolved configuration and exit"
    )
    p.set_defaults(func=run_command)
    return p


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """The :class:`RunConfig` of parsed ``heapgrasp run`` arguments (:func:`compose`).

    With ``--resume`` it is the configuration saved in ``--out``: the run continues as it
    was configured, and flags, ``--config`` and ``--set`` may only repeat it (a
    :class:`ConfigError` lists what they would change)."""
    loaded = ConfigFile.load(args.config) if args.config is not None else None
    flags = {field: getattr(args, dest) for dest, field in _FLAGS.items()}
    sets = parse_sets(args.set)
    if not args.resume:
        return compose(loaded, flags, sets)
    if args.out is None:
        raise ConfigError("--resume: name the run to continue with --out DIR")
    saved = RunDir(args.out).read_config()
    if saved is None:
        raise ConfigError(
            f"--resume: {args.out} holds no run to continue ({CONFIG_FILE} not found)"
        )
    base = loaded.resolve(saved.method) if loaded is not None else saved
    asked = base.replace(flags, source="command line").replace(sets, source="--set")
    if asked != saved:
        changed = saved.changes_to(asked)
        raise ConfigError(
            f"--resume continues {args.out} as {args.out / CONFIG_FILE} configures it; the "
            f"options given would change {changed}: leave them out, or start a new run "
            "in another --out"
        )
    return saved


def run_command(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp run``; returns the exit status."""
    from heapgrasp.run import REFUSED, format_summary, run

    try:
        config = config_from_args(args)
    except ConfigError as exc:
        print(f"heapgrasp run: {exc}", file=sys.stderr)
        return 2
    if args.print_config:
        print(json.dumps(config.to_dict(), indent=2))
        return 0
    out: Path = args.out or Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{config.method}"
    try:
        summary = run(
            config,
            out,
            resume=args.resume,
            workers=args.workers,
            progress=not args.quiet,
            gui=args.gui,
            viz=args.viz,
        )
    except REFUSED as exc:  # before any scene ran
        print(f"heapgrasp run: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"heapgrasp run: interrupted; finished scenes are in {out}; continue with "
            f"--resume --out {out}",
            file=sys.stderr,
        )
        return 130
    text = format_summary(summary)
    print(text)
    from heapgrasp.plots import write_run_page

    written = write_run_page(summary, text, out)
    print(f"results: {out / 'results.json'}; summary: {', '.join(str(p) for p in written)}")
    if args.viz:
        print(f"recordings: {out / 'viz'} (one .rrd per scene; view with `rerun FILE`)")
    return 1 if summary["scenes_failed"] else 0
