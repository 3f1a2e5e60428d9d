"""``heapgrasp bench carve|world|sim|grasp|topk|compare|seg|noise|clutter``: the
benchmarks' command lines; each runs a function of :mod:`heapgrasp.bench` (the module
named in its parser's function) with the parsed options.

The viewsphere benchmark (Natarajan et al.) is ``heapgrasp viewsphere bench``
(:mod:`heapgrasp.cli.viewsphere`); ``bench viewsphere`` is its old spelling, kept for
one release (:mod:`heapgrasp.cli.aliases`).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import TypeAlias

from heapgrasp.bench import carve, compare, grasp, paper_tables, sim, topk, world
from heapgrasp.bench import seg as bench_seg
from heapgrasp.cli.argtypes import (
    OBJECT_DIR_HELP,
    comma_choices,
    float_in,
    int_at_least,
    object_dir,
)
from heapgrasp.loop.config import CATEGORIES, LAYOUTS, METHODS, RunConfig, presets

__all__ = [
    "add_carve",
    "add_compare",
    "add_grasp",
    "add_parser",
    "add_seg",
    "add_sim",
    "add_tables",
    "add_topk",
    "add_world",
]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def add_parser(commands: SubParsers) -> SubParsers:
    """Adds the ``bench`` group and its benchmarks; returns the group's subparsers (where
    the old spelling ``bench viewsphere`` is registered)."""
    p = commands.add_parser(
        "bench",
        help="benchmarks: the closed loop on the paper's protocols (sim, noise, clutter), "
        "run comparisons, and the Rust core's speed",
        description="Benchmarks: the closed loop on the paper's protocols (sim: Tables "
        "II/III; noise: Table V; clutter: Table IV), comparisons of finished runs, and the "
        "speed of the Rust core and the networks. Natarajan et al.'s active-vision benchmark is "
        "'heapgrasp viewsphere bench'.",
    )
    benches = p.add_subparsers(
        dest="benchmark", metavar="BENCHMARK", title="benchmarks", required=True
    )
    add_carve(benches)
    add_world(benches)
    add_sim(benches)
    add_grasp(benches)
    add_topk(benches)
    add_compare(benches)
    add_seg(benches)
    add_tables(benches)
    return benches


def _carve_sizes(text: str) -> tuple[int, ...]:
    items = [s.strip() for s in text.split(",") if s.strip()]
    if not items:
        raise argparse.ArgumentTypeError("expected comma-separated resolutions, e.g. 40,80")
    return tuple(int_at_least(1)(s) for s in items)


def _carve_images(text: str) -> tuple[tuple[int, int], ...]:
    out = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        parts = item.lower().split("x")
        if len(parts) != 2:
            raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {item!r}")
        out.append((int_at_least(1)(parts[0]), int_at_least(1)(parts[1])))
    if not out:
        raise argparse.ArgumentTypeError("expected comma-separated WIDTHxHEIGHT, e.g. 320x240")
    return tuple(out)


def add_carve(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench carve`` (:mod:`heapgrasp.bench.carve`)."""
    p = subparsers.add_parser(
        "carve",
        help="Shape-from-Silhouette carving: Rust kernel vs NumPy / numba / Open3D",
        description=(
            "Times OccupancyGrid.integrate_many (Rust) against a plain NumPy reference, "
            "an @njit(parallel=True) numba loop and Open3D's VoxelGrid.carve_silhouette "
            "(the last two when installed), all on the same silhouettes: a ring of "
            "cameras around the 0.30 m workspace cube looking at three spheres (the "
            "criterion fixtures of benches/). Reports the median time per call, voxel "
            "projections per second (R^3 x views / time) and the speed-up over NumPy, "
            "and checks that the Rust and numba counts equal the NumPy reference up to "
            f"voxels within {carve.BORDER_TOL:g} px of a pixel border (exit status 1 if not)."
        ),
        epilog=(
            "examples:\n"
            "  heapgrasp bench carve                      # 40,80,160 x 320x240,640x480\n"
            "  heapgrasp bench carve --quick              # 40,80 x 320x240\n"
            "  heapgrasp bench carve --sizes 80 --methods rust,numpy --json carve.json"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--sizes",
        type=_carve_sizes,
        default=None,
        metavar="R[,R...]",
        help="grid resolutions R (R^3 voxels), comma-separated (default: 40,80,160)",
    )
    p.add_argument(
        "--images",
        type=_carve_images,
        default=None,
        metavar="WxH[,WxH...]",
        help="image sizes; fx = fy = 540 * W / 640, principal point at the centre "
        "(default: 320x240,640x480)",
    )
    p.add_argument(
        "--views",
        type=int_at_least(1),
        default=30,
        metavar="N",
        help="silhouettes carved per call (default: 30)",
    )
    p.add_argument(
        "--methods",
        type=comma_choices("method", carve.METHODS),
        default=carve.METHODS,
        metavar="M[,M...]",
        help=f"methods to run, from {','.join(carve.METHODS)} (default: all; numpy is the "
        "reference for the speed-up and the count check)",
    )
    p.add_argument(
        "--repeats",
        type=int_at_least(1),
        default=None,
        metavar="N",
        help="timed runs per method and configuration (default: "
        + ", ".join(f"{k} {v}" for k, v in carve.DEFAULT_REPEATS.items())
        + "); fewer when --max-seconds is reached",
    )
    p.add_argument(
        "--max-seconds",
        type=float_in(0.0, open_low=True),
        default=10.0,
        metavar="S",
        help="time budget per method and configuration: no further run starts once "
        "it would take the total past S seconds; at least one run always happens "
        "(default: 10)",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="only 40^3 and 80^3 at 320x240 (explicit --sizes/--images take precedence)",
    )
    p.add_argument(
        "--json",
        default=None,
        metavar="PATH",
        help="also write all timings, checks and machine info as JSON to PATH",
    )
    p.add_argument(
        "--no-progress", action="store_true", help="do not show the progress bar (stderr)"
    )
    p.set_defaults(func=carve.run)
    return p


def add_world(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench world`` (:mod:`heapgrasp.bench.world`)."""
    p = subparsers.add_parser(
        "world",
        help="simulated world: ground-truth masks vs PyBullet rendering, seconds per phase",
        description=world.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--frames", type=int, default=60, help="frames per rendering method")
    p.add_argument("--phases", type=int, default=5, help="grasp phases to time")
    p.add_argument(
        "--camera", choices=("continuous", "still"), default="continuous", help="camera preset"
    )
    p.add_argument("--seed", type=int, default=0, help="scene seed")
    p.add_argument("--json", type=Path, default=None, help="write the results as JSON here")
    p.set_defaults(func=world.run)
    return p


def add_sim(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench sim`` (:mod:`heapgrasp.bench.sim`)."""
    p = subparsers.add_parser(
        "sim",
        help="seed 000's simulation protocol for several methods: Table II/III, Fig. 4/5",
        description=sim.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--methods",
        default="heapgrasp,no-vp,vgn",
        help=f"comma-separated methods among {', '.join(METHODS)}",
    )
    p.add_argument("--scenes", type=int, default=20, help="scenes per method (4 groups)")
    p.add_argument("--objects", type=int, default=5, help="objects per scene")
    p.add_argument("--seed", type=int, default=0, help="seed of scene 0")
    p.add_argument("--layout", choices=("pile", "packed"), default="pile")
    p.add_argument("--object-dir", metavar="DIR", type=object_dir, help=OBJECT_DIR_HELP)
    p.add_argument(
        "--config",
        metavar="FILE|PRESET",
        help="TOML file of RunConfig fields (all methods), or a shipped preset: "
        + ", ".join(presets()),
    )
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="set a RunConfig field"
    )
    p.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="processes (scenes in parallel)",
    )
    p.add_argument("--out", type=Path, help="output directory (default runs/bench-sim-<time>)")
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the runs in --out (a finished run only re-renders its tables)",
    )
    p.add_argument("--no-figures", action="store_true", help="skip Fig. 4/5")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=sim.command)
    return p


def add_grasp(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench grasp`` (:mod:`heapgrasp.bench.grasp`)."""
    p = subparsers.add_parser(
        "grasp",
        help="the analytic antipodal grasp planner on circle / dense SfS grids, one grasp "
        "per scene",
        description=grasp.__doc__,
        epilog=(
            "examples:\n"
            "  heapgrasp bench grasp --scenes 5 --grids circle\n"
            "  heapgrasp bench grasp --scenes 20 --grids circle,dense --out runs/bench-grasp"
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--scenes", type=int_at_least(1), default=30, metavar="N", help="scenes (default: 30)"
    )
    p.add_argument(
        "--seed",
        type=int_at_least(0),
        default=0,
        metavar="S",
        help="seed of scene 0; scene i has seed S + i (default: 0)",
    )
    p.add_argument("--layout", choices=LAYOUTS, default="pile", help="scene layout (default: pile)")
    p.add_argument(
        "--objects",
        type=int_at_least(1),
        default=5,
        metavar="N",
        help="objects per scene (default: 5)",
    )
    p.add_argument(
        "--category", choices=CATEGORIES, default="mixed", help="scene group (default: mixed)"
    )
    p.add_argument(
        "--grids",
        type=comma_choices("grid", grasp.GRIDS),
        default=grasp.GRIDS,
        metavar="G[,G...]",
        help=f"grids to evaluate, from {','.join(grasp.GRIDS)} (default: both)",
    )
    p.add_argument(
        "--epsilon",
        type=float_in(0.0, 1.0),
        default=None,
        metavar="E",
        help="score threshold ε of select_candidates (default: AntipodalPlanner().epsilon)",
    )
    p.add_argument(
        "--sigma",
        type=float_in(0.0),
        default=None,
        metavar="S",
        help="Gaussian σ (voxels) of select_candidates (default: AntipodalPlanner().sigma)",
    )
    p.add_argument(
        "--roof-radius",
        type=float_in(0.0, 1.0),
        default=RunConfig.roof_radius,
        metavar="R",
        help=(
            "disc radius (m) trimming the grids' roofs before planning, as the pipeline "
            f"does (default {RunConfig.roof_radius}; 0: the untrimmed hull)"
        ),
    )
    p.add_argument(
        "--out", type=Path, default=None, help="output directory (default runs/bench-grasp-<time>)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=grasp.run)
    return p


def add_topk(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench topk`` (:mod:`heapgrasp.bench.topk`)."""
    p = subparsers.add_parser(
        "topk",
        help="each grasp planner's top-k grasps on the grids the loop meets, labelled on "
        "the true meshes (does an offline score predict the loop?)",
        description=topk.__doc__,
        epilog="example: heapgrasp bench topk --scenes 20 --method no-vp --out runs/topk",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--scenes", type=int_at_least(1), default=20, metavar="N")
    p.add_argument(
        "--seed", type=int_at_least(0), default=80000, metavar="S", help="seed of scene 0"
    )
    p.add_argument("--objects", type=int_at_least(1), default=5, metavar="N")
    p.add_argument(
        "--method",
        choices=("heapgrasp", "no-vp", "vgn"),
        default="heapgrasp",
        help="whose views carve the grids (default heapgrasp; vgn: the depth sensor's TSDF, "
        "whose planners take no critic)",
    )
    p.add_argument(
        "--planners",
        type=comma_choices("planner", tuple(topk.PLANNERS)),
        default=tuple(topk.PLANNERS),
        metavar="P[,P...]",
        help=f"planners to rank, from {','.join(topk.PLANNERS)} (default: all)",
    )
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="a run setting (repeatable)")
    p.add_argument("--out", type=Path, default=None, help="output directory")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=topk.run)
    return p


def add_compare(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench compare`` (:mod:`heapgrasp.bench.compare`)."""
    p = subparsers.add_parser(
        "compare",
        help="two finished runs on the same scenes: success rates with intervals, difference",
        description=compare.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("a", type=Path, help="run directory A (holds scenes.jsonl)")
    p.add_argument("b", type=Path, help="run directory B, the reference")
    p.add_argument(
        "--pool",
        nargs=2,
        type=Path,
        action="append",
        default=[],
        metavar=("A2", "B2"),
        help="pool another pair of runs on other seeds into A and B (repeatable)",
    )
    p.add_argument("--level", type=float, default=0.95, help="interval level (default 0.95)")
    p.add_argument(
        "--resamples", type=int, default=10_000, help="bootstrap resamples (default 10000)"
    )
    p.add_argument(
        "--breakdown",
        action="store_true",
        help="also print each run's success per band of the executed grasp's score (the "
        "critic's probability), per way its viewing ended (early stop after k "
        "waypoints, or all), per count of candidates and of objects left, with the "
        "failure outcomes, and its collisions by what and which part of the hand touched",
    )
    p.add_argument(
        "--different-scenes",
        action="store_true",
        help="compare even where a seed holds a different scene in A and B (other objects, "
        "category or layout); refused without it",
    )
    p.add_argument("--json", type=Path, help="also write the comparison to this file")
    p.set_defaults(func=compare.command)
    return p


def _seg_size(text: str) -> str:
    w, sep, h = text.partition("x")
    if not (sep and w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, e.g. 320x240, got {text!r}")
    return text


def add_seg(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``bench seg`` (:mod:`heapgrasp.bench.seg`)."""
    p = subparsers.add_parser(
        "seg",
        help="CPU time of the segmentation network per frame, per encoder",
        description=bench_seg.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--encoders",
        type=comma_choices("encoder", bench_seg.ENCODERS),
        default=bench_seg.ENCODERS,
        help=f"comma-separated encoders (default: {','.join(bench_seg.ENCODERS)})",
    )
    p.add_argument("--size", type=_seg_size, default="320x240", help="frame size (default 320x240)")
    p.add_argument("--threads", type=int_at_least(1), default=1, help="onnxruntime threads")
    p.add_argument("--repeats", type=int_at_least(1), default=20, help="timed runs (default 20)")
    p.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    p.set_defaults(func=bench_seg.run)
    return p


def _noise_levels(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(t) for t in text.split(",") if t.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of numbers: {text!r}") from None
    bad = [v for v in values if not 0.0 < v <= 0.5]
    if bad or not values:
        raise argparse.ArgumentTypeError(f"noise levels must be in (0, 0.5]; got {text!r}")
    return values


def _object_counts(text: str) -> tuple[int, ...]:
    try:
        values = tuple(int(t) for t in text.split(",") if t.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a list of integers: {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"object counts must be >= 1; got {text!r}")
    return values


def _table_methods(text: str) -> tuple[str, ...]:
    names = tuple(m.strip() for m in text.split(",") if m.strip())
    bad = [m for m in names if m not in METHODS]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"unknown method(s) {bad or '(none)'}; choose among {', '.join(METHODS)}"
        )
    return names


def _table_options(p: argparse.ArgumentParser, scenes: int) -> None:
    p.add_argument(
        "--scenes",
        type=int_at_least(1),
        default=scenes,
        help=f"scenes per cell (default {scenes}; the paper's Table V is 100 scenes of 5)",
    )
    p.add_argument("--seed", type=int_at_least(0), default=0, help="seed of scene 0")
    p.add_argument(
        "--config",
        metavar="FILE|PRESET",
        help="TOML file of RunConfig fields (every cell), or a shipped preset: "
        + ", ".join(presets()),
    )
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="set a RunConfig field"
    )
    p.add_argument(
        "--workers",
        type=int_at_least(1),
        default=os.cpu_count() or 1,
        help="processes (scenes in parallel)",
    )
    p.add_argument("--out", type=Path, help="output directory (default runs/bench-<name>-<time>)")
    p.add_argument("--resume", action="store_true", help="continue the cells in --out")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def add_tables(subparsers: SubParsers) -> None:
    """Adds ``bench noise`` and ``bench clutter`` (:mod:`heapgrasp.bench.paper_tables`)."""
    noise = subparsers.add_parser(
        "noise",
        help="Table V in simulation: w/o VP under pixel-flip mask noise (MSE, IoU, grasped)",
        description=paper_tables.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    noise.add_argument(
        "--levels",
        type=_noise_levels,
        default=paper_tables.NOISE_LEVELS,
        help="comma-separated flip probabilities (default 0.01,0.05,0.10,0.15)",
    )
    noise.add_argument(
        "--methods", type=_table_methods, default=("no-vp",), help="methods (default no-vp: w/o VP)"
    )
    _table_options(noise, 20)
    noise.set_defaults(func=paper_tables.noise_command)
    clutter = subparsers.add_parser(
        "clutter",
        help="Table IV in simulation: w/o VP and w/ VP on 6, 8, 10 and 12 mixed objects",
        description=paper_tables.__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    clutter.add_argument(
        "--counts",
        type=_object_counts,
        default=paper_tables.CLUTTER_COUNTS,
        help="comma-separated objects per scene (default 6,8,10,12)",
    )
    clutter.add_argument(
        "--methods",
        type=_table_methods,
        default=("no-vp", "heapgrasp"),
        help="methods (default no-vp,heapgrasp: w/o VP and w/ VP)",
    )
    _table_options(clutter, 20)
    clutter.set_defaults(func=paper_tables.clutter_command)
