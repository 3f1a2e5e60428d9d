"""Where a run's grasps fail: success per band of the executed grasp's score, and per
way the viewing ended (``heapgrasp bench compare --breakdown``).

A success rate says how often a method's grasps hold; this says *which* grasps do not.
Every attempted grasp of a run (a phase whose outcome is not ``no_candidate``) is
counted twice:

* by the band of its score (``target_grasp.score`` in the phase record: with the grasp
  critic, its probability of success; :data:`SCORE_BANDS`) — whether a method fails
  where its critic is sure, or executes more grasps the critic doubts;
* by how its viewing ended (:func:`viewing`): HEAPGrasp's early stop
  (``RunConfig.stop_below``) after k view waypoints, or every planned waypoint visited
  (the fixed-view methods always visit theirs);
* by how many candidates the grid it was chosen from offered (:func:`candidates`) — a
  lone candidate is often the last grasp a crowded hull leaves room for;
* by how many objects were left on the table (:func:`objects_left`, where the record
  says; ``heapgrasp bench compare`` adds it from the scene's earlier phases) — the
  first phase of a scene is its most cluttered.

Each cell holds the successes, the attempts, and the count of every failure outcome
(``empty``, ``collision``, …). The collisions are also counted by what the hand touched
and where (:func:`collision_kind`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = [
    "SCORE_BANDS",
    "breakdown",
    "candidates",
    "collision_kind",
    "format_breakdown",
    "objects_left",
    "score_band",
    "viewing",
]

SCORE_BANDS = (0.0, 0.7, 0.8, 0.9, 0.95, 1.0)
"""Edges of the score bands: ``[0, 0.7)``, …, ``[0.95, 1]`` (the last one closed)."""

UNKNOWN = "no score"
"""The band of a phase whose record holds no finite score of the executed grasp."""


def score_band(score: object) -> str:
    """The label of the band of :data:`SCORE_BANDS` that ``score`` falls in, or
    :data:`UNKNOWN` for a missing or non-finite score. Scores outside [0, 1] (the
    planner's own scale without a critic) fall in the first or the last band."""
    if isinstance(score, bool) or not isinstance(score, int | float) or not math.isfinite(score):
        return UNKNOWN
    *inner, (lo, hi) = itertools.pairwise(SCORE_BANDS)
    for a, b in inner:
        if score < b:
            return f"[{a:.2f}, {b:.2f})"
    return f"[{lo:.2f}, {hi:.2f}]"


def _band_order() -> list[str]:
    bands = [score_band(lo) for lo in SCORE_BANDS[:-1]]
    return [*bands, UNKNOWN]


def viewing(phase: Mapping[str, Any]) -> str:
    """How the phase's viewing ended: ``"stopped after k waypoint(s)"`` where HEAPGrasp's
    early stop ended it (``stopped_early``), else ``"all waypoints"``."""
    if phase.get("stopped_early"):
        k = len(phase.get("waypoints") or [])
        return f"stopped after {k} waypoint{'s' if k != 1 else ''}"
    return "all waypoints"


def candidates(phase: Mapping[str, Any]) -> str:
    """How many grasp candidates the grid the executed grasp was chosen from offered:
    ``"1 candidate"``, ``"2 candidates"``, ``"3+ candidates"`` (the early stop's count
    where the viewing stopped, else ``final_candidates``), or ``"not recorded"``."""
    stopped = phase.get("stopped_early")
    count = stopped.get("grasp_candidates") if isinstance(stopped, Mapping) else None
    if count is None:
        count = phase.get("final_candidates")
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        return "not recorded"
    return "1 candidate" if count == 1 else ("2 candidates" if count == 2 else "3+ candidates")


def objects_left(phase: Mapping[str, Any]) -> str:
    """How many objects were on the table when the phase began (``objects_left`` in the
    record): ``"5 objects"``, ``"1 object"``, or ``"not recorded"``."""
    n = phase.get("objects_left")
    if isinstance(n, bool) or not isinstance(n, int) or n < 0:
        return "not recorded"
    return f"{n} object{'s' if n != 1 else ''}"


def memory(phase: Mapping[str, Any]) -> str | None:
    """How a phase of a run with ``scene_memory`` began: ``"no memory yet"`` (a scene's
    first phase), ``"memory kept"`` or ``"memory dropped"`` (the first silhouettes
    showed something where the memory held free space); None for a run without it."""
    if "memory" not in phase:
        return None
    record = phase["memory"]
    if not isinstance(record, Mapping):
        return "no memory yet"
    return "memory kept" if record.get("kept") else "memory dropped"


def collision_kind(phase: Mapping[str, Any]) -> str:
    """What a collision touched, where, and with which part of the hand: ``"<stage>:
    <touched> (<parts>)"``, e.g. ``"approach: object+target (palm)"`` (the phase
    record's ``collision``, written since the hand reports its contacts; records from
    before the parts were recorded leave them out), or ``"not recorded"`` for records
    from before that."""
    record = phase.get("collision")
    if not isinstance(record, Mapping):
        return "not recorded"
    touched = record.get("touched") or []
    what = "+".join(str(t) for t in touched) if touched else "nothing"
    kind = f"{record.get('stage') or 'unknown'}: {what}"
    parts = record.get("parts")
    if parts:
        kind += f" ({'+'.join(str(p) for p in parts)})"
    return kind


def _cell() -> dict[str, Any]:
    return {"succeeded": 0, "attempted": 0, "outcomes": {}}


def _add(cell: dict[str, Any], outcome: str) -> None:
    cell["attempted"] += 1
    if outcome == "success":
        cell["succeeded"] += 1
    else:
        cell["outcomes"][outcome] = cell["outcomes"].get(outcome, 0) + 1


def _most_first(label: str) -> tuple[int, int]:
    """Sort key of :func:`objects_left`'s labels: most objects first, unrecorded last."""
    head = label.split(" ", 1)[0]
    return (0, -int(head)) if head.isdigit() else (1, 0)


def breakdown(phases: Iterable[Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """Success per score band, per viewing, per count of candidates and per count of
    objects left over the attempted grasps of ``phases`` (phase records of
    ``scenes.jsonl``): ``{"score": {band: cell}, "viewing": {kind: cell},
    "candidates": {count: cell}, "objects": {count: cell}, "collisions": {kind:
    count}}``, and ``"memory": {how the phase began: cell}`` (:func:`memory`) where
    some phase ran with ``scene_memory``; each cell ``{"succeeded", "attempted",
    "outcomes": {failure: count}}``, each collision kind from :func:`collision_kind`.
    Bands and kinds without an attempt are left out; bands come in ascending order,
    objects from the most.

    Raises ``ValueError`` for a phase without an ``outcome``.
    """
    by_score: dict[str, dict[str, Any]] = {}
    by_viewing: dict[str, dict[str, Any]] = {}
    by_candidates: dict[str, dict[str, Any]] = {}
    by_objects: dict[str, dict[str, Any]] = {}
    by_memory: dict[str, dict[str, Any]] = {}
    collisions: dict[str, int] = {}
    for i, phase in enumerate(phases):
        outcome = phase.get("outcome")
        if not isinstance(outcome, str):
            raise ValueError(f"phase {i}: no outcome in the record (got {outcome!r})")
        if outcome == "no_candidate":
            continue
        target = phase.get("target_grasp")
        score = target.get("score") if isinstance(target, Mapping) else None
        _add(by_score.setdefault(score_band(score), _cell()), outcome)
        _add(by_viewing.setdefault(viewing(phase), _cell()), outcome)
        _add(by_candidates.setdefault(candidates(phase), _cell()), outcome)
        _add(by_objects.setdefault(objects_left(phase), _cell()), outcome)
        began = memory(phase)
        if began is not None:
            _add(by_memory.setdefault(began, _cell()), outcome)
        if outcome == "collision":
            kind = collision_kind(phase)
            collisions[kind] = collisions.get(kind, 0) + 1
    order = {band: i for i, band in enumerate(_band_order())}
    memory_order = {"no memory yet": 0, "memory kept": 1, "memory dropped": 2}
    out: dict[str, dict[str, Any]] = {
        "score": dict(sorted(by_score.items(), key=lambda kv: order[kv[0]])),
        "viewing": dict(sorted(by_viewing.items())),
        "candidates": dict(sorted(by_candidates.items())),
        "objects": dict(sorted(by_objects.items(), key=lambda kv: _most_first(kv[0]))),
        "collisions": dict(sorted(collisions.items(), key=lambda kv: (-kv[1], kv[0]))),
    }
    if by_memory:
        out["memory"] = dict(sorted(by_memory.items(), key=lambda kv: memory_order[kv[0]]))
    return out


def format_breakdown(name: str, b: Mapping[str, Mapping[str, Any]]) -> str:
    """The plain-text table of :func:`breakdown` for the run called ``name``."""
    tables: tuple[tuple[str, str], ...] = (
        ("by the grasp's score", "score"),
        ("by viewing", "viewing"),
        ("by the candidates it was chosen from", "candidates"),
        ("by the objects on the table", "objects"),
        ("by the scene memory", "memory"),
    )
    tables = tuple((title, key) for title, key in tables if key in b)
    cells = [c for _, key in tables for c in b[key].values()]
    failures = sorted({o for c in cells for o in c["outcomes"]})
    head = f"{'':<28} {'success':>18}" + "".join(f" {o:>10}" for o in failures)
    lines = [f"{name}: attempted grasps", head]
    for title, key in tables:
        lines.append(f"  {title}")
        for label, cell in b[key].items():
            k, n = cell["succeeded"], cell["attempted"]
            rate = f"{k}/{n} ({100 * k / n:.1f} %)"
            counts = "".join(f" {cell['outcomes'].get(o, 0):>10}" for o in failures)
            lines.append(f"    {label:<26} {rate:>18}{counts}")
    collisions = b.get("collisions") or {}
    if collisions:
        lines.append("  collisions, by where and what the hand touched (with which part)")
        width = max(26, *(len(kind) for kind in collisions))
        lines.extend(f"    {kind:<{width}} {n:>18}" for kind, n in collisions.items())
    return "\n".join(lines)
