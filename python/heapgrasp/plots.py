"""Figures of the simulated runs (matplotlib, Agg backend).

* :func:`figure_paths` — Fig. 5 of HEAPGrasp: hand-eye camera paths in the x–y plane,
  the scene boundary dashed, the initial position a square, the grasp a cross;
* :func:`figure_grids` — Fig. 4: the measured grid of one phase per method, with its
  grasp candidates (green) and the chosen grasp (red);
* :func:`figure_run` — one run at a glance: the first phase's camera path, and where the
  objects of each scene group went (removed, knocked out, left graspable, left
  ungraspable).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["figure_paths", "figure_run", "write_run_page"]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figure_paths(
    summaries: dict[str, dict[str, Any]], path: Path, *, scene: int = 0, phase: int = 0
) -> None:
    """Camera paths (x–y) of one phase of one scene for every method (Fig. 5)."""
    plt = _pyplot()
    n = len(summaries)
    fig, axes = plt.subplots(1, n, figsize=(4 * n, 4), squeeze=False)
    for ax, (method, s) in zip(axes[0], summaries.items(), strict=True):
        size = float(s["config"]["cube_size"])
        ax.plot([0, size, size, 0, 0], [0, 0, size, size, 0], "k--", lw=1)
        rec = next(
            (p for p in s["phases"] if p["scene"] == scene and p["phase"] == phase),
            None,
        )
        _path_panel(ax, rec, size, method)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _path_panel(ax: Any, rec: dict[str, Any] | None, size: float, title: str) -> None:
    """One phase's camera path in the x–y plane (Fig. 5's panel), with a legend."""
    ax.plot([0, size, size, 0, 0], [0, 0, size, size, 0], "k--", lw=1, label="scene cube")
    if rec is not None and rec["camera_path"]:
        xy = np.asarray(rec["camera_path"])[:, :2]
        ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:blue", lw=1.5, label="camera path")
        ax.plot(xy[0, 0], xy[0, 1], "s", color="tab:blue", ms=8, label="start p⁰")
        if rec.get("grasp_position") is not None:
            g = rec["grasp_position"]
            ax.plot(g[0], g[1], "x", color="tab:red", ms=10, mew=2, label="grasp")
        length = rec.get("trajectory_length_m", 0.0)
        ax.set_title(f"{title}: {length:.2f} m ({rec['outcome']})")
    else:
        ax.set_title(f"{title}: no phase")
    ax.set_aspect("equal")
    ax.set_xlim(-0.3, size + 0.3)
    ax.set_ylim(-0.3, size + 0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7, loc="upper right")


def write_run_page(summary: dict[str, Any], text: str, out: Path) -> list[Path]:
    """``out/summary.md`` (the printed table) and ``out/summary.png``
    (:func:`heapgrasp.plots.figure_run`); returns the files written."""
    md = out / "summary.md"
    md.write_text(
        f"# {summary.get('label', summary['method'])}\n\n```\n{text}\n```\n\n"
        "![the first phase's camera path, and where the objects went](summary.png)\n\n"
        "Every number: `results.json`; every scene: `scenes.jsonl`.\n"
    )
    png = out / "summary.png"
    figure_run(summary, png)
    return [md, png]


def figure_run(summary: dict[str, Any], path: Path) -> None:
    """A finished run at a glance (``run``'s ``summary.png``): the camera path of the first
    scene's first phase, and per scene group where the objects went."""
    plt = _pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    size = float(summary["config"]["cube_size"])
    first = min(
        (p for p in summary.get("phases", [])),
        key=lambda p: (p["scene"], p["phase"]),
        default=None,
    )
    _path_panel(left, first, size, f"scene {first['scene'] if first else '–'}, phase 0")
    groups = {"all": summary, **summary.get("per_scene_group", {})}
    names = list(groups)

    def counts(o: dict[str, Any]) -> dict[str, float]:
        left, graspable = o.get("objects_left") or 0, o.get("leftovers_graspable") or 0
        removed = float(o.get("objects_removed", 0))
        knocked = float(o.get("objects_knocked_out", 0))
        # a robot cannot count what it left: the rest of the objects placed
        rest = 0.0
        if o.get("objects_left") is None:
            rest = max(0.0, float(o.get("objects_total") or 0) - removed - knocked)
        return {
            "removed": removed,
            "knocked out": knocked,
            "left, graspable": float(graspable),
            "left, ungraspable": float(left - graspable),
            "not removed (a robot's run: not analysed)": rest,
        }

    colours = {
        "removed": "tab:green",
        "knocked out": "tab:orange",
        "left, graspable": "tab:red",
        "left, ungraspable": "tab:gray",
        "not removed (a robot's run: not analysed)": "lightgray",
    }
    per_group = [counts(g.get("objects") or {}) for g in groups.values()]
    bottom = np.zeros(len(names))
    for label, colour in colours.items():
        values = [c[label] for c in per_group]
        if label.startswith("not removed") and not any(values):
            continue  # a simulated run accounts for every object
        right.bar(names, values, bottom=bottom, color=colour, label=label)
        bottom += np.asarray(values)
    right.set_ylabel("objects")
    right.set_xlabel("scene group")
    rate = summary.get("grasp_success_rate")
    right.set_title(
        "where the objects went" + ("" if rate is None else f" (grasp success {100 * rate:.1f} %)")
    )
    right.legend(fontsize=8)
    fig.suptitle(summary.get("label", summary.get("method", "")))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
