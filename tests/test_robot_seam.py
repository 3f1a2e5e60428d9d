"""The robot seam: one whole HEAPGrasp phase and a grasp on a robot that is not the
simulator, with PyBullet (and PyTorch) blocked, with the oracle's views and with the
view network's; the layers of the package."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from conftest import RejectEveryGrasp
from fake_robot import FakeRobot, FakeScene, FakeTruth, RedSegmenter
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.stages import build_pipeline
from heapgrasp.robot.interfaces import Arm, Camera, Gripper, Robot, SceneTruth

TESTS = Path(__file__).resolve().parent
BOXES = [((0.11, 0.15, 0.035), (0.05, 0.04, 0.07)), ((0.20, 0.14, 0.03), (0.04, 0.04, 0.06))]

#: Makes importing the named packages fail in the interpreter that runs it.
BLOCK = textwrap.dedent(
    """
    import importlib.abc, sys

    class Blocked(importlib.abc.MetaPathFinder):
        def __init__(self, names):
            self.names = set(names)

        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in self.names:
                raise ImportError(f"{name} is blocked in this test")
            return None
    """
)

#: Runs in a fresh interpreter where importing pybullet, pybullet_data or torch fails.
PHASE = BLOCK + textwrap.dedent(
    f"""
    import json
    BLOCKED = ("pybullet", "pybullet_data", "torch", "rerun")
    sys.meta_path.insert(0, Blocked(BLOCKED))
    sys.path.insert(0, {str(TESTS)!r})
    from fake_robot import FakeRobot, FakeScene, FakeTruth, RedSegmenter
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.loop.stages import build_pipeline
    from heapgrasp.loop.protocol import run_clutter_removal
    from heapgrasp.planning.views import OracleViewScorer

    scene = FakeScene({BOXES!r})
    robot = FakeRobot(scene)
    truth = FakeTruth(scene, robot)
    config = RunConfig(view_planner="oracle")  # HEAPGrasp with the oracle's views and the critic
    pipeline = build_pipeline(config, robot, segmenter=RedSegmenter(), truth=truth)
    assert isinstance(pipeline.view_scorer, OracleViewScorer)
    assert pipeline.critic is not None
    phases, reason = run_clutter_removal(robot, pipeline.plan, truth=truth, max_attempts=1)
    phase = phases[0]
    print(json.dumps({{
        "outcome": phase.outcome,
        "waypoints": len(phase.extra["waypoints"]),
        "frames": phase.extra["frames"],
        "looks": robot.arm.looks,
        "paths": len(robot.arm.paths),
        "placed": truth.placed_ids,
        "object": phase.object_id,
        "closed_at": robot.gripper.closed_at[0][:3, 3].tolist(),
        "trajectory": phase.to_dict()["trajectory_length_m"],
        "imported": [n for n in BLOCKED if n in sys.modules],
    }}))
    """
)


def test_a_heapgrasp_phase_and_its_grasp_run_without_pybullet_or_torch() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PHASE], capture_output=True, text=True, timeout=600, check=False
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["imported"] == []
    # Perception, grasp planning, L = 3 view waypoints planned by eq. 14, selection...
    assert result["waypoints"] == RunConfig().L
    assert result["looks"] == 1 and result["paths"] == RunConfig().L
    assert result["frames"] > 3 * RunConfig().L
    assert result["trajectory"] > 0.0
    # ...and a grasp, executed through the seam: the gripper closed on a box, which was
    # placed in the bin.
    assert result["outcome"] == "success", result
    assert result["placed"] == [result["object"]] and result["object"] in (1, 2)


def test_the_fake_and_the_simulated_robot_satisfy_the_seam() -> None:
    scene = FakeScene(BOXES)
    robot = FakeRobot(scene)
    assert isinstance(robot, Robot) and isinstance(robot.arm, Arm)
    assert isinstance(robot.arm.camera, Camera) and isinstance(robot.gripper, Gripper)
    assert isinstance(FakeTruth(scene, robot), SceneTruth)

    from heapgrasp.sim.build import object_library, sim_camera
    from heapgrasp.sim.gripper import PandaHand
    from heapgrasp.sim.robot import SimRobot
    from heapgrasp.sim.truth import SimTruth
    from heapgrasp.sim.world import SimWorld

    config = RunConfig(objects=2)
    with SimWorld(object_library(config), seed=0) as world:
        hand = PandaHand(world)
        sim = SimRobot(hand, sim_camera(config))
        assert isinstance(sim, Robot) and isinstance(sim.arm, Arm)
        assert isinstance(sim.arm.camera, Camera) and isinstance(sim.gripper, Gripper)
        assert isinstance(SimTruth(world, hand), SceneTruth)


def test_without_scene_truth_the_oracle_is_refused_and_fixed_views_run() -> None:
    scene = FakeScene(BOXES)
    robot = FakeRobot(scene)
    with pytest.raises(ConfigError, match="only the simulator has"):
        build_pipeline(RunConfig(view_planner="oracle"), robot, segmenter=RedSegmenter())
    # A real robot's HEAPGrasp w/o VP: the circle, segmented from RGB, no truth at all.
    pipeline = build_pipeline(RunConfig(method="no-vp"), robot, segmenter=RedSegmenter())
    planned = pipeline.plan()
    assert planned.grasp is not None and planned.target_object is None
    assert len(robot.arm.paths) == RunConfig().L + 1  # once around: back to the first
    assert np.isfinite(planned.camera_positions).all()


def test_a_method_needing_depth_refuses_a_camera_without_it() -> None:
    robot = FakeRobot(FakeScene(BOXES))
    with pytest.raises(ConfigError, match="needs a depth camera"):
        build_pipeline(RunConfig(method="vgn"), robot, segmenter=RedSegmenter())


PERCEPTION_AND_PLANNING_TESTS = (
    "test_roofs",
    "test_memory",
    "test_viewplan",
    "test_selection",
    "test_motion",
    "test_score",
    "test_visual_hull",
    "test_robot_seam",
)


def test_the_tests_of_perception_and_planning_need_no_pybullet() -> None:
    script = BLOCK + textwrap.dedent(
        f"""
        import importlib
        sys.meta_path.insert(0, Blocked(("pybullet", "pybullet_data")))
        sys.path.insert(0, {str(TESTS)!r})
        for name in {PERCEPTION_AND_PLANNING_TESTS!r}:
            importlib.import_module(name)
        assert "pybullet" not in sys.modules
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr[-3000:]


def test_a_run_that_needs_missing_weights_fails_before_any_scene(tmp_path: Path) -> None:
    out = tmp_path / "run"
    script = BLOCK + textwrap.dedent(
        f"""
        sys.meta_path.insert(0, Blocked(("torch",)))
        from heapgrasp.cli import main
        from heapgrasp.inference import shipped_weights
        views = ["--view-weights", {str(tmp_path / "none.onnx")!r}]
        if shipped_weights("view-network") is None:
            views = []  # no view network ships: the run says so
        raise SystemExit(main(["run", "--view-planner", "network", *views, "--out", {str(out)!r}]))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 2, done.stderr[-2000:]
    assert "view_weights: " in done.stderr and "Traceback" not in done.stderr
    assert "torch" not in done.stderr  # the network needs onnxruntime, not PyTorch
    assert not out.exists(), "nothing is written before the run can start"
    # a weights file that does not exist: the same, naming the file
    from heapgrasp.cli import main

    missing = tmp_path / "views.onnx"
    argv = ["run", "--view-planner", "network", "--view-weights", str(missing)]
    assert main([*argv, "--out", str(out)]) == 2
    assert not out.exists()


def test_a_phase_with_the_view_network_runs_on_a_robot_without_torch(tmp_path: Path) -> None:
    """HEAPGrasp planning its views with the network (a small randomly initialised
    two-channel ViewNet, exported to ONNX) on the fake robot: no scene truth, no PyBullet,
    no PyTorch."""
    torch = pytest.importorskip("torch")
    from heapgrasp.training import ViewNet, export_onnx

    torch.manual_seed(0)
    net = ViewNet(in_channels=2, encoder_channels=(4, 8, 8), compress_channels=8)
    weights = export_onnx(net, tmp_path / "view.onnx", provenance={"data": "none (test)"})
    script = BLOCK + textwrap.dedent(
        f"""
        import json
        BLOCKED = ("pybullet", "pybullet_data", "torch", "rerun")
        sys.meta_path.insert(0, Blocked(BLOCKED))
        sys.path.insert(0, {str(TESTS)!r})
        from fake_robot import FakeRobot, FakeScene, RedSegmenter
        from heapgrasp.loop.config import RunConfig
        from heapgrasp.loop.stages import build_pipeline
        from heapgrasp.planning.view_network import NetworkViewScorer

        robot = FakeRobot(FakeScene({BOXES!r}))
        config = RunConfig(view_planner="network", view_weights={str(weights)!r})
        pipeline = build_pipeline(config, robot, segmenter=RedSegmenter())
        assert isinstance(pipeline.view_scorer, NetworkViewScorer)
        assert pipeline.view_scorer.in_channels == 2
        planned = pipeline.plan()
        print(json.dumps({{
            "grasp": planned.grasp is not None,
            "paths": len(robot.arm.paths),
            "imported": [n for n in BLOCKED if n in sys.modules],
            "training": "heapgrasp.training" in sys.modules,
        }}))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600, check=False
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["imported"] == [] and not result["training"]
    assert result["paths"] == RunConfig().L  # L view waypoints chosen from the network's scores
    assert result["grasp"]


def test_the_loop_plans_for_the_robots_gripper() -> None:
    import dataclasses

    from heapgrasp.geometry.gripper import PANDA_HAND
    from heapgrasp.planning.antipodal import AntipodalPlanner

    robot = FakeRobot(FakeScene(BOXES))
    narrow = dataclasses.replace(PANDA_HAND, max_opening=0.06)
    robot.gripper.geometry = narrow
    pipeline = build_pipeline(RunConfig(method="no-vp"), robot, segmenter=RedSegmenter())
    planner = pipeline.grasp_planner
    assert isinstance(planner, AntipodalPlanner)
    assert planner.gripper == narrow and planner.max_opening == 0.06
    planned = pipeline.plan()
    assert planned.grasp is not None and planned.grasp.width <= 0.06
    assert all(c.width <= 0.06 for c in pipeline.grasp_candidates())


def test_the_shipped_grasp_networks_grasps_are_checked_against_the_hull(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from heapgrasp.loop.stages import make_grasp_planner
    from heapgrasp.perception.silhouette import SilhouettePerception
    from heapgrasp.planning.grasp_network import NetworkGraspPlanner
    from heapgrasp.planning.hull_check import HullCheck
    from heapgrasp.planning.volumes import select_candidates
    from heapgrasp.robot.grasping import PREGRASP_DISTANCE

    robot = FakeRobot(FakeScene(BOXES))
    config = RunConfig(method="no-vp", grasp_planner="network")  # the shipped weights
    pipeline = build_pipeline(config, robot, segmenter=RedSegmenter())
    planner = pipeline.grasp_planner
    assert isinstance(planner, NetworkGraspPlanner) and planner.grasp_origin == "palm"
    pipeline.plan()
    assert isinstance(pipeline.perception, SilhouettePerception)
    hull = pipeline.perception.grid.high_confidence(config.lam) > 0
    check = HullCheck(hull, pipeline.frame, pregrasp_distance=PREGRASP_DISTANCE)
    cands = pipeline.grasp_candidates()
    assert cands and not check(np.stack([c.pose for c in cands])).any()
    # The loop's candidates are eq. 15's with the check, which drops none of these.
    volumes = planner.predict(pipeline.perception.grasp_input(), pipeline.frame)
    checked = select_candidates(
        volumes, epsilon=0.8, sigma=1.0, nms_window=config.nms_window, reject=check
    )
    assert [c.index for c in cands] == [c.index for c in checked]
    # A check that rejects everything leaves the loop no candidate.
    import heapgrasp.loop.phase

    monkeypatch.setattr(heapgrasp.loop.phase, "HullCheck", RejectEveryGrasp)
    assert pipeline.grasp_candidates() == []
    # The VGN baseline reads TSDFs: its own shipped network.
    tsdf = make_grasp_planner(RunConfig(method="vgn", grasp_planner="network"))
    assert isinstance(tsdf, NetworkGraspPlanner) and tsdf.input_kind == "tsdf"
    assert tsdf.network.path.name == "grasp_network_tsdf.onnx"
