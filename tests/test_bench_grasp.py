"""heapgrasp bench grasp: arguments, the summary of hand-made records, one tiny run."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from heapgrasp.bench.grasp import (
    GRIDS,
    GraspBenchConfig,
    dense_waypoints,
    markdown_table,
    summarize,
)
from heapgrasp.cli import build_parser, main
from heapgrasp.geometry.motion import ViewSphere
from heapgrasp.loop.config import ConfigError, RunConfig


def _parse(*argv: str) -> Any:
    return build_parser().parse_args(["bench", "grasp", *argv])


def test_defaults() -> None:
    args = _parse()
    assert (args.scenes, args.seed, args.layout, args.objects, args.category) == (
        30,
        0,
        "pile",
        5,
        "mixed",
    )
    assert args.grids == GRIDS
    assert args.epsilon is None and args.sigma is None  # the planner's own, at run time
    assert args.roof_radius == RunConfig().roof_radius  # the pipeline's
    assert args.out is None and not args.quiet


def test_options_are_parsed() -> None:
    args = _parse(
        "--scenes", "3", "--seed", "7", "--layout", "packed", "--objects", "4",
        "--category", "opaque", "--grids", "dense, circle", "--epsilon", "0.6",
        "--sigma", "0", "--out", "x", "--quiet", "--roof-radius", "0",
    )  # fmt: skip
    assert (args.scenes, args.seed, args.layout, args.objects) == (3, 7, "packed", 4)
    assert args.category == "opaque" and args.grids == ("circle", "dense")
    assert (args.epsilon, args.sigma, args.out, args.quiet) == (0.6, 0.0, Path("x"), True)
    assert args.roof_radius == 0.0
    assert _parse("--grids", "dense").grids == ("dense",)


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--grids", "circle,full"], "'full'"),
        (["--grids", ","], "(none)"),
        (["--scenes", "0"], "got 0"),
        (["--scenes", "many"], "'many'"),
        (["--seed", "-1"], "got -1"),
        (["--objects", "0"], "got 0"),
        (["--epsilon", "1.5"], "got 1.5"),
        (["--sigma", "-0.5"], "got -0.5"),
        (["--sigma", "nan"], "got nan"),
        (["--roof-radius", "-0.01"], "got -0.01"),
        (["--layout", "heap"], "'heap'"),
        (["--category", "glass"], "'glass'"),
    ],
)
def test_bad_arguments_are_refused(
    argv: list[str], named: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["bench", "grasp", *argv]) == 2
    err = capsys.readouterr().err
    assert argv[0] in err and named in err


def test_dense_waypoints_cover_the_hemisphere() -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.5)
    poses = dense_waypoints(sphere, n_polar=3, n_azimuth=4, theta_max=math.radians(60))
    assert poses.shape == (13, 4, 4)
    eyes = poses[:, :3, 3] - sphere.center_array
    np.testing.assert_allclose(np.linalg.norm(eyes, axis=1), 0.5)
    theta = np.degrees(np.arccos(eyes[:, 2] / 0.5))
    np.testing.assert_allclose(theta, [0] + [20] * 4 + [40] * 4 + [60] * 4, atol=1e-9)
    # every camera looks at the centre of the cube (OpenCV: +z forward)
    to_target = sphere.target_array - poses[:, :3, 3]
    to_target /= np.linalg.norm(to_target, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ni,ni->n", poses[:, :3, 2], to_target), 1.0)
    with pytest.raises(ValueError, match="theta_max"):
        dense_waypoints(sphere, theta_max=math.pi / 2)


def test_config_is_validated() -> None:
    with pytest.raises(ConfigError, match="'full'"):
        GraspBenchConfig(grids=("circle", "full"))
    with pytest.raises(ConfigError, match="layout"):
        GraspBenchConfig(layout="heap")


def _record(grid: str, outcome: str, ms: float, far: bool = False) -> dict[str, Any]:
    attempted = outcome != "no_candidate"
    return {
        "scene": 0,
        "grid": grid,
        "outcome": outcome,
        "candidates": 2 if attempted else 0,
        "planner_ms": ms,
        "grasp": {"far_from_objects": far} if attempted else None,
    }


def test_summary_of_hand_made_records() -> None:
    records = [
        _record("circle", "success", 100.0),
        _record("circle", "collision", 200.0, far=True),
        _record("circle", "no_candidate", 600.0),
        _record("circle", "success", 300.0),
        {"scene": 4, "seed": 4, "grid": "circle", "error": "RuntimeError: boom"},
        _record("dense", "empty", 50.0),
    ]
    summary = summarize(records, ("circle", "dense"))
    c = summary["circle"]
    assert (c["scenes"], c["errors"], c["scenes_with_candidate"]) == (4, 1, 3)
    assert (c["attempts"], c["successes"], c["success_rate"]) == (3, 2, 2 / 3)
    assert c["outcomes"] == {"success": 2, "collision": 1, "empty": 0, "unreachable": 0}
    assert c["far_from_objects"] == 1
    assert c["planner_ms"] == {"mean": 300.0, "median": 250.0, "max": 600.0}
    d = summary["dense"]
    assert (d["attempts"], d["successes"], d["success_rate"]) == (1, 0, 0.0)
    assert d["outcomes"]["empty"] == 1

    none = summarize([], ("dense",))["dense"]
    assert (none["scenes"], none["attempts"], none["success_rate"]) == (0, 0, None)
    assert none["planner_ms"]["mean"] is None

    table = markdown_table(summary, GraspBenchConfig(scenes=5, grids=("circle", "dense")))
    assert "| circle | 4 | 3 | 3 | 2 | 66.7 | success 2, collision 1 | 1 | 300 | 250 |" in table
    assert "| dense | 1 | 1 | 1 | 0 | 0.0 | empty 1 | 0 | 50 | 50 |" in table
    assert "seeds 0–4" in table and "{'circle': 1}" in table


def test_one_scene_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench"
    argv = ["bench", "grasp", "--scenes", "1", "--grids", "circle", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    assert "| circle | 1 |" in capsys.readouterr().out
    data = json.loads((out / "results.json").read_text())
    assert data["benchmark"] == "grasp"
    assert data["command"] == "heapgrasp " + " ".join(argv)
    assert {"cpu_model", "cpu_count", "heapgrasp"} <= set(data["machine"])
    config = data["config"]
    assert config["grids"] == ["circle"] and config["scenes"] == 1
    assert (config["epsilon"], config["sigma"]) == (0.4, 0.5)  # AntipodalPlanner's own
    assert config["roof_radius"] == RunConfig().roof_radius
    assert set(data["summary"]) == {"circle"}
    s = data["summary"]["circle"]
    assert s["errors"] == 0
    assert 0 <= s["successes"] <= s["attempts"] <= s["scenes_with_candidate"] <= s["scenes"] == 1
    assert sum(s["outcomes"].values()) == s["attempts"]
    (record,) = data["records"]
    assert (record["scene"], record["seed"], record["grid"]) == (0, 0, "circle")
    assert record["frames"] > 3 and record["occupied_voxels"] > 0 and record["planner_ms"] > 0
    if record["outcome"] == "no_candidate":
        assert record["grasp"] is None
    else:
        grasp = record["grasp"]
        assert record["outcome"] in s["outcomes"] and len(grasp["position"]) == 3
        assert 0.0 <= grasp["width"] <= 0.08 and grasp["nearest_object_distance_m"] >= 0.0
    assert (out / "table.md").read_text().startswith("# heapgrasp bench grasp — 1 scene ×")


def test_the_config_defaults_are_the_planners_own() -> None:
    from heapgrasp.planning.antipodal import AntipodalPlanner

    planner = AntipodalPlanner()
    config = GraspBenchConfig()
    assert (config.epsilon, config.sigma) == (planner.epsilon, planner.sigma)
