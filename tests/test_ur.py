"""The UR driver (heapgrasp.robot.ur) against fakes of ur_rtde's interfaces: paths
streamed and frames paired with poses, the safety checks that refuse before anything is
sent, and the controller's faults as the package's errors."""

from __future__ import annotations

import itertools
import math
import socket
import struct
import threading

import numpy as np
import pytest
import rtde_control
import rtde_receive
from fake_hardware import CAM2TCP, WORLD2BASE
from fake_ur import (
    ClockCamera,
    FakeControl,
    FakeController,
    FakeReceive,
    set_world_pose,
    world_pose,
)
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import MotionLimits, ViewSphere, plan_waypoints
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import ConnectionLost, DeviceError, ProtectiveStop
from heapgrasp.robot.interfaces import Arm, UnreachableError
from heapgrasp.robot.ur import (
    OutsideWorkspace,
    PathRefused,
    PoseBuffer,
    URArm,
    continuous_roll,
    pose_from_rtde,
    pose_to_rtde,
    probe_rtde,
)
from scipy.spatial.transform import Rotation

SPEC = CameraSpec(width=64, height=48, fx=54.0, fy=54.0, cx=31.5, cy=23.5)


def config(**tables: dict[str, object]) -> RobotConfig:
    data: dict[str, object] = {
        "arm": {"host": "fake", "park": pose_to_rtde(WORLD2BASE @ _above())},
        "calibration": {"cam2tcp": CAM2TCP.tolist(), "world2base": WORLD2BASE.tolist()},
    }
    for k, v in tables.items():
        data[k] = {**data.get(k, {}), **v}  # type: ignore[dict-item]
    return RobotConfig.from_mapping(data)


def _above() -> np.ndarray:
    """A TCP pose 0.45 m above the scene's centre, pointing down."""
    m = np.diag([1.0, -1.0, -1.0, 1.0])
    m[:3, 3] = (0.15, 0.15, 0.45)
    return m


def rig(cfg: RobotConfig | None = None) -> tuple[URArm, FakeController]:
    ctl = FakeController()
    set_world_pose(ctl, WORLD2BASE, _above())

    def render(cam2world: np.ndarray) -> np.ndarray:
        # Encodes the camera position in the image, so a test can tell where it was taken.
        img = np.zeros((SPEC.height, SPEC.width, 3), np.uint8)
        img[0, 0] = np.clip(np.round(cam2world[:3, 3] * 200 + 100), 0, 255)
        return img

    cam = ClockCamera(ctl, WORLD2BASE, CAM2TCP, render, SPEC)
    arm = URArm(
        FakeControl(ctl),
        FakeReceive(ctl),
        cam,
        cfg or config(),
        clock=lambda: ctl.clock,
        sleep=ctl.advance,
    )
    return arm, ctl


def view_path(arm: URArm, goal_phi: float = 0.0, speed: float = 0.2) -> object:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.33)
    start = sphere.pose(-math.pi / 2, 0.5)
    set_world_pose(arm_ctl(arm), WORLD2BASE, start @ np.linalg.inv(CAM2TCP))
    (path,) = plan_waypoints(
        start, [sphere.pose(goal_phi, 0.5)], sphere, MotionLimits(speed, 1.0, 5.0)
    )
    return path


def arm_ctl(arm: URArm) -> FakeController:
    return arm.control.ctl  # type: ignore[no-any-return]


def test_the_fakes_offer_only_what_ur_rtde_has() -> None:
    for fake, real in (
        (FakeControl, rtde_control.RTDEControlInterface),
        (FakeReceive, rtde_receive.RTDEReceiveInterface),
    ):
        names = [n for n in vars(fake) if not n.startswith("_")]
        missing = [n for n in names if not hasattr(real, n)]
        assert not missing, f"{fake.__name__} offers what ur_rtde lacks: {missing}"


def test_rtde_pose_vectors_round_trip() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        m = np.eye(4)
        m[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        m[:3, 3] = rng.normal(size=3)
        assert np.allclose(pose_from_rtde(pose_to_rtde(m)), m, atol=1e-12)
    with pytest.raises(DeviceError, match="6 finite"):
        pose_from_rtde([0.0, 1.0, float("nan"), 0, 0, 0])


def test_pose_buffer_interpolates_position_and_rotation() -> None:
    buf = PoseBuffer()
    a, b = np.eye(4), np.eye(4)
    b[:3, :3] = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    b[:3, 3] = (1.0, 0.0, 0.0)
    buf.add(10.0, a)
    buf.add(12.0, b)
    mid = buf.at(11.0)[0]
    assert np.allclose(mid[:3, 3], (0.5, 0, 0))
    assert np.isclose(Rotation.from_matrix(mid[:3, :3]).magnitude(), math.pi / 4)
    with pytest.raises(ValueError, match="outside"):
        buf.at(12.5)
    with pytest.raises(DeviceError, match="backwards"):
        buf.add(11.0, a)


def test_the_arm_satisfies_the_seam() -> None:
    arm, _ = rig()
    assert isinstance(arm, Arm)


def test_a_path_is_streamed_and_every_frame_carries_the_pose_it_was_taken_at() -> None:
    arm, ctl = rig()
    path = view_path(arm)
    cap = arm.follow(path)
    servo = [a for n, a in ctl.log if n == "servoL"]
    assert len(servo) >= path.duration * arm.config.arm.servo_rate
    # ~30 frames a second, each paired with the camera pose where it was rendered
    assert len(cap) >= 30 * path.duration - 2
    for f in cap.frames:
        seen = (f.rgb[0, 0].astype(float) - 100) / 200
        assert np.abs(seen - f.cam2world[:3, 3]).max() <= 0.006  # the render's 5 mm quantum
    # where the path ends, looking where it looks (the roll is the arm's: continuous_roll)
    np.testing.assert_allclose(cap.poses[-1][:3, 3], path.poses[-1][:3, 3], atol=1e-6)
    np.testing.assert_allclose(cap.poses[-1][:3, 2], path.poses[-1][:3, 2], atol=1e-6)
    # what was streamed never exceeded the caps
    pts = np.array(
        [WORLD2BASE.T[:3, :3] @ (np.asarray(p[:3]) - WORLD2BASE[:3, 3]) for p, *_ in servo]
    )
    dt = servo[0][1]
    assert (
        np.linalg.norm(np.diff(pts, axis=0), axis=1) / dt
    ).max() <= arm.config.limits.tool_speed * 1.05
    assert ctl.names()[-1] == "servoStop"


def test_a_path_leaving_the_box_is_refused_before_anything_is_sent() -> None:
    arm, ctl = rig(
        config(
            workspace={"min": [-0.2, -0.2, -0.01], "max": [0.5, 0.5, 0.3], "bin": [0.1, 0.0, 0.2]}
        )
    )
    path = view_path(arm)
    ctl.log.clear()
    with pytest.raises(OutsideWorkspace, match="workspace box") as err:
        arm.follow(path)
    assert isinstance(err.value, UnreachableError)  # the loop skips such a view
    assert not {"servoL", "moveL", "moveJ"} & set(ctl.names())


def test_a_path_faster_than_the_cap_is_slowed_to_keep_it() -> None:
    arm, ctl = rig(config(limits={"tool_speed": 0.1}))
    path = view_path(arm, speed=0.25)
    ctl.log.clear()
    cap = arm.follow(path)
    assert not cap.timing_kept
    assert cap.duration >= 2.0 * path.duration
    servo = [np.asarray(a[0][:3]) for n, a in ctl.log if n == "servoL"]
    dt = next(a[1] for n, a in ctl.log if n == "servoL")
    speeds = np.linalg.norm(np.diff(np.stack(servo), axis=0), axis=1) / dt
    assert speeds.max() <= 0.1 * 1.05


def test_a_path_needing_more_than_the_slowdown_allowed_is_refused_before_anything_is_sent() -> None:
    arm, ctl = rig(config(limits={"tool_speed": 0.1}, arm={"max_slowdown": 1.5}))
    path = view_path(arm, speed=0.25)
    ctl.log.clear()
    with pytest.raises(PathRefused, match="times slower"):
        arm.follow(path)
    assert not {"servoL", "moveL", "moveJ"} & set(ctl.names())


def test_a_path_over_the_pole_keeps_its_views_without_the_half_turn_of_roll() -> None:
    """Opposite azimuths: the look-at poses roll half a turn over the pole; the arm
    turns the camera about its optical axis instead (continuous_roll), so the path is
    followed within the caps, every frame on the path, looking at the scene's centre."""
    arm, ctl = rig()
    path = view_path(arm, goal_phi=math.pi / 2)
    ctl.log.clear()
    cap = arm.follow(path)
    assert arm.slowdowns[-1] <= arm.config.arm.max_slowdown
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.33)
    centre = sphere.target_array
    for f in cap.frames:
        to_centre = centre - f.cam2world[:3, 3]
        assert np.dot(f.cam2world[:3, 2], to_centre / np.linalg.norm(to_centre)) > 0.999
        assert abs(np.linalg.norm(f.cam2world[:3, 3] - sphere.center_array) - 0.33) < 0.005
    servo = [pose_from_rtde(a[0]) for n, a in ctl.log if n == "servoL"]
    turns = [
        Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude()
        for a, b in itertools.pairwise(servo)
    ]
    dt = next(a[1] for n, a in ctl.log if n == "servoL")
    assert max(turns) / dt <= arm.config.limits.tool_rotation_speed * 1.05


def test_continuous_roll_keeps_positions_and_optical_axes() -> None:
    rng = np.random.default_rng(0)
    poses = np.repeat(np.eye(4)[None], 20, axis=0)
    for i in range(20):
        poses[i, :3, :3] = Rotation.random(random_state=rng).as_matrix()
        poses[i, :3, 3] = rng.normal(size=3)
    out = continuous_roll(poses, np.eye(4))
    np.testing.assert_allclose(out[:, :3, 3], poses[:, :3, 3])
    np.testing.assert_allclose(out[:, :3, 2], poses[:, :3, 2], atol=1e-12)
    # each is the nearest of its rolls to the one before
    for a, b in itertools.pairwise(out):
        best = Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude()
        for psi in np.linspace(-np.pi, np.pi, 73):
            rolled = b[:3, :3] @ Rotation.from_euler("z", psi).as_matrix()
            assert Rotation.from_matrix(a[:3, :3].T @ rolled).magnitude() >= best - 1e-9


def test_a_protective_stop_mid_path_stops_the_stream() -> None:
    arm, ctl = rig()
    path = view_path(arm)
    ctl.protective_after = 10
    with pytest.raises(ProtectiveStop, match="protective stop"):
        arm.follow(path)
    assert ctl.names()[-1] == "servoStop"
    assert len([n for n in ctl.names() if n == "servoL"]) <= 11


def test_a_dropped_connection_is_a_clear_error() -> None:
    arm, ctl = rig()
    path = view_path(arm)
    ctl.drop_after = len(ctl.log) + 40
    with pytest.raises(ConnectionLost, match="UR controller"):
        arm.follow(path)


def test_a_look_rests_and_captures_at_the_pose() -> None:
    arm, ctl = rig()
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.33)
    goal = sphere.pose(0.3, 0.4)
    frame = arm.look(goal)
    # the pose asked for, perhaps turned about the optical axis (continuous_roll)
    np.testing.assert_allclose(frame.cam2world[:3, 3], goal[:3, 3], atol=1e-9)
    np.testing.assert_allclose(frame.cam2world[:3, 2], goal[:3, 2], atol=1e-9)
    assert frame.time >= ctl.clock - 1 / 30
    assert [n for n in ctl.names() if n in ("moveL", "moveJ", "servoL")] == ["moveL"]


def test_park_uses_the_joint_caps_and_the_box() -> None:
    arm, ctl = rig()
    arm.park()
    (_, speed, acc) = next(a for n, a in ctl.log if n == "moveJ")
    assert speed <= arm.config.limits.joint_speed and acc <= arm.config.limits.joint_acceleration
    outside = config(arm={"park": pose_to_rtde(WORLD2BASE @ np.diag([1.0, -1, -1, 1]))})
    arm2, _ = rig(outside)  # the park pose's TCP at the world origin's corner: z = 0 is ok
    arm2.park()
    far = _above()
    far[:3, 3] = (2.0, 0.0, 0.3)
    arm3, ctl3 = rig(config(arm={"park": pose_to_rtde(WORLD2BASE @ far)}))
    with pytest.raises(OutsideWorkspace):
        arm3.park()
    assert "moveJ" not in ctl3.names()


def test_an_approach_stops_on_contact() -> None:
    arm, ctl = rig()
    here = world_pose(ctl, WORLD2BASE)
    down = here.copy()
    down[2, 3] = 0.02
    ctl.contact_z = float((WORLD2BASE @ np.array([0, 0, 0.2, 1.0]))[2])
    assert arm.move_linear(down, speed=0.05, stop_on_contact=True) is False
    assert "stopL" in ctl.names()
    assert world_pose(ctl, WORLD2BASE)[2, 3] > 0.15
    assert arm.contact() is not None


def test_a_pregrasp_move_goes_up_across_and_down() -> None:
    arm, ctl = rig()
    opened: list[float] = []
    arm.open_to = opened.append
    target = np.diag([1.0, -1.0, -1.0, 1.0])
    target[:3, 3] = (0.1, 0.2, 0.08)
    arm.move_to(target, opening=0.06)
    assert opened == [0.06]
    moves = [a[0] for n, a in ctl.log if n == "moveL"]
    assert len(moves) == 3
    assert np.allclose(world_pose(ctl, WORLD2BASE), target, atol=1e-9)
    heights = [(np.linalg.inv(WORLD2BASE) @ pose_from_rtde(m))[2, 3] for m in moves]
    assert heights[0] >= arm.config.arm.travel_height - 1e-9 and heights[1] >= heights[2]


def test_an_uncalibrated_arm_is_refused() -> None:
    ctl = FakeController()
    with pytest.raises(DeviceError, match="robot calibrate"):
        URArm(FakeControl(ctl), FakeReceive(ctl), None, RobotConfig())  # type: ignore[arg-type]


def test_an_arm_that_never_answers_is_named_within_seconds() -> None:
    # a host that accepts TCP and never speaks RTDE (ur_rtde waited for ever), and one
    # that refuses: each a ConnectionLost naming the address, in about the timeout
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(1)
    port = silent.getsockname()[1]
    try:  # the message of the timeout, not of a connection: it waited 0.5 s, then said so
        with pytest.raises(ConnectionLost, match=rf"127\.0\.0\.1:{port} within 0\.5 s"):
            probe_rtde("127.0.0.1", port=port, timeout=0.5)
    finally:
        silent.close()
    with pytest.raises(
        ConnectionLost, match=rf"cannot reach the UR controller at 127\.0\.0\.1:{port}"
    ):
        probe_rtde("127.0.0.1", port=port, timeout=0.5)  # closed now: refused


def test_a_controller_answering_rtde_passes_the_probe() -> None:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]

    def answer() -> None:
        conn, _ = server.accept()
        with conn:
            size, kind, version = struct.unpack(">HBH", conn.recv(5))
            assert (size, kind, version) == (5, 86, 2)
            conn.sendall(struct.pack(">HBB", 4, 86, 1))  # accepted

    thread = threading.Thread(target=answer, daemon=True)
    thread.start()
    try:
        probe_rtde("127.0.0.1", port=port, timeout=2.0)
    finally:
        thread.join(timeout=5)
        server.close()
