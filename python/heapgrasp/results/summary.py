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
from heapgrasp.loop.methods import method_of
from heapgrasp.loop.metrics import Phase, aggregate
from heapgrasp.results.stats import success_interval

__all__ = ["format_summary", "leftover_summary", "method_label", "summarize"]


def method_label(config: RunConfig) -> str:
    """A run's method as one line: the method, its views, its grasps and critic."""
    grasps = f"{config.grasp_planner_in_use} grasps"
    critic = config.critic
    if critic == "default":
        grasps += ", critic"
    elif critic is not None:
        grasps += f", critic {Path(critic).name}"
    method = method_of(config)
    if method.view_planner is not None:
        return f"{method.name} ({method.view_planner} views, {grasps})"
    return f"{method.name} ({grasps})"


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    if not values:
        return {"mean": None, "std": None}
    a = np.asarray(values, dtype=np.float64)
    return {"mean": float(a.mean()), "std": float(a.std())}


#: A leftover this close to another object (m) counts as touching it, this close to the
#: scene cube's side border (m) as at the border.
TOUCHING_M = 0.005
NEAR_BORDER_M = 0.03


def _reference(phases: Sequence[dict[str, Any]]) -> dict[str, Any] | None:
    refs = [p["reference_grid"] for p in phases if p.get("reference_grid")]
    if not refs:
        return None
    return {
        "phases": len(refs),
        "mse_percent": _stats([float(r["mse_percent"]) for r in refs]),
        "iou": _stats([float(r["iou"]) for r in refs if r.get("iou") is not None]),
    }


def leftover_summary(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Where the objects of finished scene records went: removed, knocked out of the
    workspace (the phases' ``knocked_out``), left on the table, and of those left how
    many the hand could have taken on their true meshes (the records' ``leftovers``,
    :mod:`heapgrasp.sim.leftovers`; a real run has none, and its counts of the left are
    None). ``removal_ceiling``: (removed + graspable leftovers) / objects."""
    total = sum(int(r["objects_total"]) for r in records)
    removed = sum(p["outcome"] == "success" for r in records for p in r["phases"])
    knocked = sum(len(p.get("knocked_out") or {}) for r in records for p in r["phases"])
    out: dict[str, Any] = {
        "objects_total": total,
        "objects_removed": removed,
        "removal_rate": removed / total if total else None,
        "objects_knocked_out": knocked,
        "objects_left": None,
        "leftovers_graspable": None,
        "graspable_left_rate": None,
        "removal_ceiling": None,
    }
    failed = [r["scene"] for r in records if "leftovers_error" in r]
    if failed:  # the counts of the left would hide those scenes' objects
        out["leftover_analysis_failed"] = failed
    if not records or not all("leftovers" in r for r in records):
        return out
    left = [o for r in records for o in r["leftovers"]]
    graspable = sum(bool(o["graspable"]) for o in left)
    out.update(
        objects_left=len(left),
        leftovers_graspable=graspable,
        graspable_left_rate=graspable / total if total else None,
        removal_ceiling=(removed + graspable) / total if total else None,
        leftovers={
            "lying": sum(not o["upright"] for o in left),
            "touching": sum(
                o["neighbour_m"] is not None and o["neighbour_m"] <= TOUCHING_M for o in left
            ),
            "near_border": sum(o["border_m"] < NEAR_BORDER_M for o in left),
            "by_category": dict(sorted(Counter(o["category"] for o in left).items())),
            "graspable_by_category": dict(
                sorted(Counter(o["category"] for o in left if o["graspable"]).items())
            ),
            "ungraspable_by_name": dict(
                sorted(Counter(o["name"] for o in left if not o["graspable"]).items())
            ),
        },
    )
    return out


def _fine_width(phases: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Phases that would have ended with no candidate and planned once more at the finer
    width (``RunConfig.fine_width``), how many found a grasp there and how many of those
    held, also by the voxel of the pass that found it (``"3.75 mm"``: found, held)."""
    used = [p for p in phases if p.get("fine_width")]
    found = [p for p in used if p["fine_width"].get("found")]
    by_voxel: dict[str, list[int]] = {}
    for p in found:
        key = f"{1000 * float(p['fine_width'].get('voxel_m', 0.0)):g} mm"
        tally = by_voxel.setdefault(key, [0, 0])
        tally[0] += 1
        tally[1] += p.get("outcome") == "success"
    return {
        "phases": len(used),
        "found": len(found),
        "held": sum(1 for p in found if p.get("outcome") == "success"),
        "by_voxel": by_voxel,
    }


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
    grasp_calls = (
        [
            float(w["grasp_planning_s"])
            for p in phase_dicts
            for w in p.get("waypoints", [])
            if w.get("grasp_candidates") is not None and w.get("grasp_planning_s") is not None
        ]
        + [
            float(p["final_planning_s"])
            for p in phase_dicts
            if p.get("final_planning_s") is not None and p.get("final_replanned", True)
        ]
        + [  # the final grids of the looks that found nothing and looked again
            float(look["previous_look"]["final_planning_s"])
            for p in phase_dicts
            for look in p.get("looked_again") or []
            if look.get("previous_look", {}).get("final_replanned")
        ]
    )
    per_group: dict[str, Any] = {}
    for group in sorted({r["category"] for r in done}):
        sel = [r for r in done if r["category"] == group]
        per_group[group] = aggregate(
            [Phase.from_dict(p) for r in sel for p in r["phases"]],
            sum(int(r["objects_total"]) for r in sel),
        )
        per_group[group].pop("per_category", None)
        per_group[group]["objects"] = leftover_summary(sel)
    n, k = metrics["grasps_attempted"], metrics["grasps_succeeded"]
    return {
        "method": config.method,
        "label": method_label(config),
        "view_planner": method_of(config).view_planner,
        "grasp_planner": config.grasp_planner_in_use,
        **metrics,
        # 95 % Wilson interval of the success rate, in percent (heapgrasp.results.stats).
        "grasp_success_ci95": [100 * x for x in success_interval(k, n)] if n else None,
        "per_scene_group": per_group,
        # removed, knocked out, left, and the leftovers the hand could have taken
        "objects": leftover_summary(done),
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
        # Phases that found no candidate at first and looked again (RunConfig.look_again),
        # and how many of those then found one.
        "looked_again": {
            "phases": sum(1 for p in phase_dicts if p.get("looked_again")),
            "found": sum(
                1 for p in phase_dicts if p.get("looked_again") and p["looked_again"][-1]["found"]
            ),
        },
        # Phases that would have ended with no candidate and planned once more at the
        # finer width (RunConfig.fine_width), how many found a grasp there, and how many
        # of those held.
        "fine_width": _fine_width(phase_dicts),
        # With pixel-flip noise: Ŝ≥λ against the noise-free grid of the same frames at the
        # end of each phase (Table V), None without noise.
        "reference_grid": _reference(phase_dicts),
        "config": config.to_dict(),
        "phases": phase_dicts,
    }


def _fmt(stat: dict[str, float | None], digits: int = 2) -> str:
    if stat.get("mean") is None:
        return "–"
    return f"{stat['mean']:.{digits}f} ± {stat['std']:.{digits}f}"


def format_summary(summary: dict[str, Any]) -> str:
    """A plain-text table of a :func:`summarize` result (overall and per scene group)."""
    rows = [("overall", summary), *list(summary.get("per_scene_group", {}).items())]
    head = (
        f"{'scenes':<12} {'success (%)':>22} {'removed':>9} {'trajectory (m)':>15} "
        f"{'shortest ratio (%)':>19} {'exec time (s)':>14}"
    )
    lines = [summary.get("label", summary["method"]), head, "-" * len(head)]
    for name, s in rows:
        rate = s.get("grasp_success_rate")
        succ = (
            "–"
            if rate is None
            else f"{100 * rate:.1f} ({s['grasps_succeeded']}/{s['grasps_attempted']})"
        )
        removed = f"{s['objects_removed']}/{s.get('objects_total', '?')}"
        lines.append(
            f"{name:<12} {succ:>22} {removed:>9} {_fmt(s['trajectory_length_m']):>15} "
            f"{_fmt(s['shortest_trajectory_ratio'], 0):>19} {_fmt(s['execution_time_s']):>14}"
        )
    objects = summary.get("objects") or {}
    if objects.get("objects_left") is not None and objects.get("objects_total"):
        total = objects["objects_total"]
        lines.append(
            f"objects: {objects['objects_removed']} removed, {objects['objects_left']} left "
            f"({objects['leftovers_graspable']} of them graspable on their true meshes), "
            f"{objects['objects_knocked_out']} knocked out of the workspace, of {total}; "
            f"removal ceiling {100 * objects['removal_ceiling']:.1f} %"
        )
    looked = summary.get("looked_again") or {}
    if looked.get("phases"):
        lines.append(
            f"looked again: {looked['phases']} phase(s) found no grasp at first; "
            f"{looked['found']} found one on a look again"
        )
    fine = summary.get("fine_width") or {}
    if fine.get("phases"):
        per = ", ".join(
            f"{found}/{held} at {voxel}"
            for voxel, (found, held) in fine.get("by_voxel", {}).items()
        )
        lines.append(
            f"finer width: {fine['phases']} phase(s) would have ended with no grasp; "
            f"{fine['found']} found one measured finer, {fine['held']} of them held"
            + (f" (found/held: {per})" if per else "")
        )
    ref = summary.get("reference_grid")
    if ref:
        lines.append(
            f"Ŝ≥λ against the noise-free grid (Table V): MSE {_fmt(ref['mse_percent'])} % "
            f"of the voxels, IoU {_fmt(ref['iou'])}"
        )
    if summary.get("grasp_success_ci95"):
        lo, hi = summary["grasp_success_ci95"]
        lines.append(f"success rate, 95 % interval (Wilson): [{lo:.1f}, {hi:.1f}] %")
    lat = summary.get("planning_latency_per_waypoint_s", {})
    wall = summary.get("wall_time_per_scene_s", {})
    grasp = summary.get("grasp_planning_per_call_s", {})
    lines.append(
        f"planning latency per waypoint: {_fmt(lat, 3)} s; grasp planning per call: "
        f"{_fmt(grasp, 3)} s; wall-clock per scene: {_fmt(wall, 1)} s; stop reasons: "
        f"{summary.get('stop_reasons')}"
    )
    if summary.get("early_stops"):
        lines.append(
            f"view waypoints per phase: {_fmt(summary['view_waypoints_per_phase'], 2)} "
            f"({summary['early_stops']} of {len(summary.get('phases', []))} phases stopped "
            "viewing early)"
        )
    placed, asked = summary.get("objects_total"), summary.get("objects_requested")
    if isinstance(placed, int) and isinstance(asked, int) and placed < asked:
        lines.append(f"objects placed: {placed} of the {asked} asked for (a pile drops some)")
    if summary.get("scenes_failed"):
        lines.append(f"FAILED scenes: {summary['scenes_failed']}")
    return "\n".join(lines)
