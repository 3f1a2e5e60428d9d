"""``heapgrasp bench topk``: how good each grasp planner's best few grasps are on the grids
the closed loop really meets (issue 58), labelled on the true meshes.

An offline score of a grasp network (its AP over a dataset's grids and grasps) need not
predict what the loop does with it: the loop takes the network's *best* grasps, on the
grids *its own* views carve. This benchmark measures exactly that. For ``--scenes``
seeded scenes (seed ``seed + i``, test split) the clutter-removal protocol runs as
``heapgrasp run`` runs it (``--method``'s views and grid: ``vgn`` ranks on the depth
sensor's TSDF, without a critic; the run's default grasp planner, the *driver*, decides
what is executed, so the scenes evolve as a run's do). At every phase,
on the grid the phase planned its grasp from, each planner of ``--planners`` proposes
its candidates through the loop's own selection
(:meth:`~heapgrasp.loop.phase.Pipeline.grasp_candidates`: eq. 15's smoothing, threshold
and NMS, the hull check of a network's grasps, the failed-grasp memory, the critic where
configured), and its top ``k`` candidates are labelled by the exact labeller
(:func:`heapgrasp.sim.grasp_labels.labeller`) on the scene's true meshes at that moment,
with the fingers fully open as VGN labels (the labeller agrees with physics on 92 % of
executed grasps, ``docs/benchmarks.md``).

Reported per planner: phases with a candidate; precision@k, the share of labelled
successes among every grasp it ranked ≤ k over all phases (a phase with fewer than k
candidates adds what it has); the median planning time; and the driver's closed-loop
success, which its precision@1 should predict; and how well its scores are calibrated,
its labelled grasps' share held per score bin (:func:`reliability`: the reliability
diagram ``OUT/reliability.png`` and the expected calibration error). Writes
``OUT/results.json`` (records per phase and planner), ``OUT/table.md`` and
``OUT/summary.md``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from heapgrasp.loop.config import ConfigError, RunConfig

if TYPE_CHECKING:
    from heapgrasp.loop.phase import Pipeline
    from heapgrasp.sim.world import SimWorld

__all__ = [
    "PLANNERS",
    "TopKConfig",
    "evaluate_phase",
    "figure_reliability",
    "planner_configs",
    "reliability",
    "run",
    "run_bench",
]

#: The planners this benchmark can rank, as changes to the run's settings.
PLANNERS: dict[str, dict[str, Any]] = {
    "antipodal": {"grasp_planner": "antipodal", "grasp_critic": "none"},
    "antipodal+critic": {"grasp_planner": "antipodal", "grasp_critic": "default"},
    "network": {"grasp_planner": "network", "grasp_critic": "none"},
    "network+critic": {"grasp_planner": "network", "grasp_critic": "default"},
}

#: The ranks reported (precision@k).
KS = (1, 3, 5)


@dataclass(frozen=True)
class TopKConfig:
    """What :func:`run_bench` runs."""

    scenes: int = 20
    seed: int = 80000
    objects: int = 5
    method: str = "heapgrasp"
    planners: tuple[str, ...] = tuple(PLANNERS)
    changes: dict[str, Any] = field(default_factory=dict)
    """Further run settings (``--set``), for the driver and every planner."""

    def run_config(self) -> RunConfig:
        """The driver's settings: ``heapgrasp run``'s, for this method and scene size."""
        base = {"method": self.method, "objects": self.objects, "seed": self.seed}
        return RunConfig().replace({**base, **self.changes}, source="bench topk")


def evaluate_phase(
    pipeline: Pipeline,
    world: SimWorld,
    rankers: dict[str, tuple[RunConfig, Any, Any]],
) -> dict[str, Any]:
    """Every ranker's top :data:`KS` candidates on ``pipeline``'s grid now, labelled on
    ``world``'s true meshes: per ranker the candidates' scores and labels, best first."""
    from heapgrasp.sim.grasp_labels import labeller

    label = labeller(world)
    names = label.reasons()
    out: dict[str, Any] = {}
    for name, (config, planner, critic) in rankers.items():
        with pipeline.planning_as(config, planner, critic):
            t0 = time.perf_counter()
            cands = pipeline.grasp_candidates()
            ms = 1e3 * (time.perf_counter() - t0)
        top = cands[: max(KS)]
        if top:
            poses = np.ascontiguousarray(np.stack([c.pose for c in top]), dtype=np.float64)
            ok, _, held, reason = label.label(poses, threads=1)
            labels = [bool(v) for v in ok]
            reasons = [names[int(r)] for r in reason]
            objects = [int(h) for h in held]
        else:
            labels, reasons, objects = [], [], []
        out[name] = {
            "candidates": len(cands),
            "scores": [float(c.score) for c in top],
            "labels": labels,
            "reasons": reasons,
            "objects": objects,
            "planning_ms": ms,
        }
    return out


def planner_configs(config: TopKConfig, base: RunConfig) -> dict[str, RunConfig]:
    """Each ranked planner's settings: ``base`` with :data:`PLANNERS`' changes; a
    :class:`ConfigError` naming the planner where they do not apply (a critic for
    ``vgn``)."""
    out = {}
    for name in config.planners:
        try:
            out[name] = base.replace(PLANNERS[name], source=f"planner {name}")
        except ConfigError as exc:
            raise ConfigError(f"--planners {name}: {exc}") from None
    return out


def _rankers(config: TopKConfig, base: RunConfig) -> dict[str, tuple[RunConfig, Any, Any]]:
    from heapgrasp.geometry.gripper import PANDA_HAND
    from heapgrasp.loop.stages import make_critic, make_grasp_planner

    return {
        name: (cfg, make_grasp_planner(cfg, PANDA_HAND), make_critic(cfg))
        for name, cfg in planner_configs(config, base).items()
    }


def run_scene(config: TopKConfig, index: int) -> dict[str, Any]:
    """Scene ``index`` through the protocol, every phase's rankings labelled."""
    from heapgrasp.loop.protocol import PlanResult, run_clutter_removal
    from heapgrasp.sim.build import scene_world, sim_pipeline

    base = config.run_config()
    seed = config.seed + index
    rankers = _rankers(config, base)
    phases: list[dict[str, Any]] = []
    with scene_world(base, seed, base.category) as world:
        pipeline = sim_pipeline(base, world, seed=seed)

        def plan() -> PlanResult:
            result = pipeline.plan()
            phases.append({"rankings": evaluate_phase(pipeline, world, rankers)})
            return result

        def outcome(grasp: Any, result: Any) -> None:
            phases[-1]["driver_outcome"] = str(result.value if hasattr(result, "value") else result)
            pipeline.record_outcome(grasp, result)

        done, reason = run_clutter_removal(
            pipeline.robot,
            plan,
            truth=pipeline.truth,
            max_attempts=base.max_attempts,
            on_outcome=outcome,
        )
    return {
        "scene": index,
        "seed": seed,
        "stop_reason": reason.value,
        "driver_outcomes": [p.to_dict()["outcome"] for p in done],
        "phases": phases,
    }


#: Score bins of the reliability diagram (the last edge holds 1.0).
BINS = (0.0, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95, 1.0)


def reliability(scores: npt.ArrayLike, labels: npt.ArrayLike) -> dict[str, Any]:
    """Predicted against measured success of labelled grasps: per score bin of
    :data:`BINS` the grasps, their mean score and the share that held, and the expected
    calibration error (the grasps' weighted mean of |mean score − share held| over the
    bins; 0 for a planner whose scores are probabilities)."""
    s = np.asarray(scores, dtype=np.float64)
    y = np.asarray(labels, dtype=np.float64)
    bins = []
    ece = 0.0
    for lo, hi in itertools.pairwise(BINS):
        inside = (s >= lo) & ((s < hi) if hi < 1.0 else (s <= hi))
        n = int(inside.sum())
        if n == 0:
            continue
        mean, held = float(s[inside].mean()), float(y[inside].mean())
        bins.append({"from": lo, "to": hi, "grasps": n, "mean_score": mean, "held": held})
        ece += n * abs(mean - held)
    return {"bins": bins, "ece": ece / len(s) if len(s) else None, "grasps": len(s)}


def figure_reliability(summary: dict[str, Any], planners: Sequence[str], path: Path) -> None:
    """The reliability diagram: per planner, each score bin's share held against its
    mean score (the diagonal: calibrated), the marker's area its grasps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 5))
    ax.plot([0, 1], [0, 1], "k--", lw=1, label="calibrated")
    for name in planners:
        bins = summary[name]["reliability"]["bins"]
        if not bins:
            continue
        x = [b["mean_score"] for b in bins]
        y = [b["held"] for b in bins]
        ece = summary[name]["reliability"]["ece"]
        ax.plot(x, y, "-o", lw=1, ms=3, label=f"{name} (ECE {ece:.3f})")
        ax.scatter(x, y, s=[4 * b["grasps"] for b in bins], alpha=0.3)
    ax.set(
        xlim=(0.4, 1.0),
        ylim=(0.0, 1.0),
        xlabel="score (predicted success)",
        ylabel="share held (exact labeller)",
        title="top-k grasps on the loop's grids",
    )
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def summarize(records: Sequence[dict[str, Any]], planners: Sequence[str]) -> dict[str, Any]:
    """Per planner: phases, phases with a candidate, precision@k (successes among the
    labelled grasps ranked ≤ k, over every phase), and the driver's closed-loop success."""
    out: dict[str, Any] = {}
    phases = [p for r in records for p in r.get("phases", [])]
    for name in planners:
        rows = [p["rankings"][name] for p in phases if name in p["rankings"]]
        entry: dict[str, Any] = {
            "phases": len(rows),
            "with_candidate": sum(1 for r in rows if r["candidates"]),
        }
        for k in KS:
            labels = [v for r in rows for v in r["labels"][:k]]
            entry[f"precision@{k}"] = (sum(labels) / len(labels)) if labels else None
            entry[f"labelled@{k}"] = len(labels)
        ms = [r["planning_ms"] for r in rows]
        entry["planning_ms_median"] = float(np.median(ms)) if ms else None
        scores = [v for r in rows for v in r["scores"][: len(r["labels"])]]
        labels = [v for r in rows for v in r["labels"]]
        entry["reliability"] = reliability(scores, labels)
        out[name] = entry
    executed = [o for r in records for o in r.get("driver_outcomes", []) if o != "no_candidate"]
    out["driver_closed_loop"] = {
        "attempts": len(executed),
        "success_rate": (sum(o == "success" for o in executed) / len(executed))
        if executed
        else None,
    }
    return out


def markdown_table(summary: dict[str, Any], config: TopKConfig) -> str:
    """The summary as a markdown table."""
    head = "| planner | phases with a candidate | " + " | ".join(f"precision@{k}" for k in KS)
    head += " | calibration error"
    lines = [
        f"## Top-k grasps on the loop's grids ({config.method}, {config.scenes} scenes from "
        f"seed {config.seed})",
        "",
        head + " | planning (median) |",
        "|---|--:|" + "--:|" * len(KS) + "--:|--:|",
    ]
    for name in config.planners:
        s = summary[name]
        cells = []
        for k in KS:
            p, n = s[f"precision@{k}"], s[f"labelled@{k}"]
            cells.append("–" if p is None else f"{100 * p:.1f} % ({n})")
        ms = s["planning_ms_median"]
        ece = s["reliability"]["ece"]
        cells.append("–" if ece is None else f"{ece:.3f}")
        lines.append(
            f"| {name} | {s['with_candidate']} / {s['phases']} | "
            + " | ".join(cells)
            + f" | {'–' if ms is None else f'{ms:.0f} ms'} |"
        )
    d = summary["driver_closed_loop"]
    rate = d["success_rate"]
    lines += [
        "",
        f"The driver (the run's default planner) executed {d['attempts']} grasps, "
        + ("none" if rate is None else f"{100 * rate:.1f} % of them held")
        + " in physics: its precision@1 should predict that.",
        "",
        "Calibration error: the labelled grasps' mean |score − share held| over the score "
        "bins of the reliability diagram (0: the scores are probabilities).",
    ]
    return "\n".join(lines) + "\n"


def run_bench(config: TopKConfig, *, progress: bool = True) -> list[dict[str, Any]]:
    """Every scene of ``config``; a scene that raises is recorded with its error."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    records: list[dict[str, Any]] = []
    bar = tqdm(
        total=config.scenes,
        desc="bench topk",
        unit="scene",
        disable=not progress,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    try:
        for i in range(config.scenes):
            try:
                records.append(run_scene(config, i))
            except ConfigError:
                raise
            except Exception as exc:  # recorded, the run goes on
                records.append(
                    {"scene": i, "seed": config.seed + i, "error": f"{type(exc).__name__}: {exc}"}
                )
            bar.update(1)
    finally:
        bar.close()
    return records


def run(args: argparse.Namespace) -> int:
    """``heapgrasp bench topk``; 0, 1 where a scene raised, 2 for bad settings."""
    from heapgrasp.bench.carve import machine_info
    from heapgrasp.loop.config import parse_sets
    from heapgrasp.results.pages import write_summary

    try:
        config = TopKConfig(
            scenes=args.scenes,
            seed=args.seed,
            objects=args.objects,
            method=args.method,
            planners=tuple(args.planners),
            changes=parse_sets(args.set or []),
        )
        planner_configs(config, config.run_config())  # settings checked before any scene
    except ConfigError as exc:
        print(f"heapgrasp bench topk: {exc}", file=sys.stderr)
        return 2
    out: Path = args.out or Path("runs") / f"bench-topk-{time.strftime('%Y%m%d-%H%M%S')}"
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        records = run_bench(config, progress=not args.quiet)
    except ConfigError as exc:
        print(f"heapgrasp bench topk: {exc}", file=sys.stderr)
        return 2
    summary = summarize(records, config.planners)
    table = markdown_table(summary, config)
    payload = {
        "benchmark": "topk",
        "command": " ".join(["heapgrasp", *getattr(args, "argv", ["bench", "topk"])]),
        "wall_time_s": time.perf_counter() - t0,
        "machine": machine_info(),
        "config": {**asdict(config), "planner_settings": {n: PLANNERS[n] for n in config.planners}},
        "summary": summary,
        "records": records,
    }
    (out / "results.json").write_text(json.dumps(payload, indent=2) + "\n")
    (out / "table.md").write_text(table)
    figure_reliability(summary, config.planners, out / "reliability.png")
    write_summary(out, table, [("reliability.png", "reliability diagram")])
    print(table)
    print(f"results: {out}")
    return 1 if any("error" in r for r in records) else 0
