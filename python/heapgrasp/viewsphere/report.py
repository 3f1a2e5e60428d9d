"""The viewsphere benchmark's results: per-policy summaries, the object classes, Fig. 10
and 11, Table 1 and the markdown table (Natarajan et al. §5.1).

Everything here reads the per-pose records :func:`heapgrasp.viewsphere.episode.run_pose`
returns; nothing runs a policy.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.viewsphere.episode import VIEWPOINT_POLICIES

__all__ = ["CLASS_THRESHOLDS", "classify", "figures", "markdown_table", "summarize"]

#: Random's share of BFS's success at step 2: at most the first is hard, at most the
#: second medium, else easy (Natarajan et al. §5.1).
CLASS_THRESHOLDS = (0.40, 0.80)


def _policy_summary(records: Sequence[Mapping[str, Any]], name: str, steps: int) -> dict[str, Any]:
    entries = [r["policies"][name] for r in records if name in r.get("policies", {})]
    n = len(entries)
    found = np.array([e["found"] for e in entries], dtype=bool)
    taken = np.array([e["steps"] if e["found"] else steps for e in entries], dtype=np.float64)
    success = [float(np.mean(found & (taken <= s))) if n else 0.0 for s in range(steps + 1)]
    executed = [e["executed"] for e in entries if e.get("executed") is not None]
    held = np.array([e.get("executed") == "success" for e in entries], dtype=bool)
    decisions = [t for e in entries for t in e.get("decisions_s", [])]
    return {
        "poses_run": n,
        "success_at_step": success,
        # Found by the step and held when executed (None unless every found grasp was).
        "held_at_step": (
            [float(np.mean(found & held & (taken <= s))) for s in range(steps + 1)]
            if n and len(executed) == int(found.sum())
            else None
        ),
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
    """An object's class from random's and BFS's success at step 2 (Natarajan et al. §5.1)."""
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


#: Natarajan et al.'s Table 1 average reductions of the 3D heuristic over information gain (%):
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
        "# The viewsphere benchmark (Natarajan et al.)",
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
            ax.set_xlabel("object class (Natarajan et al. §5.1)")
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
        ax.set_title("object difficulty (Natarajan et al. §5.1)", fontsize=9)
        ax.legend(fontsize=7)
        ax.tick_params(axis="x", rotation=60, labelsize=7)
        fig.tight_layout()
        fig.savefig(out / "difficulty.png", dpi=110)
        plt.close(fig)


# --------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------
