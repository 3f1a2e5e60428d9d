"""heapgrasp.results.stats: Wilson intervals, per-scene counts, paired scene bootstrap."""

from __future__ import annotations

import math
from typing import Any

import pytest
from heapgrasp.bench.sim import add_uncertainty, markdown_tables
from heapgrasp.loop.config import RunConfig
from heapgrasp.results.stats import (
    format_interval,
    paired_success_difference,
    scene_counts,
    success_interval,
)


def _wilson(k: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return centre - half, centre + half


def test_success_interval_is_wilsons() -> None:
    for k, n in ((43, 51), (35, 40), (0, 5), (5, 5), (1, 1)):
        low, high = success_interval(k, n)
        assert (low, high) == pytest.approx(_wilson(k, n), abs=1e-9)
        assert 0.0 <= low <= k / n <= high <= 1.0
    # A wider level gives a wider interval.
    lo99, hi99 = success_interval(43, 51, level=0.99)
    lo95, hi95 = success_interval(43, 51)
    assert lo99 < lo95 and hi99 > hi95


@pytest.mark.parametrize(
    ("k", "n", "level", "match"),
    [
        (3, 0, 0.95, "attempted >= 1"),
        (4, 3, 0.95, "4/3"),
        (-1, 3, 0.95, "-1/3"),
        (1.5, 3, 0.95, "succeeded must be an integer, got 1.5"),
        (1, True, 0.95, "attempted must be an integer, got True"),
        (1, 3, 1.0, "level must be in"),
        (1, 3, float("nan"), "level must be in"),
    ],
)
def test_success_interval_refuses_bad_counts(k: Any, n: Any, level: float, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        success_interval(k, n, level=level)


def _phases(rows: dict[int, list[str]]) -> list[dict[str, Any]]:
    return [{"scene": s, "outcome": o} for s, outs in rows.items() for o in outs]


def test_scene_counts_skip_phases_without_a_grasp() -> None:
    counts = scene_counts(
        _phases(
            {
                3: ["success", "empty", "no_candidate"],
                1: ["collision"],
                2: ["no_candidate"],
            }
        )
    )
    assert counts == {1: (0, 1), 2: (0, 0), 3: (1, 2)}
    assert list(counts) == [1, 2, 3]
    with pytest.raises(ValueError, match="'scene'"):
        scene_counts([{"outcome": "success"}])


def test_paired_difference_of_a_method_with_itself_is_zero() -> None:
    a = {0: (3, 4), 1: (2, 3), 2: (4, 4), 3: (1, 3)}
    d = paired_success_difference(a, a)
    assert d == {"difference": 0.0, "low": 0.0, "high": 0.0, "scenes": 4}


def test_paired_difference_bounds_and_determinism() -> None:
    a = {s: (n, n) for s, n in enumerate([1, 2, 3, 2, 1, 4])}
    b = {s: (0, n) for s, n in enumerate([1, 2, 3, 2, 1, 4])}
    d = paired_success_difference(a, b)
    assert d["difference"] == pytest.approx(100.0)
    assert d["low"] == pytest.approx(100.0) and d["high"] == pytest.approx(100.0)
    mixed = {0: (3, 4), 1: (1, 3), 2: (4, 4), 3: (0, 2), 4: (2, 2), 5: (1, 1)}
    ref = {0: (4, 4), 1: (3, 3), 2: (3, 4), 3: (2, 2), 4: (1, 2), 5: (1, 1)}
    first = paired_success_difference(mixed, ref, seed=3)
    assert first == paired_success_difference(mixed, ref, seed=3)
    assert first["difference"] == pytest.approx(100 * (11 / 16 - 14 / 16))
    low, high, mid = first["low"], first["high"], first["difference"]
    assert isinstance(low, float) and isinstance(high, float) and isinstance(mid, float)
    assert low < mid < high


def test_paired_difference_uses_common_scenes_only() -> None:
    a = {0: (1, 1), 1: (0, 1), 7: (5, 5)}
    b = {0: (1, 1), 1: (1, 1), 9: (0, 5)}
    d = paired_success_difference(a, b)
    assert d["scenes"] == 2 and d["difference"] == pytest.approx(-50.0)
    assert paired_success_difference(a, {5: (1, 1)})["difference"] is None
    none = paired_success_difference({0: (0, 0), 1: (0, 0)}, b)
    assert none == {"difference": None, "low": None, "high": None, "scenes": 2}
    with pytest.raises(ValueError, match="resamples must be an integer >= 100, got 5"):
        paired_success_difference(a, b, resamples=5)


def test_format_interval() -> None:
    assert format_interval(-3.21, 18.94) == "[-3.2, 18.9]"
    assert format_interval(None, 1.0) == "–"


def _summary(method: str, rows: dict[int, list[str]]) -> dict[str, Any]:
    phases = _phases(rows)
    attempted = [p for p in phases if p["outcome"] != "no_candidate"]
    ok = sum(p["outcome"] == "success" for p in attempted)
    stat = {"mean": 1.0, "std": 0.0}
    return {
        "label": method,
        "grasps_attempted": len(attempted),
        "grasps_succeeded": ok,
        "grasp_success_rate": ok / len(attempted),
        "objects_removed": ok,
        "objects_total": 10,
        "trajectory_length_m": stat,
        "shortest_trajectory_ratio": stat,
        "execution_time_s": stat,
        "planning_latency_per_waypoint_s": stat,
        "wall_time_per_scene_s": stat,
        "phases": phases,
    }


def test_tables_carry_intervals_and_the_difference_from_no_vp() -> None:
    summaries = {
        "heapgrasp": _summary("heapgrasp", {0: ["success", "empty"], 1: ["success"]}),
        "no-vp": _summary("no-vp", {0: ["success", "success"], 1: ["success"]}),
    }
    add_uncertainty(summaries)
    low, high = summaries["heapgrasp"]["grasp_success_ci95"]
    assert (low / 100, high / 100) == pytest.approx(success_interval(2, 3))
    diff = summaries["heapgrasp"]["success_difference"]
    assert diff["reference"] == "no-vp" and diff["scenes"] == 2
    assert diff["difference"] == pytest.approx(100 * (2 / 3 - 1))
    assert "success_difference" not in summaries["no-vp"]
    text = markdown_tables(summaries, RunConfig(scenes=2))
    assert f"| 66.7 (2/3) | {format_interval(low, high)} |" in text
    assert "- heapgrasp: -33.3 [" in text and "over 2 scenes" in text
