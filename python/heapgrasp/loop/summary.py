"""``results.json``: the §VI-D metrics of a run's finished scene records.

Shared by simulated runs (:mod:`heapgrasp.run`) and real ones (:mod:`heapgrasp.real`),
which write the same files; nothing here needs the simulator.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.loop.config import RunConfig
from heapgrasp.loop.metrics import Phase, aggregate
from heapgrasp.loop.stats import success_interval

__all__ = ["method_label", "summarize"]


def method_label(config: RunConfig) -> str:
    """A run's method as one line: the method, its views, its grasps and critic."""
    grasps = f"{config.grasp_planner} grasps"
    critic = config.critic
    if critic == "default":
        grasps += ", critic"
    elif critic is not None:
        grasps += f", critic {Path(critic).name}"
    if config.method == "heapgrasp":
        return f"heapgrasp ({config.view_planner} views, {grasps})"
    return f"{config.method} ({grasps})"


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    if not values:
        return {"mean": None, "std": None}
    a = np.asarray(values, dtype=np.float64)
    return {"mean": float(a.mean()), "std": float(a.std())}


def summarize(config: RunConfig, records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """``results.json``: the §VI-D metrics over every phase of every finished scene."""
    done = sorted((r for r in records if "error" not in r), key=lambda r: int(r["scene"]))
    failed = [r for r in records if "error" in r]
    phases: list[Phase] = []
    phase_dicts: list[dict[str, Any]] = []
    for r in done:
        for k, p in enumerate(r["phases"]):
            phases.append(Phase.from_dict(p))
            phase_dicts.append({"scene": r["scene"], "phase": k, **p})
    metrics = aggregate(phases, sum(int(r["objects_total"]) for r in done))
    latencies = [
        w["latency_s"]
        for p in phase_dicts
        for w in p.get("waypoints", [])
        if w.get("latency_s") is not None
    ]
    # One grasp-planning call: the grid to eq. 15's candidates (and the critic's scores),
    # at a waypoint where grasps were planned or at the end of a phase's viewing where the
    # final grid was planned again.
    grasp_calls = [
        float(w["grasp_planning_s"])
        for p in phase_dicts
        for w in p.get("waypoints", [])
        if w.get("grasp_candidates") is not None and w.get("grasp_planning_s") is not None
    ] + [
        float(p["final_planning_s"])
        for p in phase_dicts
        if p.get("final_planning_s") is not None and p.get("final_replanned", True)
    ]
    per_group: dict[str, Any] = {}
    for group in sorted({r["category"] for r in done}):
        sel = [r for r in done if r["category"] == group]
        per_group[group] = aggregate(
            [Phase.from_dict(p) for r in sel for p in r["phases"]],
            sum(int(r["objects_total"]) for r in sel),
        )
        per_group[group].pop("per_category", None)
    n, k = metrics["grasps_attempted"], metrics["grasps_succeeded"]
    return {
        "method": config.method,
        "label": method_label(config),
        "view_planner": config.view_planner if config.method == "heapgrasp" else None,
        "grasp_planner": config.grasp_planner,
        **metrics,
        # 95 % Wilson interval of the success rate, in percent (heapgrasp.loop.stats).
        "grasp_success_ci95": [100 * x for x in success_interval(k, n)] if n else None,
        "per_scene_group": per_group,
        "scenes_completed": len(done),
        # the objects the scenes were drawn from (RunConfig.object_dir) and those placed
        "object_dir": config.object_dir,
        "objects_used": sorted(
            {o["name"] for r in done for o in r.get("world", {}).get("objects", [])}
        ),
        # objects asked for and placed (a pile may drop some off the table)
        "objects_requested": sum(int(r.get("objects_requested", config.objects)) for r in done),
        "scenes_failed": [{"scene": r["scene"], "error": r["error"]} for r in failed],
        "stop_reasons": dict(Counter(r["stop_reason"] for r in done)),
        "wall_time_per_scene_s": _stats([float(r["wall_time_s"]) for r in done]),
        "planning_latency_per_waypoint_s": _stats(latencies),
        "grasp_planning_per_call_s": _stats(grasp_calls),
        "view_waypoints_per_phase": _stats([len(p.get("waypoints", [])) for p in phase_dicts]),
        # Phases whose viewing ended before L waypoints (RunConfig.stop_below).
        "early_stops": sum(1 for p in phase_dicts if p.get("stopped_early")),
        "config": config.to_dict(),
        "phases": phase_dicts,
    }
