"""``heapgrasp bench sim``: HEAPGrasp's simulation protocol for several methods.

Seed 000 §VI-C: ``--scenes`` scenes (20 by default) of ``--objects`` objects, split into
four equal scene groups — transparent, opaque, specular, mixed — every method on the
same seeded scenes (scene ``i`` has seed ``seed + i``). Each method's run is a normal
:func:`heapgrasp.run.run` in ``OUT/<method>/`` (resumable), on a process pool.

Writes ``OUT/summary.md`` (the tables with the figures), ``OUT/table.md`` (a Table
II-style overall table beside the paper's numbers and
a Table III-style table per scene group; every success rate with its 95 % interval, and
each method's difference from no-vp with a paired scene-bootstrap interval,
:mod:`heapgrasp.results.stats`), ``OUT/summary.json``, ``OUT/fig5_paths.png``
(camera paths in the x–y plane, as Fig. 5) and ``OUT/fig4_grids.png`` (the measured
high-confidence grid of one phase with its grasp candidates, as Fig. 4).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from heapgrasp.loop.config import METHODS, ConfigError, ConfigFile, RunConfig
from heapgrasp.results.pages import write_summary
from heapgrasp.results.stats import format_interval, methods_differences, success_interval

__all__ = [
    "PAPER_TABLE_II",
    "add_uncertainty",
    "markdown_tables",
    "run_bench",
    "scene_groups",
]

#: HEAPGrasp Table II (simulation): success (%), (succeeded, attempted), trajectory length
#: (m) mean ± std, shortest trajectory ratio (%) mean ± std.
PAPER_TABLE_II: dict[str, tuple[float, tuple[int, int], tuple[float, float], tuple[int, int]]] = {
    "vgn": (87.1, (433, 497), (1.87, 0.09), (325, 35)),
    "no-vp": (92.7, (458, 494), (1.87, 0.08), (337, 32)),
    "heapgrasp": (86.4, (432, 500), (0.94, 0.12), (151, 27)),
}
#: HEAPGrasp Table III (real robot), overall success (%) per method and scene group.
PAPER_TABLE_III: dict[str, dict[str, float]] = {
    "vgn": {"opaque": 88.5, "specular": 72.0, "transparent": 53.8, "mixed": 74.1},
    "hemisphere6": {"opaque": 91.7, "specular": 52.2, "transparent": 68.2, "mixed": 73.1},
    "no-vp": {"opaque": 96.2, "specular": 100.0, "transparent": 96.0, "mixed": 100.0},
    "heapgrasp": {"opaque": 92.6, "specular": 100.0, "transparent": 95.7, "mixed": 96.2},
}
GROUPS = ("transparent", "opaque", "specular", "mixed")


def scene_groups(scenes: int) -> list[str]:
    """Scene group of each scene: four equal consecutive blocks (§VI-C)."""
    return [GROUPS[min(3, (4 * i) // scenes)] for i in range(scenes)]


def _configs(
    args: argparse.Namespace, methods: Sequence[str]
) -> tuple[RunConfig, dict[str, RunConfig]]:
    """The base config (the tables' header) and each method's
    (:func:`heapgrasp.loop.config.compose`: ``--config``, its ``[methods.NAME]`` table, the
    flags, ``--set``)."""
    from heapgrasp.loop.config import compose, parse_sets

    loaded = ConfigFile.load(args.config) if args.config is not None else None
    flags = {"scenes": args.scenes, "objects": args.objects, "seed": args.seed}
    flags["layout"] = args.layout
    flags["object_dir"] = args.object_dir
    sets = parse_sets(args.set)
    per_method = {m: compose(loaded, flags, sets, m) for m in methods if m in METHODS}
    return compose(loaded, flags, sets), per_method


def run_bench(
    base: RunConfig,
    methods: Sequence[str],
    out: Path,
    *,
    workers: int = 1,
    resume: bool = False,
    progress: bool = True,
    figures: bool = True,
    per_method: Mapping[str, RunConfig] | None = None,
) -> dict[str, dict[str, Any]]:
    """Runs every method on the same scenes; writes the tables (and figures). A method
    runs with ``base``, or with its entry in ``per_method`` (a config file's
    ``[methods.NAME]`` table applied), its ``method`` set to it."""
    from heapgrasp.run import run

    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ConfigError(f"--methods: unknown {bad}; choose among {', '.join(METHODS)}")
    out.mkdir(parents=True, exist_ok=True)
    groups = scene_groups(base.scenes)
    summaries: dict[str, dict[str, Any]] = {}
    for method in methods:
        config = (per_method or {}).get(method, base).replace({"method": method})
        t0 = time.perf_counter()
        summaries[method] = run(
            config,
            out / method,
            resume=resume,
            workers=workers,
            categories=groups,
            progress=progress,
        )
        summaries[method]["bench_wall_time_s"] = time.perf_counter() - t0
    add_uncertainty(summaries)
    (out / "summary.json").write_text(
        json.dumps(
            {m: {k: v for k, v in s.items() if k != "phases"} for m, s in summaries.items()},
            indent=2,
        )
    )
    (out / "table.md").write_text(markdown_tables(summaries, base))
    if figures:
        from heapgrasp.plots import figure_paths

        figure_paths(summaries, out / "fig5_paths.png")
        figure_grids(base, list(methods), out / "fig4_grids.png", scene=0)
    write_summary(
        out,
        markdown_tables(summaries, base),
        [
            ("fig5_paths.png", "Fig. 5: camera paths of scene 0's first phase"),
            ("fig4_grids.png", "Fig. 4: the measured grid of one phase, its candidates"),
        ],
    )
    return summaries


def add_uncertainty(summaries: dict[str, dict[str, Any]], reference: str = "no-vp") -> None:
    """Adds to every method's summary ``grasp_success_ci95`` (Wilson, percent) and, when
    ``reference`` ran and the summaries hold their ``phases``, ``success_difference``: the
    paired scene-bootstrap difference from ``reference`` in points
    (:mod:`heapgrasp.results.stats`)."""
    for s in summaries.values():
        n, k = s.get("grasps_attempted", 0), s.get("grasps_succeeded", 0)
        s["grasp_success_ci95"] = [100 * x for x in success_interval(k, n)] if n else None
    if not all("phases" in s for s in summaries.values()):
        return
    diffs = methods_differences({m: s["phases"] for m, s in summaries.items()}, reference)
    for m, d in diffs.items():
        summaries[m]["success_difference"] = {"reference": reference, **d}


def _ci(s: dict[str, Any]) -> str:
    n, k = s.get("grasps_attempted", 0), s.get("grasps_succeeded", 0)
    if not n:
        return "–"
    low, high = success_interval(k, n)
    return format_interval(100 * low, 100 * high)


def _pm(stat: dict[str, Any], digits: int) -> str:
    if stat.get("mean") is None:
        return "–"
    return f"{stat['mean']:.{digits}f} ± {stat['std']:.{digits}f}"


def _ms(stat: dict[str, Any]) -> str:
    if stat.get("mean") is None:
        return "–"
    return f"{1e3 * stat['mean']:.0f} ± {1e3 * stat['std']:.0f}"


def _rate(s: dict[str, Any]) -> str:
    r = s.get("grasp_success_rate")
    if r is None:
        return "–"
    return f"{100 * r:.1f} ({s['grasps_succeeded']}/{s['grasps_attempted']})"


def _left(s: dict[str, Any]) -> str:
    o = s.get("objects") or {}
    if o.get("objects_left") is None:
        return "–"
    out = f"{o['objects_left']} ({o['leftovers_graspable']})"
    return out + (f", {o['objects_knocked_out']} out" if o.get("objects_knocked_out") else "")


def _ceiling(s: dict[str, Any]) -> str:
    ceiling = (s.get("objects") or {}).get("removal_ceiling")
    return "–" if ceiling is None else f"{100 * ceiling:.1f}"


def markdown_tables(summaries: dict[str, dict[str, Any]], base: RunConfig) -> str:
    """Table II-style (overall, beside the paper) and Table III-style (per group) tables."""
    lines = [
        f"# heapgrasp bench sim — {base.scenes} scenes × {base.objects} objects ({base.layout})",
        "",
        *(
            []
            if base.object_dir is None
            else [f"Objects: the user's, from `{base.object_dir}`.", ""]
        ),
        "Overall (Table II shape). Paper columns: HEAPGrasp Table II (simulation, ideal depth "
        "and masks); ours: the simulated depth sensor of `docs/simulation.md` unless "
        "`ideal_depth = true`. Removed: objects picked and placed, of those placed. Left "
        "(graspable): objects left on the table when the scenes ended (those the hand "
        "could have taken on their true meshes), and those knocked out of the workspace. "
        "Ceiling: (removed + graspable leftovers) / objects.",
        "",
        "| Method | Success (%) | 95 % CI | Removed | Left (graspable) | Ceiling (%) "
        "| Trajectory (m) | Shortest ratio (%) "
        "| Exec. time (s) | Latency / waypoint (s) | Grasp planning / call (ms) "
        "| Wall / scene (s) | Paper success (%) | Paper trajectory (m) | Paper ratio (%) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method, s in summaries.items():
        paper = PAPER_TABLE_II.get(method)
        p_cols = (
            f"{paper[0]} ({paper[1][0]}/{paper[1][1]}) | {paper[2][0]} ± {paper[2][1]} | "
            f"{paper[3][0]} ± {paper[3][1]}"
            if paper
            else "– | – | –"
        )
        removed = f"{s['objects_removed']}/{s['objects_total']}"
        lines.append(
            f"| {s.get('label', method)} | {_rate(s)} | {_ci(s)} | {removed} "
            f"| {_left(s)} | {_ceiling(s)} "
            f"| {_pm(s['trajectory_length_m'], 2)} | {_pm(s['shortest_trajectory_ratio'], 0)} "
            f"| {_pm(s['execution_time_s'], 2)} | {_pm(s['planning_latency_per_waypoint_s'], 3)} "
            f"| {_ms(s.get('grasp_planning_per_call_s', {}))} "
            f"| {_pm(s['wall_time_per_scene_s'], 1)} | {p_cols} |"
        )
    lines += [
        "",
        "Per scene group (Table III shape; paper = real robot, overall success).",
        "",
        "| Method | Group | Success (%) | Trajectory (m) | Shortest ratio (%) | Exec. time (s) "
        "| Paper success (%) |",
        "|---|---|---|---|---|---|---|",
    ]
    for method, s in summaries.items():
        for group, g in s.get("per_scene_group", {}).items():
            paper_g = PAPER_TABLE_III.get(method, {}).get(group)
            lines.append(
                f"| {method} | {group} | {_rate(g)} | {_pm(g['trajectory_length_m'], 2)} "
                f"| {_pm(g['shortest_trajectory_ratio'], 0)} | {_pm(g['execution_time_s'], 2)} "
                f"| {'–' if paper_g is None else paper_g} |"
            )
    ref = summaries.get("no-vp")
    if ref and ref["trajectory_length_m"]["mean"]:
        lines += ["", "Trajectory length relative to no-vp:", ""]
        for method, s in summaries.items():
            if s["trajectory_length_m"]["mean"] is not None:
                ratio = s["trajectory_length_m"]["mean"] / ref["trajectory_length_m"]["mean"]
                lines.append(f"- {method}: {100 * ratio:.0f} %")
    diffs = {m: s["success_difference"] for m, s in summaries.items() if "success_difference" in s}
    if diffs:
        lines += [
            "",
            "Success rate minus no-vp's, in points, with a 95 % interval from resampling the "
            "scenes both ran (paired bootstrap, `heapgrasp.results.stats`):",
            "",
        ]
        for method, d in diffs.items():
            if d["difference"] is None:
                lines.append(f"- {method}: – (no attempt)")
            else:
                lines.append(
                    f"- {method}: {d['difference']:+.1f} {format_interval(d['low'], d['high'])}"
                    f" over {d['scenes']} scenes"
                )
    return "\n".join(lines) + "\n"


def command(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp bench sim``; returns the exit status."""
    from heapgrasp.run import REFUSED

    try:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
        base, per_method = _configs(args, methods)
        out: Path = args.out or Path("runs") / f"bench-sim-{time.strftime('%Y%m%d-%H%M%S')}"
        summaries = run_bench(
            base,
            methods,
            out,
            workers=args.workers,
            resume=args.resume,
            progress=not args.quiet,
            figures=not args.no_figures,
            per_method=per_method,
        )
    except REFUSED as exc:
        print(f"heapgrasp bench sim: {exc}", file=sys.stderr)
        return 2
    print((out / "table.md").read_text())
    print(f"results: {out}")
    return 1 if any(s["scenes_failed"] for s in summaries.values()) else 0


def figure_grids(base: RunConfig, methods: Sequence[str], path: Path, *, scene: int = 0) -> None:
    """The measured grid after the first phase's views of ``scene`` per method (Fig. 4),
    re-running that phase in-process."""
    import numpy as np

    from heapgrasp.plots import _pyplot
    from heapgrasp.sim.build import object_library, scene_world, sim_pipeline

    plt = _pyplot()
    fig = plt.figure(figsize=(4.5 * len(methods), 4.5))
    library = object_library(base)
    group = ("transparent", "opaque", "specular", "mixed")[min(3, (4 * scene) // base.scenes)]
    for k, method in enumerate(methods):
        config = base.replace({"method": method})
        seed = config.seed + scene
        ax = fig.add_subplot(1, len(methods), k + 1, projection="3d")
        with scene_world(config, seed, group, library=library) as world:
            pipeline = sim_pipeline(config, world, seed=seed)
            planned = pipeline.plan()
            grid = pipeline.perception.grasp_input()
            cands = pipeline.grasp_candidates()
        occ = np.argwhere(grid > 0)
        centres = pipeline.frame.centers(occ)
        voxels = ax.scatter(
            *centres.T, s=2, c=centres[:, 2], cmap="viridis", alpha=0.4, label="Ŝ≥λ voxel"
        )
        fig.colorbar(voxels, ax=ax, shrink=0.6, pad=0.1, label="voxel height z (m)")
        if cands:
            cp = np.stack([c.position for c in cands])
            ax.scatter(*cp.T, s=25, c="tab:green", depthshade=False, label="grasp candidate")
        if planned.grasp is not None:
            g = planned.grasp.pose
            ax.scatter(*g[:3, 3], s=60, c="tab:red", depthshade=False, label="executed grasp")
            tip = g[:3, 3] - 0.05 * g[:3, 2]
            ax.plot(*np.stack([tip, g[:3, 3]]).T, c="tab:red", lw=2)
        size = config.cube_size
        ax.set_xlim(0, size)
        ax.set_ylim(0, size)
        ax.set_zlim(0, size)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_zlabel("z (m)")
        ax.legend(fontsize=7, loc="upper left")
        ax.set_title(f"{method} ({group}): {len(occ)} voxels, {len(cands)} grasps")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
