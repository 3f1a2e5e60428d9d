"""``heapgrasp bench viewsphere``: seed 001's active-vision benchmark (§4.1, §5.1).

Each object stands at the table's centre in ``--poses`` poses (the protocol's yaws,
:func:`~heapgrasp.sim.viewsphere_protocol.protocol_yaws`); from each pose every policy
runs one episode from the start view (azimuth π, polar π/7): a move of 20° at a time
on the viewsphere until the fused views yield a grasp (seed 001 §3.3) or 6 moves were
made. A pose without a grasp after them counts 6 steps. The policies:

* ``random``: a uniformly random direction each move (seeded per pose);
* ``brick``: always north-east;
* ``heuristic-2d``, ``heuristic-3d``: seed 001's Algorithms 1 and 2
  (:mod:`heapgrasp.planning.viewsphere_heuristics`);
* ``information-gain``: the comparison of §4.2.3, which flies between 34 fixed
  viewpoints; its steps are viewpoints, and ``travelled_steps`` its path in 20° steps;
* ``pca-lr``, ``pca-lda``, ``dqn``: seed 001's learned policies (§4.3), trained on the
  training shapes only (:mod:`heapgrasp.planning.viewsphere_learned`), from the shipped
  files or ``--weights MODEL=FILE``;
* ``heapgrasp-net``, ``heapgrasp-oracle``: HEAPGrasp's eq. 14 on a grid carved from the
  views' silhouettes (no depth), scored by the shipped view network or, privileged, by
  the exact oracle reading the true meshes
  (:mod:`heapgrasp.planning.viewsphere_heapgrasp`); ``oracle_agreement`` records, per
  decision of the network, whether the oracle chose alike;
* ``bfs``: breadth-first search, the fewest moves that reach a set of views yielding a
  grasp (each distinct set of views synthesised once; at most ``bfs_max_sets`` sets,
  past which the pose counts as not found and is marked incomplete).

Unless ``--no-execute``, the grasp an episode found is also executed by the
free-flying Panda hand in PyBullet on the object (lift and shake): the physical success
the paper did not measure.

Writes in ``--out``:

* ``results.json``: ``{"policies": {POLICY: {"objects": {OBJECT: {"success_at_step":
  [7 fractions, steps 0..6], "mean_steps", "executed_success", "poses": [...]}}}}}``,
  the settings, each object's class and the errors;
* ``records/OBJECT.jsonl``: one line per finished pose (what a rerun resumes from);
* ``table.md``: success at each step per object and policy, mean steps, the class;
  each policy's success over BFS's per class at steps 1 and 3 (Fig. 11), decision
  times, and information gain vs the 3D heuristic (Table 1);
* ``fig10_success.png``: success vs step per object, all policies (the paper's Fig. 10);
* ``fig11_bfs_ratio.png``: policy / BFS success per class at steps 1 and 3 (Fig. 11);
* ``difficulty.png``: random's share of BFS's success at step 2 per object, with the
  class thresholds (≤ 0.40 hard, ≤ 0.80 medium, else easy).

Rerunning with the same ``--out`` and settings continues where a run stopped (poses
already recorded are not run again); other settings are refused.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from datetime import datetime
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.bench.argtypes import add_ray_argument, comma_choices, int_at_least
from heapgrasp.bench.pages import write_summary
from heapgrasp.loop.config import parse_sets
from heapgrasp.loop.records import write_json
from heapgrasp.loop.viewsphere import ViewsphereConfig

__all__ = [
    "CLASS_THRESHOLDS",
    "POLICIES",
    "PoseTask",
    "add_parser",
    "classify",
    "markdown_table",
    "run_pose",
    "summarize",
]

#: The policies, in the order they are reported.
POLICIES = (
    "random",
    "brick",
    "heuristic-2d",
    "heuristic-3d",
    "information-gain",
    "pca-lr",
    "pca-lda",
    "dqn",
    "heapgrasp-net",
    "heapgrasp-oracle",
    "bfs",
)
#: Policies whose steps are viewpoints flown to, not 20° moves: their success per
#: step is not comparable with the others' and they stay out of Fig. 11 (Table 1
#: compares their path in steps).
VIEWPOINT_POLICIES = ("information-gain",)
#: The learned policies: each runs a policy file (shipped, or ``--weights MODEL=FILE``).
LEARNED = ("pca-lr", "pca-lda", "dqn")
#: Random's share of BFS's success at step 2: at most the first is hard, at most the
#: second medium, else easy (seed 001 §5.1).
CLASS_THRESHOLDS = (0.40, 0.80)
#: The sensor options: the paper's ideal depth, or our depth sensor's model with the
#: object of that optical category.
SENSORS = ("ideal", "opaque", "transparent", "specular")


@dataclass(frozen=True)
class PoseTask:
    """One object pose: every policy's episode from it."""

    object_name: str
    meshes: tuple[tuple[Any, Any], ...]
    """The object's meshes at rest (yaw 0)."""
    pose: int
    yaw_deg: float
    policies: tuple[str, ...]
    config: dict[str, Any]
    seed: int
    sensor: str
    execute: bool
    weights: tuple[tuple[str, str], ...] = ()
    """The learned policies' files, ``(model, path)``."""


def _policy(
    name: str, world: Any, config: ViewsphereConfig, weights: Mapping[str, str] | None = None
) -> Any:
    """The policy ``name`` for episodes in ``world`` (a learned one from ``weights``)."""
    from heapgrasp.planning import viewsphere_heuristics as vh
    from heapgrasp.planning.viewsphere_policies import BrickPolicy, RandomPolicy

    if name in ("random", "brick"):
        return {"random": RandomPolicy, "brick": BrickPolicy}[name]()
    scorer = config.view_scorer(world.sphere, world.camera)
    if name == "heuristic-2d":
        return vh.Heuristic2D(scorer)
    if name == "heuristic-3d":
        return vh.Heuristic3D(scorer, half_length=world.grasps.gripper.max_opening)
    if name == "information-gain":
        return vh.InformationGain(scorer)
    if name in ("heapgrasp-oracle", "heapgrasp-net"):
        from heapgrasp.planning.viewsphere_heapgrasp import HeapgraspViewPolicy

        network = None
        if name == "heapgrasp-net":
            from heapgrasp.inference import shipped_weights
            from heapgrasp.planning.view_network import NetworkViewScorer

            path = shipped_weights("view-network")
            if path is None:
                raise ValueError("heapgrasp-net needs the shipped view network; none ships")
            network = NetworkViewScorer(str(path))
        return HeapgraspViewPolicy(
            world.sphere,
            world.camera,
            world.silhouette,
            "oracle" if name == "heapgrasp-oracle" else "network",
            scene=world.objects_scene,
            network=network,
        )
    if name in LEARNED:
        from heapgrasp.planning.viewsphere_learned import LearnedPolicy

        if not weights or name not in weights:
            raise ValueError(f"no policy file for {name}")
        return LearnedPolicy.from_file(weights[name], scorer, name)
    raise ValueError(f"unknown policy {name!r}")


class _Timed:
    """A policy whose decisions are timed (seconds per call, in ``times``)."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.name = policy.name
        self.times: list[float] = []

    @property
    def agreement(self) -> list[bool] | None:
        """The HEAPGrasp network policy's agreement with the oracle, per decision."""
        out: list[bool] | None = getattr(self.policy, "agreement", None)
        return out

    def reset(self, seed: int) -> None:
        self.times = []
        self.policy.reset(seed)

    def choose(self, state: Any) -> int:
        t = time.perf_counter()
        out: int = self.policy.choose(state)
        self.times.append(time.perf_counter() - t)
        return out

    def choose_view(self, state: Any) -> Any:
        t = time.perf_counter()
        out = self.policy.choose_view(state)
        self.times.append(time.perf_counter() - t)
        return out


def run_pose(task: PoseTask) -> dict[str, Any]:
    """Every policy's episode on one object pose (module doc): the pose's record."""
    import math

    from heapgrasp.geometry.viewsphere import DIRECTIONS
    from heapgrasp.planning.viewsphere_policies import (
        breadth_first,
        run_episode,
        run_viewpoint_episode,
    )
    from heapgrasp.sim.optics import Category
    from heapgrasp.sim.viewsphere_world import ViewsphereWorld

    config = ViewsphereConfig.from_dict(task.config)
    sensor = None if task.sensor == "ideal" else Category(task.sensor)
    t0 = time.perf_counter()
    yaw = math.radians(task.yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    world = ViewsphereWorld(
        [(np.asarray(v) @ turn.T, f) for v, f in task.meshes],
        config=config,
        sensor=sensor,
        seed=task.seed * 1000 + task.pose,
    )
    record: dict[str, Any] = {"pose": task.pose, "yaw_deg": task.yaw_deg, "policies": {}}
    executor = _Executor(task) if task.execute else None
    for name in task.policies:
        t = time.perf_counter()
        sets_before = world.grasps.sets_evaluated
        decisions: list[float] = []
        agreement: list[bool] | None = None
        if name == "bfs":
            episode = breadth_first(
                world.grasp_found,
                sphere=world.sphere,
                start=world.start,
                max_steps=config.max_steps,
                max_sets=config.bfs_max_sets,
            )
        else:
            policy = _Timed(_policy(name, world, config, dict(task.weights)))
            run = run_viewpoint_episode if name == "information-gain" else run_episode
            episode = run(
                policy,
                world.grasp_found,
                sphere=world.sphere,
                start=world.start,
                max_steps=config.max_steps,
                seed=task.seed * 1000 + task.pose,
                observe=world.grasps.fused,
            )
            decisions = policy.times
            agreement = policy.agreement
        grasp = world.grasp(list(episode.poses)) if episode.found else None
        seconds = time.perf_counter() - t
        entry: dict[str, Any] = {
            "path": [DIRECTIONS[d] for d in episode.directions],
            "views_deg": [
                [round(math.degrees(p.azimuth), 3), round(math.degrees(p.polar), 3)]
                for p in episode.poses
            ],
            "steps": episode.steps,
            "travelled_steps": round(episode.travelled / world.sphere.step, 4),
            "found": episode.found,
            "complete": episode.complete,
            "grasp": None if grasp is None else grasp.to_dict(),
            "quality_deg": None if grasp is None else round(grasp.quality, 4),
            "executed": None,
            "seconds": round(seconds, 4),
            "decisions_s": [round(t, 5) for t in decisions],
            **({"oracle_agreement": agreement} if agreement else {}),
            "sets_synthesised": world.grasps.sets_evaluated - sets_before,
        }
        if executor is not None and grasp is not None:
            entry["executed"] = executor.outcome(grasp)
        record["policies"][name] = entry
    record["seconds"] = round(time.perf_counter() - t0, 4)
    return record


class _Executor:
    """Executes found grasps on the pose's object with the simulated hand; the same grasp
    (two policies ending on one set of views) is executed once."""

    def __init__(self, task: PoseTask) -> None:
        self.task = task
        self._done: dict[bytes, str] = {}

    def outcome(self, grasp: Any) -> str:
        from heapgrasp.sim.viewsphere_execute import execute_found_grasp

        key = np.round(grasp.pose, 9).tobytes()
        if key not in self._done:
            self._done[key] = execute_found_grasp(
                self.task.object_name,
                list(self.task.meshes),
                float(np.radians(self.task.yaw_deg)),
                grasp,
            )
        return self._done[key]


# --------------------------------------------------------------------------------------
# Summary
# --------------------------------------------------------------------------------------
def _policy_summary(records: Sequence[Mapping[str, Any]], name: str, steps: int) -> dict[str, Any]:
    entries = [r["policies"][name] for r in records if name in r.get("policies", {})]
    n = len(entries)
    found = np.array([e["found"] for e in entries], dtype=bool)
    taken = np.array([e["steps"] if e["found"] else steps for e in entries], dtype=np.float64)
    success = [float(np.mean(found & (taken <= s))) if n else 0.0 for s in range(steps + 1)]
    executed = [e["executed"] for e in entries if e.get("executed") is not None]
    decisions = [t for e in entries for t in e.get("decisions_s", [])]
    return {
        "poses_run": n,
        "success_at_step": success,
        "mean_steps": float(taken.mean()) if n else None,
        "mean_travelled_steps": (
            float(np.mean([e.get("travelled_steps", 0.0) for e in entries])) if n else None
        ),
        "mean_decision_s": float(np.mean(decisions)) if decisions else None,
        "max_decision_s": float(np.max(decisions)) if decisions else None,
        "found": int(found.sum()),
        "incomplete": sum(not e.get("complete", True) for e in entries),
        "executed": len(executed),
        "executed_success": (
            sum(o == "success" for o in executed) / len(executed) if executed else None
        ),
        "executed_outcomes": {o: executed.count(o) for o in sorted(set(executed))},
        "mean_seconds": float(np.mean([e["seconds"] for e in entries])) if n else None,
        "poses": [
            {"pose": r["pose"], "yaw_deg": r["yaw_deg"], **r["policies"][name]}
            for r in records
            if name in r.get("policies", {})
        ],
    }


def classify(random_at_2: float | None, bfs_at_2: float | None) -> str | None:
    """An object's class from random's and BFS's success at step 2 (seed 001 §5.1)."""
    if random_at_2 is None or bfs_at_2 is None:
        return None
    if bfs_at_2 <= 0.0:
        return "hard"
    ratio = random_at_2 / bfs_at_2
    if ratio <= CLASS_THRESHOLDS[0]:
        return "hard"
    return "medium" if ratio <= CLASS_THRESHOLDS[1] else "easy"


def summarize(
    settings: Mapping[str, Any],
    records: Mapping[str, Sequence[Mapping[str, Any]]],
    errors: Mapping[str, str],
) -> dict[str, Any]:
    """``results.json``'s content from each object's pose records."""
    steps = int(settings["config"]["max_steps"])
    policies: dict[str, Any] = {}
    for name in settings["policies"]:
        policies[name] = {
            "objects": {
                obj: _policy_summary(sorted(recs, key=lambda r: r["pose"]), name, steps)
                for obj, recs in records.items()
                if recs
            }
        }
    classes: dict[str, Any] = {}
    for obj in records:
        at2 = {
            name: policies[name]["objects"][obj]["success_at_step"][min(2, steps)]
            for name in ("random", "bfs")
            if name in policies and obj in policies[name]["objects"]
        }
        ratio = at2["random"] / at2["bfs"] if len(at2) == 2 and at2["bfs"] > 0 else None
        classes[obj] = {
            "random_at_2": at2.get("random"),
            "bfs_at_2": at2.get("bfs"),
            "ratio": ratio,
            "class": classify(at2.get("random"), at2.get("bfs")),
        }
    return {
        "benchmark": "seed 001 viewsphere",
        "settings": dict(settings),
        "policies": policies,
        "classes": classes,
        "bfs_ratios": bfs_ratios(policies, classes),
        "table1": table1(policies),
        "errors": dict(errors),
        "seconds": sum(r.get("seconds", 0.0) for recs in records.values() for r in recs),
    }


def bfs_ratios(
    policies: Mapping[str, Any], classes: Mapping[str, Any], steps: Sequence[int] = (1, 3)
) -> dict[str, dict[str, dict[str, float | None]]]:
    """Fig. 11's numbers: per policy, class (easy, medium, hard, all) and step, the mean
    over the class's objects of the policy's success over BFS's (objects where BFS
    found nothing by that step are left out; policies that fly between viewpoints,
    :data:`VIEWPOINT_POLICIES`, too)."""
    if "bfs" not in policies:
        return {}
    bfs = policies["bfs"]["objects"]
    out: dict[str, dict[str, dict[str, float | None]]] = {}
    for name, pol in policies.items():
        if name == "bfs" or name in VIEWPOINT_POLICIES:
            continue
        out[name] = {}
        for cls in ("easy", "medium", "hard", "all"):
            objs = [
                o
                for o, c in classes.items()
                if (cls == "all" or c["class"] == cls) and o in pol["objects"] and o in bfs
            ]
            row: dict[str, float | None] = {}
            for step in steps:
                r = [
                    pol["objects"][o]["success_at_step"][step] / bfs[o]["success_at_step"][step]
                    for o in objs
                    if step < len(bfs[o]["success_at_step"]) and bfs[o]["success_at_step"][step] > 0
                ]
                row[f"step_{step}"] = float(np.mean(r)) if r else None
            out[name][cls] = row
    return out


#: Seed 001's Table 1 average reductions of the 3D heuristic over information gain (%):
#: effective steps, time.
PAPER_TABLE1_REDUCTIONS = (41.0, 73.0)


def table1(policies: Mapping[str, Any]) -> dict[str, Any]:
    """Table 1's numbers per object: information gain's viewpoints and effective steps,
    the 3D heuristic's steps, and the reduction (%); each one's decision time per
    episode and episode time (s), and the reduction of the latter."""
    if not {"information-gain", "heuristic-3d"} <= set(policies):
        return {}
    gain = policies["information-gain"]["objects"]
    h3d = policies["heuristic-3d"]["objects"]
    rows: dict[str, Any] = {}
    for obj in gain:
        if obj not in h3d:
            continue
        g, h = gain[obj], h3d[obj]
        eff, steps = g["mean_travelled_steps"], h["mean_steps"]

        def per_episode(o: Mapping[str, Any]) -> float:
            return float(np.mean([sum(p.get("decisions_s", [])) for p in o["poses"]]))

        rows[obj] = {
            "viewpoints": g["mean_steps"],
            "effective_steps": eff,
            "heuristic_3d_steps": steps,
            "step_reduction_pct": 100.0 * (eff - steps) / eff if eff else None,
            "gain_seconds": g["mean_seconds"],
            "heuristic_3d_seconds": h["mean_seconds"],
            "time_reduction_pct": (
                100.0 * (g["mean_seconds"] - h["mean_seconds"]) / g["mean_seconds"]
                if g["mean_seconds"]
                else None
            ),
            "gain_decision_seconds": per_episode(g),
            "heuristic_3d_decision_seconds": per_episode(h),
        }
    mean = {
        key: float(np.mean([r[key] for r in rows.values() if r[key] is not None]))
        for key in ("step_reduction_pct", "time_reduction_pct")
        if any(r[key] is not None for r in rows.values())
    }
    keys = ("step_reduction_pct", "time_reduction_pct")
    paper = dict(zip(keys, PAPER_TABLE1_REDUCTIONS, strict=True))
    return {"objects": rows, "mean": mean, "paper_mean": paper}


def markdown_table(results: Mapping[str, Any]) -> str:
    """Success at each step per object and policy, mean steps, executed success and the
    objects' classes, as Markdown."""
    settings = results["settings"]
    steps = int(settings["config"]["max_steps"])
    lines = [
        "# Seed 001's viewsphere benchmark",
        "",
        f"Objects: {len(results['classes'])}; poses per object: {settings['poses']}; "
        f"sensor: {settings['sensor']}; random seed: {settings['seed']}; "
        f"BFS budget: {settings['config']['bfs_max_sets']} sets of views.",
        "",
        "Success: the fraction of poses where a grasp was found within the step; "
        "mean steps count a pose without a grasp as "
        f"{steps}; executed: the found grasps the simulated hand lifted. A policy marked "
        "(viewpoints) counts viewpoints flown to, not 20° moves (its path in moves: "
        "Table 1).",
        "",
        "| object | class | policy | "
        + " | ".join(f"{s}" for s in range(steps + 1))
        + " | mean steps | executed | s / pose |",
        "|---|---|---|" + "---|" * (steps + 1) + "---|---|---|",
    ]
    for obj, cls in results["classes"].items():
        for name, pol in results["policies"].items():
            o = pol["objects"].get(obj)
            if o is None:
                continue
            exe = o["executed_success"]
            extra = f" ({o['incomplete']} incomplete)" if o["incomplete"] else ""
            lines.append(
                f"| {obj} | {cls['class'] or '–'} | {_label(name)}{extra} | "
                + " | ".join(f"{100 * v:.0f}" for v in o["success_at_step"])
                + f" | {o['mean_steps']:.2f} | "
                + ("–" if exe is None else f"{100 * exe:.0f} % of {o['executed']}")
                + f" | {o['mean_seconds']:.2f} |"
            )
    means = []
    for name, pol in results["policies"].items():
        objs = list(pol["objects"].values())
        if objs:
            curve = np.mean([o["success_at_step"] for o in objs], axis=0)
            ms = np.mean([o["mean_steps"] for o in objs])
            means.append(
                f"| mean | | {_label(name)} | "
                + " | ".join(f"{100 * v:.0f}" for v in curve)
                + f" | {ms:.2f} | | |"
            )
    lines += means
    ratios = results.get("bfs_ratios") or {}
    if ratios:
        lines += [
            "",
            "## Policy / BFS success (Fig. 11)",
            "",
            "| policy | easy 1 | easy 3 | medium 1 | medium 3 | hard 1 | hard 3 | all 1 | all 3 |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for name, by_class in ratios.items():
            cells = [
                "–" if (v := by_class[c][f"step_{s}"]) is None else f"{v:.2f}"
                for c in ("easy", "medium", "hard", "all")
                for s in (1, 3)
            ]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
    decisions = [
        (name, pol["objects"])
        for name, pol in results["policies"].items()
        if any(o.get("mean_decision_s") is not None for o in pol["objects"].values())
    ]
    if decisions:
        lines += ["", "## Decision time", "", "| policy | mean ms | max ms |", "|---|---|---|"]
        for name, objs in decisions:
            timed = [o for o in objs.values() if o["mean_decision_s"] is not None]
            mean_s = [float(o["mean_decision_s"]) for o in timed]
            max_s = [float(o["max_decision_s"]) for o in timed]
            lines.append(
                f"| {name} | {1000 * float(np.mean(mean_s)):.0f} | {1000 * max(max_s):.0f} |"
            )
    t1 = results.get("table1") or {}
    if t1.get("objects"):
        lines += [
            "",
            "## Information gain vs the 3D heuristic (Table 1)",
            "",
            "| object | viewpoints | effective steps | 3D steps | reduction % | "
            "gain s / episode | 3D s / episode | reduction % |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for obj, r in t1["objects"].items():
            lines.append(
                f"| {obj} | {r['viewpoints']:.2f} | {r['effective_steps']:.2f} | "
                f"{r['heuristic_3d_steps']:.2f} | {_pct(r['step_reduction_pct'])} | "
                f"{r['gain_seconds']:.2f} | {r['heuristic_3d_seconds']:.2f} | "
                f"{_pct(r['time_reduction_pct'])} |"
            )
        m, paper = t1["mean"], t1["paper_mean"]
        lines.append(
            f"| mean (paper) | | | | {_pct(m.get('step_reduction_pct'))} "
            f"({_pct(paper.get('step_reduction_pct'))}) | | | "
            f"{_pct(m.get('time_reduction_pct'))} ({_pct(paper.get('time_reduction_pct'))}) |"
        )
    if results["errors"]:
        lines += ["", "## Errors", ""]
        lines += [f"- {obj}: {msg}" for obj, msg in results["errors"].items()]
    return "\n".join(lines) + "\n"


def _label(name: str) -> str:
    """A policy's name in tables and legends (steps in viewpoints said so)."""
    return f"{name} (viewpoints)" if name in VIEWPOINT_POLICIES else name


def _pct(v: float | None) -> str:
    return "–" if v is None else f"{v:.0f}"


def figures(results: Mapping[str, Any], out: Path) -> None:
    """``fig10_success.png`` and ``difficulty.png`` (module doc)."""
    from heapgrasp.plots import _pyplot

    plt = _pyplot()
    objects = list(results["classes"])
    if not objects:
        return
    steps = int(results["settings"]["config"]["max_steps"])
    cols = min(4, len(objects))
    rows = (len(objects) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for ax, obj in zip(axes.flat, objects, strict=False):
        for name, pol in results["policies"].items():
            o = pol["objects"].get(obj)
            if o is not None:
                ax.plot(
                    range(steps + 1),
                    o["success_at_step"],
                    marker="o",
                    ms=3,
                    ls=":" if name in VIEWPOINT_POLICIES else "-",
                    label=_label(name),
                )
        cls = results["classes"][obj]["class"]
        ax.set_title(f"{obj}" + (f" ({cls})" if cls else ""), fontsize=8)
        ax.set_ylim(0, 1.02)
        ax.set_xticks(range(steps + 1))
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(objects) :]:
        ax.axis("off")
    axes[0][0].legend(fontsize=7)
    fig.supxlabel("steps")
    fig.supylabel("success")
    fig.tight_layout()
    fig.savefig(out / "fig10_success.png", dpi=110)
    plt.close(fig)
    by_class = results.get("bfs_ratios") or {}
    if by_class:
        classes = ("easy", "medium", "hard")
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.2), sharey=True)
        width = 0.8 / len(by_class)
        for ax, step in zip(axes, (1, 3), strict=True):
            for k, (name, rows) in enumerate(by_class.items()):
                values = [rows[c][f"step_{step}"] for c in classes]
                # groups centred on their class's tick, all inside the axes
                xs = [i - 0.4 + (k + 0.5) * width for i in range(len(classes))]
                ax.bar(xs, [np.nan if v is None else v for v in values], width, label=name)
                for x, v in zip(xs, values, strict=True):
                    # a measured 0 and a class without objects must not look alike
                    if v is None:
                        ax.text(x, 0.02, "n/a", ha="center", va="bottom", fontsize=7, rotation=90)
                    elif v == 0:
                        ax.text(x, 0.02, "0", ha="center", va="bottom", fontsize=6)
            ax.set_xticks(range(len(classes)), classes)
            ax.set_xlim(-0.5, len(classes) - 0.5)
            ax.set_xlabel("object class (seed 001 §5.1)")
            ax.set_title(f"step {step}", fontsize=9)
            ax.axhline(1.0, color="k", lw=0.8)
            ax.grid(axis="y", alpha=0.3)
        axes[0].set_ylabel("policy / BFS success")
        axes[1].legend(fontsize=7, bbox_to_anchor=(1.02, 1.0), loc="upper left")
        fig.tight_layout()
        fig.savefig(out / "fig11_bfs_ratio.png", dpi=110)
        plt.close(fig)
    ratios = [(o, c["ratio"]) for o, c in results["classes"].items() if c["ratio"] is not None]
    if ratios:
        fig, ax = plt.subplots(figsize=(max(5.0, 0.5 * len(ratios) + 2), 4.0))
        bars = ax.bar([o for o, _ in ratios], [r for _, r in ratios], color="tab:gray")
        ax.bar_label(bars, fmt="%.2f", fontsize=6)  # a measured 0 is written, not blank
        hard, medium = CLASS_THRESHOLDS
        ax.axhline(hard, color="tab:red", ls="--", lw=1, label=f"hard ≤ {hard:g}")
        ax.axhline(medium, color="tab:orange", ls="--", lw=1, label=f"medium ≤ {medium:g} < easy")
        ax.set_ylabel("random / BFS success\nat step 2")
        ax.set_xlabel("object")
        ax.set_title("object difficulty (seed 001 §5.1)", fontsize=9)
        ax.legend(fontsize=7)
        ax.tick_params(axis="x", rotation=60, labelsize=7)
        fig.tight_layout()
        fig.savefig(out / "difficulty.png", dpi=110)
        plt.close(fig)


# --------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------
def _read_records(path: Path) -> dict[int, dict[str, Any]]:
    """A records file's poses (the last line of a pose wins; a torn last line, from a
    run that was killed while writing, is cut off the file)."""
    out: dict[int, dict[str, Any]] = {}
    if not path.is_file():
        return out
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        # cut the torn line off, or the next record appended would join it and be lost
        keep = data.rfind(b"\n") + 1
        with path.open("r+b") as f:
            f.truncate(keep)
        print(f"heapgrasp: cut a torn last record off {path}", file=sys.stderr)
        data = data[:keep]
    for line in data.decode().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        out[int(rec["pose"])] = rec
    return out


def _objects(
    args: argparse.Namespace, config: ViewsphereConfig
) -> tuple[list[Any], dict[str, str]]:
    """The benchmark's objects and the errors of those that cannot be used."""
    from heapgrasp.sim.objects import default_cache_dir
    from heapgrasp.sim.viewsphere_objects import stand_ins, user_objects

    errors: dict[str, str] = {}
    if args.object_dir is not None:
        objects = user_objects(
            args.object_dir,
            default_cache_dir(),
            on_bad=lambda name, problem: errors.__setitem__(name, problem),
        )
    else:
        objects = stand_ins(args.objects)
    usable = []
    for obj in objects:
        try:
            obj.check_size(config.object_half_xy, config.object_max_height)
        except ValueError as exc:
            errors[obj.name] = str(exc)
            continue
        usable.append(obj)
    return usable, errors


def _settings(args: argparse.Namespace, config: ViewsphereConfig) -> dict[str, Any]:
    return {
        "policies": list(args.policies),
        "objects": "object-dir" if args.object_dir is not None else list(args.objects),
        "object_dir": args.object_dir,
        "poses": args.poses,
        "seed": args.seed,
        "sensor": args.sensor,
        "execute": args.execute,
        "config": config.to_dict(),
        "weights": {
            model: {"path": path, "sha256": _sha256(path)} for model, path in args.weights_files
        },
    }


def _sha256(path: str) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def resolve_weights(policies: Sequence[str], given: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """The files of the learned ``policies``: ``given`` ``MODEL=FILE`` entries, else the
    shipped ones. ValueError naming a bad entry, a missing file or a learned policy
    without one; each file is opened and checked."""
    from heapgrasp.inference import OnnxNetwork
    from heapgrasp.planning.viewsphere_learned import shipped_policy

    chosen: dict[str, str] = {}
    for entry in given:
        model, sep, path = entry.partition("=")
        if not sep or model not in LEARNED or not path:
            raise ValueError(
                f"--weights wants MODEL=FILE with MODEL among {', '.join(LEARNED)}; got {entry!r}"
            )
        chosen[model] = str(Path(path).expanduser().absolute())
    out = []
    for model in (p for p in policies if p in LEARNED):
        if model not in chosen:
            shipped = shipped_policy(model)
            if shipped is None:
                raise ValueError(
                    f"no {model} policy ships with this install: train one (heapgrasp train "
                    f"viewsphere-policy --kind {model}) and pass --weights {model}=FILE"
                )
            chosen[model] = str(shipped)
        network = OnnxNetwork(chosen[model], kind="viewsphere-policy", threads=1)
        if network.hparams.get("model") != model:
            raise ValueError(
                f"{chosen[model]} holds a {network.hparams.get('model')} policy, not {model}"
            )
        out.append((model, chosen[model]))
    return tuple(out)


def _tasks(
    objects: Sequence[Any], args: argparse.Namespace, config: ViewsphereConfig, out: Path
) -> tuple[list[PoseTask], dict[str, dict[int, dict[str, Any]]]]:
    from heapgrasp.sim.viewsphere_protocol import protocol_yaws

    done: dict[str, dict[int, dict[str, Any]]] = {}
    tasks = []
    for obj in objects:
        done[obj.name] = _read_records(out / "records" / f"{obj.name}.jsonl")
        yaws = protocol_yaws(obj.yaw_range, args.poses)
        for i, yaw in enumerate(yaws):
            if i in done[obj.name]:
                continue
            tasks.append(
                PoseTask(
                    obj.name,
                    obj.meshes,
                    i,
                    round(float(np.degrees(yaw)), 6),
                    tuple(args.policies),
                    config.to_dict(),
                    args.seed,
                    args.sensor,
                    args.execute,
                    tuple(args.weights_files),
                )
            )
    return tasks, done


def _init_worker() -> None:
    from heapgrasp.loop.workers import init_worker

    init_worker(int(os.environ.get("HEAPGRASP_NUM_THREADS", "1")))


def _safe_pose(task: PoseTask) -> dict[str, Any]:
    """:func:`run_pose`, an exception recorded in the pose's record."""
    try:
        return run_pose(task)
    except Exception as exc:  # one pose's failure must not lose the others
        return {"pose": task.pose, "yaw_deg": task.yaw_deg, "error": f"{type(exc).__name__}: {exc}"}


def _execute(
    tasks: Sequence[PoseTask],
    finish: Callable[[PoseTask, dict[str, Any]], None],
    *,
    workers: int,
    ray_address: str | None,
) -> None:
    """Runs the tasks here, on a process pool or on Ray; ``finish`` gets each result.
    A worker that dies (a native crash) breaks the pool: its unfinished tasks run again
    in a new pool, and a task that breaks two pools is recorded as failed."""
    if ray_address is not None:
        _execute_ray(tasks, finish, ray_address)
        return
    if workers == 1:
        for t in tasks:
            finish(t, _safe_pose(t))
        return
    crashes: dict[tuple[str, int], int] = {}
    pending = list(tasks)
    while pending:
        retry: list[PoseTask] = []
        ctx = get_context("spawn")
        with ProcessPoolExecutor(
            min(workers, len(pending)), mp_context=ctx, initializer=_init_worker
        ) as pool:
            futures: dict[Future[dict[str, Any]], PoseTask] = {
                pool.submit(_safe_pose, t): t for t in pending
            }
            remaining = set(futures)
            while remaining:
                finished, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for fut in finished:
                    t = futures[fut]
                    try:
                        finish(t, fut.result())
                    except BrokenProcessPool:
                        key = (t.object_name, t.pose)
                        crashes[key] = crashes.get(key, 0) + 1
                        if crashes[key] >= 2:
                            finish(
                                t,
                                {
                                    "pose": t.pose,
                                    "yaw_deg": t.yaw_deg,
                                    "error": "the worker process died (a native crash)",
                                },
                            )
                        else:
                            retry.append(t)
        pending = retry


def _execute_ray(
    tasks: Sequence[PoseTask],
    finish: Callable[[PoseTask, dict[str, Any]], None],
    address: str,
) -> None:
    from heapgrasp.data.shards import ray_map

    for k, result, error in ray_map(_safe_pose, [(t,) for t in tasks], address):
        t = tasks[k]
        if error is not None:
            result = {"pose": t.pose, "yaw_deg": t.yaw_deg, "error": f"{error}"}
        finish(t, result)


def run_bench(args: argparse.Namespace) -> dict[str, Any]:
    """Runs (or continues) the benchmark in ``args.out``; returns ``results.json``."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    config = ViewsphereConfig.from_dict({**ViewsphereConfig().to_dict(), **parse_sets(args.set)})
    args.weights_files = resolve_weights(args.policies, args.weights)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / "records").mkdir(exist_ok=True)
    settings = _settings(args, config)
    settings_file = out / "settings.json"
    if settings_file.is_file():
        before = json.loads(settings_file.read_text())
        if before != json.loads(json.dumps(settings)):
            changed = sorted(k for k in settings if before.get(k) != settings[k])
            raise ValueError(
                f"{out} holds a run with other settings ({', '.join(changed)}); "
                "rerun with those settings to continue it, or choose another --out"
            )
    write_json(settings_file, settings)
    objects, errors = _objects(args, config)
    for name, problem in errors.items():
        print(f"heapgrasp: skipping object {name}: {problem}", file=sys.stderr)
    tasks, done = _tasks(objects, args, config, out)
    records = {name: dict(poses) for name, poses in done.items()}
    total = sum(args.poses for _ in objects)
    if tasks and not args.quiet:
        print(_duration_note(len(tasks), len(args.policies), args.workers), file=sys.stderr)
    bar = tqdm(
        total=total,
        initial=total - len(tasks),
        unit="pose",
        desc="viewsphere",
        disable=args.quiet,
        file=sys.stderr,
    )
    pose_errors: dict[str, list[str]] = {}
    last_write = [0.0]

    def write_results() -> dict[str, Any]:
        good = {
            name: [r for r in recs.values() if "error" not in r] for name, recs in records.items()
        }
        errs = dict(errors)
        for name, msgs in pose_errors.items():
            errs[name] = f"{len(msgs)} pose(s) failed; first: {msgs[0]}"
        results = summarize(settings, good, errs)
        write_json(out / "results.json", results)
        return results

    def finish(task: PoseTask, record: dict[str, Any]) -> None:
        if "error" in record:
            pose_errors.setdefault(task.object_name, []).append(
                f"pose {task.pose}: {record['error']}"
            )
        else:
            with (out / "records" / f"{task.object_name}.jsonl").open("a") as f:
                f.write(json.dumps(record) + "\n")
            records[task.object_name][task.pose] = record
        bar.update(1)
        if time.monotonic() - last_write[0] > 30.0:
            write_results()
            last_write[0] = time.monotonic()

    try:
        _execute(tasks, finish, workers=args.workers, ray_address=args.ray)
    finally:
        bar.close()
        results = write_results()
        (out / "table.md").write_text(markdown_table(results))
    if not args.no_figures:
        figures(results, out)
    write_summary(
        out,
        markdown_table(results),
        [
            ("fig10_success.png", "success against steps per object (the paper's Fig. 10)"),
            ("fig11_bfs_ratio.png", "policy / BFS success per class (Fig. 11)"),
            ("difficulty.png", "each object's difficulty"),
        ],
    )
    return results


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Registers ``heapgrasp bench viewsphere``."""
    from heapgrasp.sim.viewsphere_objects import TEST_OBJECTS, TRAIN_OBJECTS

    p = subparsers.add_parser(
        "viewsphere",
        help="seed 001's active-vision benchmark: policies on the viewsphere, success per step",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    some = comma_choices("policy", POLICIES)
    p.add_argument(
        "--policies",
        type=lambda text: POLICIES if text.strip().lower() == "all" else some(text),
        default=POLICIES,
        help=f"comma-separated policies among {', '.join(POLICIES)}, or all (the default)",
    )
    p.add_argument(
        "--objects",
        type=comma_choices("object", (*TEST_OBJECTS, *TRAIN_OBJECTS)),
        default=tuple(TEST_OBJECTS),
        metavar="NAMES",
        help="comma-separated stand-in objects (default: the 12 test objects: "
        + ", ".join(TEST_OBJECTS)
        + "; training shapes: "
        + ", ".join(TRAIN_OBJECTS)
        + ")",
    )
    p.add_argument(
        "--object-dir",
        metavar="DIR",
        type=lambda s: str(Path(s).expanduser().absolute()),
        help="your objects instead of the stand-ins: each subfolder of DIR holds a "
        "PyBullet object (model.urdf with its visual and collision meshes, in metres), "
        "or DIR holds mesh files. An object named like a protocol object (e.g. "
        "003_cracker_box) takes the protocol's resting pose and yaw range; any other "
        "rests in its most stable pose, with yaws over 0-359 degrees. An object that "
        "cannot be used is reported and skipped",
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
        + "; from heapgrasp train viewsphere-policy)",
    )
    p.add_argument("--no-figures", action="store_true", help="skip the plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=command)
    return p


#: CPU seconds one pose took for one policy in the full protocol's run (12 objects × 100
#: poses × 11 policies in 43 min on 2 workers: docs/benchmarks.md).
SECONDS_PER_POSE_POLICY = 43 * 60 * 2 / (12 * 100 * 11)


def _duration_note(poses: int, policies: int, workers: int) -> str:
    """What a run is about to do and roughly how long it takes (from the full protocol's
    measured rate, :data:`SECONDS_PER_POSE_POLICY`)."""
    minutes = poses * policies * SECONDS_PER_POSE_POLICY / max(1, min(workers, poses)) / 60
    about = f"about {minutes:.0f} min" if minutes >= 1 else "under a minute"
    return (
        f"heapgrasp bench viewsphere: {poses} object pose(s) × {policies} policies to run, "
        f"{about} on {workers} worker(s) (the full protocol, 12 objects × 100 poses × "
        "11 policies, took 43 min on 2 cores; --poses and --policies run less)"
    )


def command(args: argparse.Namespace) -> int:
    """``heapgrasp bench viewsphere``."""
    if args.poses > 100:
        print(
            f"heapgrasp: error: --poses must be at most 100 (the protocol's lists), got "
            f"{args.poses}",
            file=sys.stderr,
        )
        return 2
    if args.out is None:
        args.out = Path("runs") / f"bench-viewsphere-{datetime.now():%Y%m%d-%H%M%S}"
    from heapgrasp.loop.records import RunDir, RunLockedError

    try:
        # one writer per --out: a second run with the same settings would redo the work
        rundir = RunDir(args.out).lock()
    except RunLockedError as exc:
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    try:
        results = run_bench(args)
    except (ImportError, ValueError, FileNotFoundError) as exc:  # refused: a missing extra,
        print(f"heapgrasp: error: {exc}", file=sys.stderr)  # other settings, a bad file
        return 2
    finally:
        rundir.unlock()
    print(markdown_table(results))
    print(f"results: {args.out / 'results.json'}", file=sys.stderr)
    return 1 if results["errors"] else 0
