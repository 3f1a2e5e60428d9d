"""The closed loop: one-object scenes end in a grasp; runs resume after interruption."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import RejectEveryGrasp, box_model
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.phase import MEMORY_TOLERANCE, SILHOUETTE_VIEWS
from heapgrasp.loop.protocol import PlanResult, StopReason, run_clutter_removal
from heapgrasp.perception.silhouette import SilhouettePerception
from heapgrasp.planning.volumes import GraspCandidate
from heapgrasp.run import (
    RESULTS_FILE,
    SCENES_FILE,
    RunExistsError,
    format_summary,
    load_records,
    run,
)
from heapgrasp.sim.build import sim_pipeline
from heapgrasp.sim.object_model import ObjectModel
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.world import SimWorld

BOX = (0.05, 0.04, 0.07)


@pytest.mark.parametrize("method", ["heapgrasp", "no-vp", "vgn"])
def test_one_object_scene_ends_in_a_successful_grasp(tmp_path: Path, method: str) -> None:
    model = box_model(tmp_path, BOX)
    config = RunConfig(method=method, objects=1, category="opaque")
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(config, world)
        phases, reason = run_clutter_removal(pipeline.robot, pipeline.plan, truth=pipeline.truth)
    assert reason == StopReason.CLEARED, [p.to_dict()["outcome"] for p in phases]
    assert [p.outcome for p in phases] == ["success"]
    rec = phases[0].to_dict()
    assert rec["trajectory_length_m"] > 0.3
    assert rec["shortest_trajectory_ratio"] >= 100.0
    assert rec["motion_time_s"] > 1.0 and rec["compute_time_s"] > 0.0
    # L = 3 view waypoints; the circle baselines also close the circle (Table II).
    assert len(rec["waypoints"]) == (3 if method == "heapgrasp" else 4)
    if method == "heapgrasp":
        # Eq. 18 picked candidates of the U×V set, with the view score recorded.
        for w in rec["waypoints"]:
            assert 0 <= w["index"][0] < 40 and 0 <= w["index"][1] < 20
            assert w["view_score"] <= w["view_score_max"] + 1e-6
        assert rec["waypoints"][0]["gamma2"] == 0.0 and rec["waypoints"][1]["gamma2"] == 0.35


def test_transparent_object_is_invisible_to_the_depth_baseline(tmp_path: Path) -> None:
    model = box_model(tmp_path, BOX)
    config = RunConfig(method="vgn", objects=1, category="transparent")
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="transparent", seed=0, models=[model])
        pipeline = sim_pipeline(config, world)
        result = pipeline.plan()
        # Depth passes through glass: nothing is measured, so nothing can be grasped.
        assert pipeline.perception.grasp_input().sum() < 5
        assert result.grasp is None
        # Silhouettes see it.
        sfs = sim_pipeline(config.replace({"method": "no-vp"}), world)
        assert sfs.plan().grasp is not None


def test_the_tsdf_networks_grasps_are_checked_against_the_measured_surfaces(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import heapgrasp.loop.phase
    from heapgrasp.perception.depth import DepthPerception
    from heapgrasp.planning.grasp_network import NetworkGraspPlanner
    from heapgrasp.planning.hull_check import HullCheck
    from heapgrasp.planning.volumes import select_candidates
    from heapgrasp.robot.grasping import PREGRASP_DISTANCE

    model = box_model(tmp_path, BOX)
    config = RunConfig(method="vgn", grasp_planner="network")  # the shipped TSDF network
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(config, world)
        assert isinstance(pipeline.grasp_planner, NetworkGraspPlanner)
        assert pipeline.grasp_planner.input_kind == "tsdf"
        pipeline.plan()
        assert isinstance(pipeline.perception, DepthPerception)
        shells = pipeline.perception.grasp_input() > 0
        assert shells.sum() > 100  # the box's observed surfaces
        check = HullCheck(shells, pipeline.frame, pregrasp_distance=PREGRASP_DISTANCE)
        cands = pipeline.grasp_candidates()
        assert cands and not check(np.stack([c.pose for c in cands])).any()
        # Unchecked, the same network's best grasps include some that meet the surfaces
        # (the check runs before eq. 15's NMS, so a rejected peak hides none nearby).
        volumes = pipeline.grasp_planner.predict(pipeline.perception.tsdf_values(), pipeline.frame)
        unchecked = select_candidates(volumes, epsilon=0.8, sigma=1.0, nms_window=config.nms_window)
        assert check(np.stack([c.pose for c in unchecked])).any()

        monkeypatch.setattr(heapgrasp.loop.phase, "HullCheck", RejectEveryGrasp)
        assert pipeline.grasp_candidates() == []


def test_a_phase_starts_beside_the_scene_looking_at_it(tmp_path: Path) -> None:
    model = box_model(tmp_path, BOX)
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(RunConfig(method="no-vp"), world)
        p0 = pipeline.initial_pose()
        centre = pipeline.sphere.center_array
        eye = p0[:3, 3]
        assert np.linalg.norm(eye - centre) == pytest.approx(0.5)
        assert eye[1] < centre[1] - 0.3  # the bin's side (-y)
        to_target = pipeline.sphere.target_array - eye
        assert np.dot(p0[:3, 2], to_target / np.linalg.norm(to_target)) == pytest.approx(1.0)
        top = sim_pipeline(RunConfig(method="no-vp", start="above"), world).initial_pose()
        np.testing.assert_allclose(top[:3, 3], centre + np.array([0.0, 0.0, 0.6]), atol=1e-12)
        assert top[:3, 2] @ [0.0, 0.0, -1.0] == pytest.approx(1.0)  # looking down
        # the silhouette hull's roofs are trimmed for the planner as configured
        assert isinstance(pipeline.perception, SilhouettePerception)
        assert pipeline.perception.roof_radius == RunConfig().roof_radius > 0
        assert pipeline.perception.silhouette_views == SILHOUETTE_VIEWS > 0
        raw = sim_pipeline(RunConfig(method="no-vp", roof_radius=0.0), world).perception
        assert isinstance(raw, SilhouettePerception) and raw.roof_radius == 0.0


class _ScriptedViews:
    """A view scorer that prefers nothing (every candidate scores ``level``, 0 unless
    set, but those nearest the camera, which see nothing new: 0) and records the
    targets it is given."""

    name = "flat"

    def __init__(self, level: float = 0.0) -> None:
        self.targets: list[Any] = []
        self.level = level

    def scores(self, ctx: Any) -> Any:
        self.targets.append(None if ctx.target is None else ctx.target[:3, 3].copy())
        out = np.full(ctx.candidates.shape[:2], self.level, dtype=np.float32)
        gap = np.linalg.norm(ctx.candidates[..., :3, 3] - ctx.current_pose[:3, 3], axis=-1)
        out[gap <= gap.min() + 1e-3] = 0.0  # (the top of the sphere is U candidates)
        return out


def _candidate(x: float, score: float) -> GraspCandidate:
    pose = np.eye(4)
    pose[:3, 3] = (x, 0.15, 0.05)
    return GraspCandidate(pose, 0.05, score, (0, 0, 0))


def _plan_scripted(
    model: ObjectModel,
    config: RunConfig,
    script: list[list[GraspCandidate]],
    view_level: float = 0.0,
) -> tuple[PlanResult, _ScriptedViews]:
    """One phase on ``model`` alone, the grasp planner's candidates taken from ``script``
    (one list per call) and the view scores from :class:`_ScriptedViews` (``view_level``
    everywhere)."""
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        views = _ScriptedViews(view_level)
        pipeline = sim_pipeline(config, world, view_scorer=views)
        calls = iter(script)
        pipeline.grasp_candidates = lambda final=True: next(calls)  # type: ignore[method-assign]
        return pipeline.plan(), views


def test_the_grasp_before_the_first_waypoint_does_not_anchor_eq16(tmp_path: Path) -> None:
    # Eq. 16 keeps the grasp closest to the previous target, but the target planned at
    # p0 (gamma2 = 0, §VI-B: unreliable) must not anchor it: at the second waypoint the
    # top-scoring grasp wins, and from then on the closest one.
    model = box_model(tmp_path, BOX)
    script = [
        # at p0 nothing is planned: with gamma2 = 0 its target would steer nothing
        [_candidate(0.06, 0.5), _candidate(0.25, 0.95)],  # near p0's target / best
        [_candidate(0.07, 0.99), _candidate(0.24, 0.6)],  # best / near the last target
        [_candidate(0.07, 0.99), _candidate(0.24, 0.6)],  # final
    ]
    result, views = _plan_scripted(model, RunConfig(), script)
    waypoints = result.extra["waypoints"]
    assert waypoints[0]["target"] is None and waypoints[0]["grasp_candidates"] is None
    targets = [w["target"]["position"][0] for w in waypoints[1:]]
    assert targets == pytest.approx([0.25, 0.24])
    # The view scorer sees the target of eq. 16 (for the oracle's target column), but
    # not p0's, which is unreliable (gamma2 = 0).
    assert views.targets[0] is None
    assert [t[0] for t in views.targets[1:]] == pytest.approx([0.25, 0.24])
    assert result.extra["target_grasp"]["position"][0] == pytest.approx(0.24)
    assert result.extra["best_grasp"]["position"][0] == pytest.approx(0.07)


def test_with_gamma2_zero_no_grasp_is_planned_before_the_final_grid(tmp_path: Path) -> None:
    # gamma2 = 0 at every waypoint: no target steers a view, so the only grasp planning
    # is on the final grid, where the top-scoring candidate is taken.
    model = box_model(tmp_path, BOX)
    script = [[_candidate(0.24, 0.6), _candidate(0.07, 0.99)]]  # final
    result, views = _plan_scripted(model, RunConfig(gamma2=0.0), script)
    waypoints = result.extra["waypoints"]
    assert len(waypoints) == 3 and len(views.targets) == 3
    assert all(w["target"] is None and w["grasp_candidates"] is None for w in waypoints)
    assert views.targets == [None, None, None]
    assert result.grasp is not None and result.grasp.pose[0, 3] == pytest.approx(0.07)


def test_move_weight_takes_the_nearer_of_equally_good_views(tmp_path: Path) -> None:
    # Every view scores the same (but the nearest ones, which see nothing new): without
    # move_weight eq. 18 takes the first of them, with it the nearest; the path shrinks.
    model = box_model(tmp_path, BOX)
    script = [[_candidate(0.07, 0.99)]]  # gamma2 = 0: only the final grid is planned

    def legs(result: PlanResult) -> list[float]:
        points = [result.camera_positions[0]]
        points += [np.asarray(w["position"]) for w in result.extra["waypoints"]]
        return [float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(points)]

    plain, _ = _plan_scripted(model, RunConfig(gamma2=0.0), script, view_level=0.1)
    config = RunConfig(gamma2=0.0, move_weight=0.05)
    near, _ = _plan_scripted(model, config, script, view_level=0.1)
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        pipeline = sim_pipeline(config, world, view_scorer=_ScriptedViews())
        p0 = pipeline.initial_pose()[:3, 3]
        gaps = np.linalg.norm(pipeline.candidates[..., :3, 3] - p0, axis=-1)
    # the nearest candidates score 0 (they see nothing new): the next ring is taken
    assert legs(near)[0] == pytest.approx(float(np.min(gaps[gaps > gaps.min() + 1e-3])))
    assert sum(legs(near)) < sum(legs(plain))
    assert all(w["view_score"] == pytest.approx(0.1) for w in near.extra["waypoints"])


def test_with_gamma2_at_p0_the_grasp_at_p0_is_planned_and_anchors_eq16(tmp_path: Path) -> None:
    # With gamma2_first > 0 the grasp planned at p0 steers the first view, so it is
    # planned, and eq. 16 keeps the closest grasp from then on.
    model = box_model(tmp_path, BOX)
    script = [
        [_candidate(0.05, 0.9)],  # at p0
        [_candidate(0.06, 0.5), _candidate(0.25, 0.95)],
        [_candidate(0.07, 0.99), _candidate(0.24, 0.6)],
        [_candidate(0.07, 0.99), _candidate(0.24, 0.6)],  # final
    ]
    result, views = _plan_scripted(model, RunConfig(gamma2_first=0.35), script)
    targets = [w["target"]["position"][0] for w in result.extra["waypoints"]]
    assert targets == pytest.approx([0.05, 0.06, 0.07])
    assert [t[0] for t in views.targets] == pytest.approx([0.05, 0.06, 0.07])
    assert result.extra["target_grasp"]["position"][0] == pytest.approx(0.07)


@pytest.mark.parametrize(
    ("changes", "view_level", "waypoints"),
    [
        ({}, 0.0, 3),  # the paper: exactly L waypoints
        ({"stop_below": 0.02}, 0.0, 1),  # nothing left to carve at the first waypoint
        ({"stop_below": 0.02}, 0.05, 3),  # every look still carves 5 % of the region
        ({"stop_below": 0.02, "stop_confidence": 0.95}, 0.0, 2),  # 0.9 is too doubtful
        ({"stop_below": 0.02, "stop_confidence": 0.999}, 0.0, 3),
        # 5 % is worth no detour at 100 per metre: only the camera's own candidate lies
        # on the way to the grasp, and it sees nothing new.
        ({"stop_below": 0.02, "stop_detour_weight": 100.0}, 0.05, 1),
    ],
)
def test_viewing_stops_early_where_no_look_would_carve_the_target(
    tmp_path: Path, changes: dict[str, Any], view_level: float, waypoints: int
) -> None:
    # gamma2 = 0 at every waypoint (whole-grid eq. 18): without the early stop nothing
    # is planned before the final grid; with it the target is planned from the second
    # waypoint on (EarlyStop.after = 1), and its region's scores decide.
    model = box_model(tmp_path, BOX)
    planned = [
        [_candidate(0.25, 0.9), _candidate(0.06, 0.5)],  # at the first waypoint
        [_candidate(0.24, 0.99)],  # at the second
        [_candidate(0.23, 0.99)],  # at the third: the final grid
    ]
    # Planned at each waypoint from the second on (not at all without the
    # early stop), then on the final grid, which is not planned again after a stop: the
    # script runs dry if it is.
    first = 1 if changes else 3
    script = planned[first - 1 : waypoints]
    config = RunConfig(gamma2=0.0, **changes)
    result, views = _plan_scripted(model, config, script, view_level)
    extra = result.extra
    assert len(extra["waypoints"]) == waypoints
    stopped = extra["stopped_early"]
    assert (stopped is not None) == (waypoints < 3)
    if stopped is not None:
        # The grasp is planned on the grid where the viewing stopped, and it is the
        # target whose region was checked.
        assert stopped["target"]["position"][0] == pytest.approx([0.25, 0.24][waypoints - 1])
        assert stopped["worth_max"] < 0.02
        assert result.grasp is not None
        assert result.grasp.pose[0, 3] == pytest.approx(stopped["target"]["position"][0])
    # gamma2 = 0: the choice of the next waypoint counts the whole grid (no target), the
    # stop test the target's region (its target recorded by the scorer).
    whole = [t for t in views.targets if t is None]
    assert len(whole) == waypoints


@pytest.mark.parametrize(("view_level", "stops"), [(0.0, True), (0.05, False)])
def test_a_phase_that_never_stopped_sweeps_along_the_rim(
    tmp_path: Path, view_level: float, stops: bool
) -> None:
    # sweep_degrees: only a phase that took all L waypoints goes on, along the rim of
    # the candidates, by at most that much azimuth while its grasp is unsure; one that
    # stopped early grasps at once.
    model = box_model(tmp_path, BOX)
    sure, unsure = [_candidate(0.24, 0.99)], [_candidate(0.24, 0.9)]
    script = [sure, sure, unsure, unsure]
    config = RunConfig(
        gamma2=0.0, stop_below=0.02, stop_confidence=0.95, sweep_degrees=90.0, sweep_step=45.0
    )
    result, _ = _plan_scripted(model, config, script, view_level)
    waypoints = result.extra["waypoints"]
    swept = [w for w in waypoints if w.get("sweep")]
    if stops:
        assert len(waypoints) == 1 and not swept
        return
    assert len(waypoints) == 5 and len(swept) == 2 and waypoints[3:] == swept
    assert all(w["frames"] > 0 for w in swept)
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        sphere = sim_pipeline(config, world, view_scorer=_ScriptedViews()).sphere
    rim = config.theta_max * (config.V - 1) / config.V
    start = sphere.spherical(np.asarray(waypoints[2]["position"]))[0]
    for k, w in enumerate(swept, start=1):
        phi, theta, _ = sphere.spherical(np.asarray(w["position"]))
        assert theta == pytest.approx(rim)
        turn = (phi - start + math.pi) % (2 * math.pi) - math.pi
        assert abs(turn) == pytest.approx(math.radians(45.0 * k))
    # the camera's path ends at the sweep's last waypoint, then goes to the grasp
    np.testing.assert_allclose(result.camera_positions[-2], swept[-1]["position"], atol=1e-6)


@pytest.mark.parametrize("sure_at", [2, None])
def test_the_sweep_ends_where_the_grasp_is_sure(tmp_path: Path, sure_at: int | None) -> None:
    # grasps are planned at each of the sweep's waypoints, and the sweep
    # ends at the first whose best grasp reaches stop_confidence; that grid's grasps
    # are the final ones (not planned again).
    model = box_model(tmp_path, BOX)
    unsure, sure = [_candidate(0.24, 0.9)], [_candidate(0.25, 0.97)]
    # two view waypoints plan grasps (p0's does not, gamma2 = 0), then the sweep's; the
    # final grasp is the last sweep step's (the script has no entry for another plan)
    sweep = [sure if k == sure_at else unsure for k in range(1, 5)]
    script = [unsure, unsure, *sweep]
    config = RunConfig(
        gamma2=0.0,
        stop_below=0.02,
        stop_confidence=0.95,
        sweep_degrees=180.0,
        sweep_step=45.0,
    )
    result, _ = _plan_scripted(model, config, script, view_level=0.05)
    swept = [w for w in result.extra["waypoints"] if w.get("sweep")]
    if sure_at is None:
        assert len(swept) == 4 and [w["best_score"] for w in swept] == [0.9] * 4
        assert result.extra["target_grasp"]["score"] == pytest.approx(0.9)
        return
    assert [w["best_score"] for w in swept] == [0.9, 0.97]
    assert result.extra["target_grasp"]["position"][0] == pytest.approx(0.25)


def test_a_phase_that_found_no_grasp_does_not_sweep(tmp_path: Path) -> None:
    model = box_model(tmp_path, BOX)
    config = RunConfig(
        gamma2=0.0,
        stop_below=0.02,
        stop_confidence=0.95,
        sweep_degrees=180.0,
        look_again=0,
        fine_width=False,
    )
    result, _ = _plan_scripted(model, config, [[], [], []], view_level=0.05)
    waypoints = result.extra["waypoints"]
    assert len(waypoints) == 3 and not any(w.get("sweep") for w in waypoints)
    assert result.extra["target_grasp"] is None


def test_a_phase_without_a_candidate_looks_again_from_the_turned_start(tmp_path: Path) -> None:
    # gamma2 = 0: grasps are planned on the final grid of each look only. The first look
    # finds nothing; the second, from the start turned by 180°, finds the grasp.
    model = box_model(tmp_path, BOX)
    config = RunConfig(gamma2=0.0, look_again=2)
    result, _ = _plan_scripted(model, config, [[], [_candidate(0.15, 0.9)]])
    assert result.grasp is not None
    assert result.extra["target_grasp"]["position"][0] == pytest.approx(0.15)
    (look,) = result.extra["looked_again"]
    assert look["turn_deg"] == pytest.approx(180.0) and look["found"]
    # L waypoints, the turned start, L waypoints again
    waypoints = result.extra["waypoints"]
    assert len(waypoints) == 2 * config.L + 1 and look["waypoints"] == config.L + 1
    turned = waypoints[config.L]
    assert turned["look_again"] == 1
    # the side start lies on the scene's -y side; turned half a turn, on its +y side
    centre = config.cube_size / 2
    assert turned["position"][1] > centre + 0.3
    assert turned["position"][0] == pytest.approx(centre, abs=1e-6)
    # the same grid carved on: every frame of both looks counted (the camera path is
    # every frame's position, then the grasp's)
    assert result.extra["frames"] == len(result.camera_positions) - 1


def test_a_phase_gives_up_after_its_looks_again(tmp_path: Path) -> None:
    model = box_model(tmp_path, BOX)
    # (the finer width plans the real grid: off here, tested on its own below)
    config = RunConfig(gamma2=0.0, look_again=1, fine_width=False)
    result, _ = _plan_scripted(model, config, [[], []])
    assert result.grasp is None
    assert [(x["turn_deg"], x["found"]) for x in result.extra["looked_again"]] == [
        (pytest.approx(180.0), False)
    ]
    # the paper's rule: no candidate, no second look, no second plan
    paper = RunConfig(gamma2=0.0, look_again=0, fine_width=False)
    result, _ = _plan_scripted(model, paper, [[]])
    assert result.grasp is None and result.extra["looked_again"] == []
    assert "fine_width" not in result.extra
    assert len(result.extra["waypoints"]) == RunConfig().L


def test_a_lying_box_too_wide_for_the_voxel_faces_is_grasped_at_the_finer_width(
    tmp_path: Path,
) -> None:
    # A 5.5 cm wide box lying flat: on the circle's hull, the opening measured at the
    # extreme voxels' outer faces leaves no grasp; measured at their centres, and checked
    # against the silhouettes carved three times finer, the box is taken.
    model = box_model(tmp_path, (0.055, 0.12, 0.05))
    outcomes = {}
    for fine in (False, True):
        config = RunConfig(method="no-vp", objects=1, look_again=0, fine_width=fine)
        with SimWorld(ObjectLibrary([model]), seed=0) as world:
            world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
            pipeline = sim_pipeline(config, world)
            assert (pipeline.wide_planner is not None) == fine
            phases, reason = run_clutter_removal(
                pipeline.robot, pipeline.plan, truth=pipeline.truth
            )
        outcomes[fine] = (reason, [p.outcome for p in phases], phases[0].to_dict())
    assert outcomes[False][:2] == (StopReason.NO_CANDIDATE, ["no_candidate"])
    reason, tried, record = outcomes[True]
    assert (reason, tried) == (StopReason.CLEARED, ["success"])
    fine = record["fine_width"]
    assert fine["found"] and fine["passes"][-1]["checked"] >= 1
    assert fine["voxel_m"] == pytest.approx(fine["passes"][-1]["voxel_m"])
    assert [p["voxel_m"] for p in fine["passes"]] == pytest.approx(
        [0.0075, 0.00375][: len(fine["passes"])]
    )


def test_a_failed_grasp_is_not_planned_again_until_one_succeeds(tmp_path: Path) -> None:
    model = box_model(tmp_path, BOX)
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(RunConfig(method="no-vp"), world)
        planned = pipeline.plan()
        assert planned.grasp is not None
        first = planned.grasp.pose[:3, 3].copy()
        before = pipeline.grasp_candidates()
        pipeline.record_outcome(planned.grasp, "empty")
        after = pipeline.grasp_candidates()
        # Every candidate near the failed grasp is gone; the others stay.
        assert all(np.linalg.norm(c.position - first) > 0.02 for c in after)
        kept = [c for c in before if np.linalg.norm(c.position - first) > 0.02]
        assert [c.index for c in after] == [c.index for c in kept]
        assert len(after) < len(before)
        again = pipeline.plan()
        if again.grasp is not None:
            assert np.linalg.norm(again.grasp.pose[:3, 3] - first) > 0.02
        # A success means the scene changed: the memory is cleared.
        pipeline.record_outcome(planned.grasp, "success")
        assert [c.index for c in pipeline.grasp_candidates()] == [c.index for c in before]
        # failed_grasp_radius = 0 allows the repeat.
        pipeline.record_outcome(planned.grasp, "empty")
        pipeline.config = pipeline.config.replace({"failed_grasp_radius": 0.0})
        assert [c.index for c in pipeline.grasp_candidates()] == [c.index for c in before]


def test_with_scene_memory_the_next_phase_starts_from_the_last_ones_hull(
    tmp_path: Path,
) -> None:
    model = box_model(tmp_path, BOX)
    config = RunConfig(method="heapgrasp", scene_memory=True, L=2)
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=2, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(config, world)
        assert isinstance(pipeline.perception, SilhouettePerception)
        first = pipeline.plan()
        assert first.extra["memory"] is None  # a scene's first phase: nothing yet
        carved = pipeline.perception.grid.count_high_confidence(config.lam)
        # The scene as it was (no grasp executed): the memory explains the first frame
        # and is kept, and the first frame starts from the last phase's hull.
        pipeline.perception.reset()
        assert pipeline.perception.grid.count_high_confidence(config.lam) >= carved
        again = pipeline.plan()
        # A run without it records nothing.
        plain = sim_pipeline(RunConfig(method="no-vp"), world).plan()
    record = again.extra["memory"]
    assert record is not None and record["kept"], record
    assert record["restored_voxels"] <= MEMORY_TOLERANCE
    assert "memory" not in plain.extra


def _interrupt_after(n: int) -> Any:
    seen: list[int] = []

    def hook(record: dict[str, Any]) -> None:
        seen.append(record["scene"])
        if len(seen) == n:
            raise KeyboardInterrupt

    return hook


def test_an_interrupted_run_resumes_without_losing_scenes(tmp_path: Path) -> None:
    config = RunConfig(
        method="no-vp", objects=2, scenes=3, layout="packed", max_attempts=3, look_again=0
    )
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        run(config, out, progress=False, on_scene=_interrupt_after(1))
    first = load_records(out)
    assert [r["scene"] for r in first] == [0]
    partial = json.loads((out / RESULTS_FILE).read_text())
    assert partial["scenes_completed"] == 1
    with pytest.raises(RunExistsError, match="--resume"):
        run(config, out, progress=False)
    with pytest.raises(ConfigError, match="objects"):
        run(config.replace({"objects": 3}), out, resume=True, progress=False)
    # A run saved before a parameter existed ran as its default: it may be resumed with
    # the default, not with another value.
    saved_config = json.loads((out / "config.json").read_text())
    del saved_config["move_weight"]
    (out / "config.json").write_text(json.dumps(saved_config))
    with pytest.raises(ConfigError, match=r"move_weight: 0.0 -> 0.5"):
        run(config.replace({"move_weight": 0.5}), out, resume=True, progress=False)
    summary = run(config, out, resume=True, progress=False)
    records = load_records(out)
    assert sorted(r["scene"] for r in records) == [0, 1, 2]
    assert records[0] == first[0], "finished scenes are kept as they were"
    assert summary["scenes_completed"] == 3
    for key in (
        "method",
        "grasps_attempted",
        "grasps_succeeded",
        "grasp_success_rate",
        "objects_removed",
        "objects_total",
        "trajectory_length_m",
        "shortest_trajectory_ratio",
        "execution_time_s",
        "grasp_success_ci95",
        "phases",
    ):
        assert key in summary
    if summary["grasps_attempted"]:
        low, high = summary["grasp_success_ci95"]
        assert low <= 100 * summary["grasp_success_rate"] <= high
        assert f"[{low:.1f}, {high:.1f}] %" in format_summary(summary)
    assert summary["grasps_attempted"] == sum(
        p["outcome"] != "no_candidate" for r in records for p in r["phases"]
    )
    # The circle visits all its waypoints (3 and the way back): no phase stops early.
    assert summary["early_stops"] == 0
    assert summary["view_waypoints_per_phase"]["mean"] == pytest.approx(4.0)
    assert "stopped viewing early" not in format_summary(summary)
    stopped = format_summary({**summary, "early_stops": 1})
    assert f"(1 of {len(summary['phases'])} phases stopped viewing early)" in stopped
    # the phases that planned again at the finer width, counted and printed
    assert set(summary["fine_width"]) == {"phases", "found", "held", "by_voxel"}
    assert "finer width" not in format_summary({**summary, "fine_width": {"phases": 0}})
    finer = format_summary({**summary, "fine_width": {"phases": 3, "found": 2, "held": 1}})
    assert "finer width: 3 phase(s) would have ended with no grasp; 2 found one" in finer
    by_voxel = {"phases": 3, "found": 2, "held": 1, "by_voxel": {"3.75 mm": [2, 1]}}
    assert "(found/held: 2/1 at 3.75 mm)" in format_summary({**summary, "fine_width": by_voxel})
    # Same seeds → same scenes: a fresh run of scene 0 gives the same record.
    again = run(config.replace({"scenes": 1}), None, progress=False)
    np.testing.assert_allclose(
        again["phases"][0]["camera_path"], records[0]["phases"][0]["camera_path"]
    )
    assert (out / SCENES_FILE).read_text().count("\n") == 3


@pytest.mark.parametrize("opens_fully", [False, True])
def test_a_planner_labelled_fully_open_has_its_grasps_executed_so(
    tmp_path: Path, opens_fully: bool
) -> None:
    """The grasp network's grasps were labelled with the hand fully open (VGN): the phase
    hands them to the robot at the widest opening; other planners' at their width."""
    from heapgrasp.planning.antipodal import AntipodalPlanner

    class Narrow(AntipodalPlanner):
        def predict(self, grid: Any, frame: Any) -> Any:
            volumes = super().predict(grid, frame)
            volumes.widths[...] = 0.02
            return volumes

    planner = Narrow()
    planner.opens_fully = opens_fully  # type: ignore[attr-defined]
    model = box_model(tmp_path, BOX)
    config = RunConfig(method="no-vp", objects=1, category="opaque", grasp_critic="none")
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        result = sim_pipeline(config, world, grasp_planner=planner).plan()
    assert result.grasp is not None
    assert result.grasp.width == pytest.approx(0.08 if opens_fully else 0.02)
