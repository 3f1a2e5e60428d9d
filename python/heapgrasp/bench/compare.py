"""``heapgrasp bench compare A B``: two finished runs on the same scenes, side by side.

``A`` and ``B`` are run directories holding ``scenes.jsonl`` (``heapgrasp run --out``,
or one method's folder of ``heapgrasp bench sim``), e.g. a method before and after a
change, or two methods. Scenes are matched by their seed, and a seed must hold the same
scene in both (objects, category, layout: else it refuses, unless
``--different-scenes``). Prints, for each run, the
success rate with its 95 % Wilson interval, the objects removed and the mean trajectory;
then A's success rate minus B's with a paired bootstrap interval over the common scenes
(:mod:`heapgrasp.results.stats`), and A's mean trajectory as a share of B's. ``--json FILE``
also writes the numbers.

``--pool A2 B2`` (repeatable) adds another pair of runs on other scenes, e.g. the same
two methods on held-out seeds: A's runs are pooled, B's too, and the comparison is over
all their scenes. A seed may appear in only one run of each side.

``--breakdown`` adds, for each side, where its grasps fail: success and failure outcomes
per band of the executed grasp's score, per way the viewing ended, per count of
candidates the grasp was chosen from and per count of objects left on the table, and
the collisions by what the hand touched, where and with which part
(:mod:`heapgrasp.bench.breakdown`); ``--json`` always holds it.

Examples::

    heapgrasp bench compare runs/after/heapgrasp runs/before/heapgrasp
    heapgrasp bench compare runs/top/heapgrasp runs/top/no-vp \
        --pool runs/heldout/heapgrasp runs/heldout/no-vp
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.bench.breakdown import breakdown, format_breakdown
from heapgrasp.results.stats import (
    format_interval,
    paired_success_difference,
    scene_counts,
    success_interval,
)

__all__ = ["CompareError", "compare_runs", "format_comparison", "scene_signature"]


class CompareError(ValueError):
    """A run directory cannot be compared (missing, empty, or no scene in common)."""


def scene_signature(record: dict[str, Any]) -> dict[str, Any]:
    """What makes a scene record's scene the one it is, beyond its seed: the scene group,
    the objects asked for, the layout and workspace, and the objects placed (name and
    optical category, by id) — what two runs must share for their scenes to be paired."""
    world = record.get("world") or {}
    return {
        "group": record.get("category"),
        "objects_requested": record.get("objects_requested"),
        "layout": world.get("layout"),
        "workspace": world.get("workspace"),
        "objects": [
            [o.get("id"), o.get("name"), o.get("category")] for o in world.get("objects", [])
        ],
    }


def _phases(
    run_dirs: Sequence[Path],
) -> tuple[list[dict[str, Any]], list[float], list[dict[str, Any]], dict[int, dict[str, Any]]]:
    """Outcomes keyed by scene seed, the trajectory of every attempted grasp, the phase
    records themselves and each seed's :func:`scene_signature`, over one or more runs
    whose seeds do not overlap."""
    from heapgrasp.run import SCENES_FILE, load_records

    phases, lengths, records_out = [], [], []
    signatures: dict[int, dict[str, Any]] = {}
    owner: dict[int, Path] = {}
    seen: set[Path] = set()
    for run_dir in run_dirs:
        if not run_dir.is_dir():
            raise CompareError(f"{run_dir}: not a directory")
        if run_dir.resolve() in seen:
            raise CompareError(f"{run_dir}: given twice on one side")
        seen.add(run_dir.resolve())
        records = [r for r in load_records(run_dir) if "error" not in r]
        if not records:
            raise CompareError(f"{run_dir}: no finished scene in {run_dir / SCENES_FILE}")
        for r in records:
            scene = int(r.get("seed", r["scene"]))
            first = owner.setdefault(scene, run_dir)
            if first != run_dir:
                raise CompareError(
                    f"seed {scene} is in both {first} and {run_dir}: pool runs on other scenes"
                )
            signatures[scene] = scene_signature(r)
            left = r.get("objects_total")
            for p in r["phases"]:
                phases.append({"scene": scene, "outcome": p["outcome"]})
                # The objects on the table when the phase began (for the breakdown).
                records_out.append({**p, "objects_left": left} if isinstance(left, int) else p)
                if isinstance(left, int):
                    left -= int(p["outcome"] == "success") + len(p.get("knocked_out") or {})
                if p.get("grasp_position") is not None and p.get("trajectory_length_m") is not None:
                    lengths.append(float(p["trajectory_length_m"]))
    return phases, lengths, records_out, signatures


def _dirs(runs: Path | str | Sequence[Path | str]) -> list[Path]:
    if isinstance(runs, Path | str):
        return [Path(runs)]
    if not runs:
        raise CompareError("no run directory given")
    return [Path(r) for r in runs]


def compare_runs(
    a: Path | str | Sequence[Path | str],
    b: Path | str | Sequence[Path | str],
    *,
    level: float = 0.95,
    resamples: int = 10_000,
    seed: int = 0,
    different_scenes: bool = False,
) -> dict[str, Any]:
    """The comparison of run directories ``a`` and ``b`` (see the module docstring); each
    may be a sequence of runs on disjoint seeds, pooled.

    Scenes are paired by seed, and a seed must hold the same scene in both
    (:func:`scene_signature`: scene group, objects asked for, layout, the objects placed):
    runs with other scene settings raise :class:`CompareError` naming the first seeds
    that differ and how, unless ``different_scenes``, which compares them anyway and
    lists those seeds under ``different_scenes`` in the result."""
    runs: dict[str, Any] = {}
    counts = {}
    signatures: dict[str, dict[int, dict[str, Any]]] = {}
    for name, given in (("a", a), ("b", b)):
        paths = _dirs(given)
        phases, lengths, records, signatures[name] = _phases(paths)
        per_scene = scene_counts(phases)
        counts[name] = per_scene
        k = sum(c[0] for c in per_scene.values())
        n = sum(c[1] for c in per_scene.values())
        runs[name] = {
            "path": " + ".join(str(p) for p in paths),
            "paths": [str(p) for p in paths],
            "scenes": len(per_scene),
            "grasps_succeeded": k,
            "grasps_attempted": n,
            "grasp_success_rate": k / n if n else None,
            "grasp_success_ci": [100 * x for x in success_interval(k, n, level)] if n else None,
            "trajectory_length_m": float(np.mean(lengths)) if lengths else None,
            "breakdown": breakdown(records),
        }
    common = set(counts["a"]) & set(counts["b"])
    if not common:
        raise CompareError(
            f"{runs['a']['path']} and {runs['b']['path']} have no scene (seed) in common"
        )
    differ = sorted(s for s in common if signatures["a"][s] != signatures["b"][s])
    if differ and not different_scenes:
        first = differ[0]
        sa, sb = signatures["a"][first], signatures["b"][first]
        what = ", ".join(f"{k}: {sa[k]!r} in A, {sb[k]!r} in B" for k in sa if sa[k] != sb.get(k))
        raise CompareError(
            f"{len(differ)} of the {len(common)} common seeds hold different scenes in the "
            f"two runs (seed {first}: {what}); compare runs made with the same scene "
            "settings (objects, category, layout, object set), or pass --different-scenes "
            "to compare them anyway"
        )
    diff = paired_success_difference(
        counts["a"], counts["b"], level=level, resamples=resamples, seed=seed
    )
    ta, tb = runs["a"]["trajectory_length_m"], runs["b"]["trajectory_length_m"]
    return {
        **runs,
        "level": level,
        "success_difference": diff,
        "trajectory_ratio": ta / tb if ta is not None and tb else None,
        "different_scenes": differ,
    }


def format_comparison(c: dict[str, Any], *, details: bool = False) -> str:
    """The plain-text report of :func:`compare_runs`; ``details`` adds each run's
    :mod:`~heapgrasp.bench.breakdown` (success per score band and per viewing)."""
    pct = round(100 * c["level"])
    lines = [f"{'run':<4} {'scenes':>6} {'success (%)':>20} {f'{pct} % CI':>16} {'traj. (m)':>10}"]
    for name in ("a", "b"):
        r = c[name]
        rate = r["grasp_success_rate"]
        succ = (
            "–"
            if rate is None
            else f"{100 * rate:.1f} ({r['grasps_succeeded']}/{r['grasps_attempted']})"
        )
        ci = r["grasp_success_ci"]
        ci_s = "–" if ci is None else format_interval(ci[0], ci[1])
        traj = "–" if r["trajectory_length_m"] is None else f"{r['trajectory_length_m']:.3f}"
        lines.append(f"{name.upper():<4} {r['scenes']:>6} {succ:>20} {ci_s:>16} {traj:>10}")
    d = c["success_difference"]
    if d["difference"] is None:
        lines.append(f"A - B: – (no attempt on the {d['scenes']} common scenes)")
    else:
        lines.append(
            f"A - B: {d['difference']:+.1f} points, {pct} % interval "
            f"{format_interval(d['low'], d['high'])} (paired bootstrap over {d['scenes']} "
            "common scenes)"
        )
    if c["trajectory_ratio"] is not None:
        lines.append(f"trajectory A / B: {100 * c['trajectory_ratio']:.1f} %")
    if c.get("different_scenes"):
        lines.append(
            f"WARNING: {len(c['different_scenes'])} paired seed(s) hold different scenes in "
            "A and B (--different-scenes)"
        )
    lines.append(f"A: {c['a']['path']}\nB: {c['b']['path']}")
    if details:
        for name in ("a", "b"):
            lines.append("")
            lines.append(format_breakdown(name.upper(), c[name]["breakdown"]))
    return "\n".join(lines)


def command(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp bench compare``; returns the exit status."""
    try:
        c = compare_runs(
            [args.a, *(pair[0] for pair in args.pool)],
            [args.b, *(pair[1] for pair in args.pool)],
            level=args.level,
            resamples=args.resamples,
            different_scenes=args.different_scenes,
        )
    except ValueError as exc:  # CompareError, and bad --level / --resamples
        print(f"heapgrasp bench compare: {exc}", file=sys.stderr)
        return 2
    print(format_comparison(c, details=args.breakdown))
    if args.json is not None:
        args.json.write_text(json.dumps(c, indent=2))
    return 0
