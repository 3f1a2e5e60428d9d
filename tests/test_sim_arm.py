"""The Franka Panda arm mode: IK, wrist camera, grasping, camera paths, joint timing."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import box_model
from heapgrasp.geometry.motion import MotionLimits, ViewSphere, plan_waypoints
from heapgrasp.robot.grasping import BIN_POSE
from heapgrasp.sim.arm import PandaArm, UnreachableError
from heapgrasp.sim.arm_config import ArmConfig, default_hand2camera
from heapgrasp.sim.arm_timing import JointPathError, joint_profile, retime_for_arm
from heapgrasp.sim.gripper import Grasp, GraspOutcome, execute_grasp
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.robot import Robot
from heapgrasp.sim.world import SimWorld

TOP_DOWN = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # TCP z pointing down
POS_TOL, ANGLE_TOL = 1e-3, 0.01
SPHERE = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.33)
CANDIDATES = SPHERE.candidates(40, 20, math.pi / 5)


def pose_errors(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    r = a[:3, :3].T @ b[:3, :3]
    angle = math.acos(min(1.0, max(-1.0, 0.5 * (np.trace(r) - 1.0))))
    return float(np.linalg.norm(a[:3, 3] - b[:3, 3])), angle


def assert_pose_close(a: np.ndarray, b: np.ndarray) -> None:
    dp, da = pose_errors(a, b)
    assert dp <= POS_TOL and da <= ANGLE_TOL, (dp, da)


def top_down(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ TOP_DOWN
    m[:3, 3] = (x, y, z)
    return m


@pytest.fixture(scope="module")
def empty_arm() -> Iterator[PandaArm]:
    """An arm in an empty world (kinematic tests)."""
    world = SimWorld(ObjectLibrary([]))
    try:
        yield PandaArm(world)
    finally:
        world.close()


@pytest.fixture
def arm(empty_arm: PandaArm) -> PandaArm:
    empty_arm.park()
    return empty_arm


@pytest.fixture
def box_world(tmp_path: Path) -> Iterator[tuple[SimWorld, int]]:
    model = box_model(tmp_path)
    world = SimWorld(ObjectLibrary([model]))
    world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
    (oid,) = world.objects
    try:
        yield world, oid
    finally:
        world.close()


# ----------------------------------------------------------------------------- kinematics


def test_the_arm_is_a_robot(arm: PandaArm) -> None:
    assert isinstance(arm, Robot)
    assert arm.time == arm.world.time


@pytest.mark.parametrize(
    "tcp",
    [
        top_down(0.15, 0.15, 0.10),
        top_down(0.0, 0.0, 0.01, yaw=1.0),
        top_down(0.30, 0.30, 0.20, yaw=-2.5),
        top_down(0.30, 0.0, 0.05, yaw=math.pi),
        BIN_POSE,
        CANDIDATES[7, 12] @ np.linalg.inv(ArmConfig().hand2camera),  # a tilted pose
    ],
)
def test_ik_round_trip(arm: PandaArm, tcp: np.ndarray) -> None:
    arm.reset(tcp, 0.05)
    assert_pose_close(arm.tcp_pose(), tcp)
    assert_pose_close(arm.forward_kinematics(arm.joint_positions()), tcp)
    np.testing.assert_array_equal(arm.tcp, tcp)
    assert arm.width() == pytest.approx(0.05, abs=1e-6)
    q = arm.inverse_kinematics(tcp)
    cfg = arm.config
    assert np.all(q >= np.array(cfg.joint_lower)) and np.all(q <= np.array(cfg.joint_upper))
    assert_pose_close(arm.forward_kinematics(q), tcp)


def test_default_placement_reaches_table_one_grasps_and_bin(arm: PandaArm) -> None:
    """The default base placement reaches every Table I view candidate with the
    camera, top-down grasps over the cube, and the bin pose (the ArmConfig claims)."""
    unique = np.unique(CANDIDATES.reshape(-1, 16).round(9), axis=0).reshape(-1, 4, 4)
    assert len(unique) == 761
    for cam in CANDIDATES.reshape(-1, 4, 4):
        assert_pose_close(arm.move_camera(cam), cam)
    for x in (0.0, 0.15, 0.3):
        for y in (0.0, 0.3):
            for z in (0.01, 0.2):
                for yaw in (-2.4, -0.8, 0.8, 2.4):
                    arm.reset(top_down(x, y, z, yaw))
                    assert_pose_close(arm.tcp_pose(), top_down(x, y, z, yaw))
    arm.reset(BIN_POSE)
    assert_pose_close(arm.tcp_pose(), BIN_POSE)


def test_move_camera_reaches_view_candidates(arm: PandaArm) -> None:
    for u, v in [(0, 0), (0, 19), (10, 10), (20, 19), (25, 5), (35, 19)]:
        cam = CANDIDATES[u, v]
        reached = arm.move_camera(cam)
        assert_pose_close(reached, cam)
        assert_pose_close(arm.camera_pose(), reached)
        # The camera is on the hand: 6.5 cm off the TCP axis, looking along it.
        assert arm.tcp[:3, 2] @ reached[:3, 2] == pytest.approx(1.0, abs=1e-6)


def test_unreachable_camera_pose_raises_and_leaves_the_arm(arm: PandaArm) -> None:
    arm.move_camera(CANDIDATES[3, 4])
    before = arm.joint_positions()
    far = CANDIDATES[3, 4].copy()
    far[:3, 3] += (3.0, 0.0, 0.0)
    with pytest.raises(UnreachableError, match=r"position error [0-9.]+ mm and angle error"):
        arm.move_camera(far)
    with pytest.raises(ValueError, match="unreachable"):
        arm.reset(top_down(3.0, 0.0, 0.1))
    np.testing.assert_array_equal(arm.joint_positions(), before)
    try:
        arm.move_camera(far)
    except UnreachableError as err:
        assert err.frame == "camera" and err.position_error > 2.0
        np.testing.assert_allclose(err.target, far, atol=1e-12)


def test_park_is_out_of_the_scene_and_nothing_is_touched(arm: PandaArm) -> None:
    arm.park()
    x, y, z = arm.tcp_pose()[:3, 3]
    assert (x < -0.1 or y > 0.4) and z > 0.3
    arm.step(24)  # the base stands on the table: that is no contact
    assert arm.contacts() == set() and arm.held_object() is None
    assert arm.touching_parts() == set()
    assert arm.width() == pytest.approx(0.08, abs=1e-3)


def test_default_hand_to_camera_is_a_wrist_camera() -> None:
    h2c = default_hand2camera()
    offset = np.linalg.norm(h2c[:2, 3])
    assert 0.05 <= offset <= 0.07
    np.testing.assert_allclose(h2c[:3, 2], [0.0, 0.0, 1.0])  # looks along the approach


# ----------------------------------------------------------------------------- grasping


def test_top_down_grasp_of_a_box_succeeds(box_world: tuple[SimWorld, int]) -> None:
    world, oid = box_world
    x, y, z = world.object_pose(oid)[:3, 3]
    arm = PandaArm(world)
    result = execute_grasp(arm, Grasp(top_down(x, y, z), width=0.07))
    assert result.outcome == GraspOutcome.SUCCESS, result
    assert result.object_id == oid
    assert world.object_pose(oid)[2, 3] > z + 0.05, "the box was lifted"
    assert_pose_close(arm.tcp_pose(), arm.tcp)  # joint control tracked the TCP


def test_grasp_in_empty_space_and_through_the_table(box_world: tuple[SimWorld, int]) -> None:
    world, _ = box_world
    arm = PandaArm(world)
    result = execute_grasp(arm, Grasp(top_down(0.05, 0.25, 0.03), width=0.07))
    assert result.outcome == GraspOutcome.EMPTY and result.object_id is None
    result = execute_grasp(arm, Grasp(top_down(0.05, 0.25, -0.03), width=0.07))
    assert result.outcome == GraspOutcome.COLLISION
    assert result.parts == frozenset({"finger"})  # the fingertips reach the table first


def test_a_palm_on_the_box_is_reported(box_world: tuple[SimWorld, int]) -> None:
    # Fingers opened past the box, the TCP planned so deep that the hand lands on it.
    world, oid = box_world
    x, y, z = world.object_pose(oid)[:3, 3]
    arm = PandaArm(world)
    top = z + 0.025  # the 5 cm box's top; the hand's face is 3.9 cm behind the TCP
    result = execute_grasp(arm, Grasp(top_down(x, y, top - 0.044), width=0.07))
    assert result.outcome == GraspOutcome.COLLISION, result
    assert result.parts == frozenset({"palm"})


def test_move_linear_is_physical(box_world: tuple[SimWorld, int]) -> None:
    world, oid = box_world
    x, y, z = world.object_pose(oid)[:3, 3]
    arm = PandaArm(world)
    arm.reset(top_down(x, y, z + 0.15))
    t0 = world.time
    assert arm.move_linear(top_down(x, y, z + 0.05), speed=0.1)
    assert world.time - t0 == pytest.approx(1.1, abs=0.02)  # 10 cm at 0.1 m/s + settling
    assert_pose_close(arm.tcp_pose(), top_down(x, y, z + 0.05))
    # Straight down onto the box: stops on the contact.
    assert not arm.move_linear(top_down(x, y, z - 0.02), abort_on_contact=True)
    assert world.objects[oid].body in arm.contacts()


# ----------------------------------------------------------------------------- camera paths


def test_follow_with_the_arm(box_world: tuple[SimWorld, int]) -> None:
    world, oid = box_world
    arm = PandaArm(world)
    (path,) = plan_waypoints(CANDIDATES[0, 10], [CANDIDATES[10, 15]], SPHERE)
    arm.move_camera(path.poses[0])
    capture = world.follow(path, mount=arm)
    _, expected = path.sample()
    assert len(capture) == len(expected)
    for frame, pose in zip(capture.frames, expected, strict=True):
        assert_pose_close(frame.cam2world, pose)
        assert (frame.labels == oid).sum() > 50, "the box is in view"
    assert arm.reconfigurations == 0
    assert_pose_close(arm.camera_pose(), path.poses[-1])


def test_free_camera_roll_keeps_the_view_direction() -> None:
    with SimWorld(ObjectLibrary([])) as world:
        arm = PandaArm(world, ArmConfig(camera_roll="free"))
        arm.move_camera(CANDIDATES[0, 0])
        for u, v in [(2, 3), (5, 8), (9, 12)]:
            cam = CANDIDATES[u, v]
            reached = arm.move_camera(cam)
            assert np.linalg.norm(reached[:3, 3] - cam[:3, 3]) < POS_TOL
            assert reached[:3, 2] @ cam[:3, 2] > math.cos(ANGLE_TOL)


# ----------------------------------------------------------------------------- timing


def test_retiming_respects_the_joint_limits(arm: PandaArm) -> None:
    fast = MotionLimits(max_velocity=1.7, max_acceleration=13.0, max_jerk=6500.0)
    (path,) = plan_waypoints(CANDIDATES[0, 10], [CANDIDATES[10, 15]], SPHERE, fast)
    arm.move_camera(path.poses[0])
    before = joint_profile(path, arm)
    assert before.limit_ratios(arm.config)[0] > 1.0, "the Cartesian limits are too fast"
    retimed = retime_for_arm(path, arm)
    assert retimed.duration > path.duration
    np.testing.assert_array_equal(retimed.poses, path.poses)
    for rate in (100.0, 250.0):
        profile = joint_profile(retimed, arm, rate=rate)
        assert max(profile.limit_ratios(arm.config)) <= 1.0
        assert np.all(np.abs(profile.velocities) <= np.array(arm.config.max_velocity))
    # A path within the limits is returned as is.
    (slow,) = plan_waypoints(CANDIDATES[5, 19], [CANDIDATES[35, 19]], SPHERE)
    arm.move_camera(slow.poses[0])
    assert retime_for_arm(slow, arm) is slow


def test_paths_over_the_pole_need_a_free_camera_roll(arm: PandaArm) -> None:
    # From the pole, look-at poses spin about the optical axis: with the roll fixed,
    # joint 7 runs into its limit and only a re-configuration would follow the path.
    (path,) = plan_waypoints(CANDIDATES[0, 0], [CANDIDATES[15, 19]], SPHERE)
    arm.move_camera(path.poses[0])
    with pytest.raises(JointPathError, match="re-configuration"):
        retime_for_arm(path, arm)
    with SimWorld(ObjectLibrary([])) as world:
        free = PandaArm(world, ArmConfig(camera_roll="free"))
        free.move_camera(path.poses[0])
        retimed = retime_for_arm(path, free)
        assert max(joint_profile(retimed, free).limit_ratios(free.config)) <= 1.0
        capture = world.follow(retimed, mount=free)
        assert free.reconfigurations == 0
        _, expected = retimed.sample()
        np.testing.assert_allclose(capture.positions, expected[:, :3, 3], atol=POS_TOL)


# ----------------------------------------------------------------------------- config


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"base_position": (0.0, float("nan"), 0.0)}, "base_position"),
        ({"base_yaw": float("inf")}, "base_yaw"),
        ({"hand2camera": 2.0 * np.eye(4)}, "hand2camera"),
        ({"hand2camera": np.eye(3)}, "hand2camera"),
        ({"max_velocity": (2.0,) * 6 + (-1.0,)}, "max_velocity"),
        ({"max_jerk": (1.0,) * 6}, "max_jerk"),
        ({"joint_lower": (3.0,) * 7}, "joint_lower"),
        ({"rest_pose": (0.0,) * 7}, "rest_pose"),
        ({"ik_position_tolerance": 0.0}, "ik_position_tolerance"),
        ({"ik_angle_tolerance": -1.0}, "ik_angle_tolerance"),
        ({"ik_iterations": 0}, "ik_iterations"),
        ({"ik_random_restarts": 1.5}, "ik_random_restarts"),
        ({"camera_roll": "loose"}, "camera_roll"),
        ({"max_angular_speed": 0.0}, "max_angular_speed"),
    ],
)
def test_bad_config_values_are_named(kwargs: dict[str, object], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        ArmConfig(**kwargs)  # type: ignore[arg-type]


def test_config_defaults() -> None:
    cfg = ArmConfig()
    assert cfg.max_velocity == (2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61)
    assert cfg.max_acceleration == (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)
    assert cfg.max_jerk == (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)
    np.testing.assert_array_equal(cfg.base_pose[:3, 3], cfg.base_position)
    assert not cfg.hand2camera.flags.writeable
