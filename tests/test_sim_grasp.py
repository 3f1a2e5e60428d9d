"""Grasp execution with the free-flying Panda hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import box_model
from heapgrasp.sim.gripper import Grasp, GraspOutcome, PandaHand, execute_grasp
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.truth import touched_labels
from heapgrasp.sim.world import SimWorld

TOP_DOWN = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # TCP z pointing down


def tcp(position: tuple[float, float, float], rotation: np.ndarray = TOP_DOWN) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = position
    return m


@pytest.fixture
def world_with_box(tmp_path: Path) -> tuple[SimWorld, int]:
    model = box_model(tmp_path)
    world = SimWorld(ObjectLibrary([model]))
    world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
    (oid,) = world.objects
    return world, oid


def test_top_down_grasp_of_a_box_succeeds(world_with_box: tuple[SimWorld, int]) -> None:
    world, oid = world_with_box
    with world:
        x, y, z = world.object_pose(oid)[:3, 3]
        hand = PandaHand(world)
        result = execute_grasp(hand, Grasp(tcp((x, y, z)), width=0.07))
        assert result.outcome == GraspOutcome.SUCCESS, result
        assert result.object_id == oid
        assert world.object_pose(oid)[2, 3] > z + 0.05, "the box was lifted"
        assert result.duration > 0.5


def test_grasp_in_empty_space_fails(world_with_box: tuple[SimWorld, int]) -> None:
    world, _ = world_with_box
    with world:
        hand = PandaHand(world)
        result = execute_grasp(hand, Grasp(tcp((0.05, 0.25, 0.03)), width=0.07))
        assert result.outcome == GraspOutcome.EMPTY and result.object_id is None


def test_grasp_through_the_table_collides(world_with_box: tuple[SimWorld, int]) -> None:
    world, _ = world_with_box
    with world:
        hand = PandaHand(world)
        result = execute_grasp(hand, Grasp(tcp((0.05, 0.25, -0.03)), width=0.07))
        assert result.outcome == GraspOutcome.COLLISION
        assert result.stage == "approach" and world.table in result.touched
        assert touched_labels(world, result.touched, None) == ["table"]
        assert result.parts == frozenset({"finger"})  # the fingertips reach it first


def test_a_palm_that_lands_on_the_object_is_reported(
    world_with_box: tuple[SimWorld, int],
) -> None:
    # The fingers, opened wider than the 5 cm box, pass beside it; the TCP is planned
    # so deep that the hand's front face comes down on the box's top first.
    world, oid = world_with_box
    with world:
        x, y, _ = world.object_pose(oid)[:3, 3]
        result = execute_grasp(PandaHand(world), Grasp(tcp((x, y, 0.006)), width=0.07))
        assert result.outcome == GraspOutcome.COLLISION, result
        assert result.stage == "approach"
        assert touched_labels(world, result.touched, oid) == ["target"]
        assert result.parts == frozenset({"palm"})


def test_a_hand_inside_the_object_collides_at_the_pregrasp(
    world_with_box: tuple[SimWorld, int],
) -> None:
    world, oid = world_with_box
    with world:
        x, y, z = world.object_pose(oid)[:3, 3]
        hand = PandaHand(world)
        # The pre-grasp pose (5 cm back, above) puts the closed fingers in the box.
        result = execute_grasp(hand, Grasp(tcp((x, y, z - 0.05)), width=0.0))
        assert result.outcome == GraspOutcome.COLLISION, result
        assert result.stage == "pregrasp"
        body = world.objects[oid].body
        assert body in result.touched
        assert touched_labels(world, result.touched, oid) == ["target"]
        assert touched_labels(world, result.touched, None) == ["object"]
        assert touched_labels(world, {10_000}, None) == ["other"]
        assert result.parts and result.parts <= {"palm", "finger"}


def test_successes_record_no_contact(world_with_box: tuple[SimWorld, int]) -> None:
    world, oid = world_with_box
    with world:
        x, y, z = world.object_pose(oid)[:3, 3]
        result = execute_grasp(PandaHand(world), Grasp(tcp((x, y, z)), width=0.07))
        assert result.success and result.touched == frozenset() and result.stage is None
        assert result.parts == frozenset()


def test_bad_grasps_are_rejected() -> None:
    with pytest.raises(ValueError, match="width"):
        Grasp(tcp((0, 0, 0)), width=-0.01)
    with pytest.raises(ValueError, match="width"):
        Grasp(tcp((0, 0, 0)), width=float("nan"))
    with pytest.raises(ValueError, match="rigid"):
        Grasp(tcp((0, 0, 0), rotation=2 * np.eye(3)), width=0.05)


def test_the_simulated_gripper_closes_to_a_width_or_until_it_meets_something(
    world_with_box: tuple[SimWorld, int],
) -> None:
    from heapgrasp.sim.robot import SimRobot

    world, _ = world_with_box
    with world:
        hand = PandaHand(world)
        robot = SimRobot(hand)
        assert robot.gripper.geometry.max_opening == pytest.approx(0.08)
        robot.gripper.open()
        assert hand.width() == pytest.approx(0.08, abs=2e-3)
        robot.gripper.close(width=0.03)  # in free space: stops at the width asked
        assert hand.width() == pytest.approx(0.03, abs=2e-3) and not robot.gripper.holding()
        robot.gripper.close()  # shut
        assert hand.width() < 0.005
