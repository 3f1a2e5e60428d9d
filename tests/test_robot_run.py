"""``heapgrasp robot run`` (dry and executed), ``replay``, ``check`` and ``calibrate`` on
the whole robot faked (``fake_hardware``): a UR controller, a Robotiq URCap server on
127.0.0.1 and a camera rendering boxes, with a segmentation network file."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fake_hardware import CAM2TCP, WORLD2BASE, Rig, SceneCamera, make_rig, robot_toml
from fake_robot import FakeRobot, FakeScene, FakeTruth, RedSegmenter
from fake_ur import set_world_pose
from heapgrasp.cli import main
from heapgrasp.cli.robot import ROBOT_TOML
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.gripper import ROBOTIQ_2F140
from heapgrasp.loop.protocol import run_clutter_removal
from heapgrasp.loop.stages import build_pipeline
from heapgrasp.real.calibrate import calibrate_robot, read_taught, world_in_board
from heapgrasp.real.check import check
from heapgrasp.real.replay import replay
from heapgrasp.real.session import dry_run, execute
from heapgrasp.real.stages import load
from heapgrasp.robot.calibration import CharucoBoard, render_board
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import ProtectiveStop, RobotConfigError
from heapgrasp.robot.hardware import Drivers, HardwareRobot

METHOD = {"L": 2}


@pytest.fixture
def rig() -> Rig:
    r = make_rig()
    yield r
    r.server.close()


def test_a_dry_run_checks_every_motion_and_sends_none(rig: Rig, tmp_path: Path) -> None:
    cfg = robot_toml(tmp_path, method=METHOD)
    result = dry_run(cfg, tmp_path / "dry", drivers=rig.drivers())
    assert rig.motions() == []  # the arm got no motion command
    assert result["rerun"] and (tmp_path / "dry" / "dry_run.rrd").stat().st_size > 0
    assert not [c for c in rig.server.sent() if c.startswith("SET")]  # the gripper none
    assert result["motion_commands_sent"] == 0 and not result["moved"]
    kinds = [c["motion"] for c in result["checks"]]
    # L view waypoints; where no grasp was found, each look again adds the turned start
    # and L more: every one a path checked
    looks = len(result["looked_again"])
    assert kinds[:2] == ["park", "look"] and kinds.count("path") == len(result["waypoints"])
    assert len(result["waypoints"]) == METHOD["L"] * (1 + looks) + looks
    assert all(c["ok"] for c in result["checks"])
    saved = json.loads((tmp_path / "dry" / "dry_run.json").read_text())
    assert saved["checks"] == result["checks"]
    assert list((tmp_path / "dry" / "frames" / "scene_000" / "phase_000").glob("*.npz"))


def test_a_dry_run_reports_a_view_outside_the_box(rig: Rig, tmp_path: Path) -> None:
    box = "[workspace]\nmin = [-0.25, -0.55, -0.01]\nmax = [0.55, 0.55, 0.36]\n"
    cfg = robot_toml(tmp_path, method=METHOD, extra=box)
    result = dry_run(cfg, tmp_path / "dry", drivers=rig.drivers(), viz=False)
    assert rig.motions() == []
    # the parked arm is above the box: the park and the first look are refused, and the
    # phase cannot start
    assert [c["motion"] for c in result["refused"]] == ["park", "look"]
    assert "workspace box" in result["refused"][0]["detail"]
    assert "workspace box" in result["stopped"]


def _fake_robot_run() -> tuple[list[int], dict[int, np.ndarray]]:
    """The same scene and settings on the seam's fake robot (the simulator's role):
    which boxes it picked and where it grasped each."""
    from fake_hardware import BOXES

    scene = FakeScene(BOXES)
    robot = FakeRobot(scene)
    robot.gripper.geometry = ROBOTIQ_2F140
    truth = FakeTruth(scene, robot)
    pipeline = build_pipeline(load_settings(), robot, segmenter=RedSegmenter(), truth=truth)
    phases, _ = run_clutter_removal(
        robot, pipeline.plan, truth=truth, on_outcome=pipeline.record_outcome
    )
    grasps = {p.object_id: p.grasp_position for p in phases if p.outcome == "success"}
    return truth.placed_ids, grasps  # type: ignore[return-value]


def load_settings():  # type: ignore[no-untyped-def]
    from heapgrasp.loop.config import RunConfig

    return RunConfig().replace(METHOD)


def test_an_executed_run_clears_the_scene_as_the_fake_robot_does(rig: Rig, tmp_path: Path) -> None:
    cfg = robot_toml(tmp_path, method=METHOD)
    out = tmp_path / "run"
    record = execute(cfg, out, objects=2, drivers=rig.drivers())
    outcomes = [p["outcome"] for p in record["phases"]]
    assert outcomes.count("success") == 2 and record["stop_reason"] == "no_candidate"
    assert not rig.scene.ids  # both boxes were carried to the bin
    fake_picked, fake_grasps = _fake_robot_run()
    assert sorted(rig.picked) == sorted(fake_picked)  # the same boxes
    ours = [np.asarray(p["grasp_position"]) for p in record["phases"] if p["outcome"] == "success"]
    for box, pos in zip(rig.picked, ours, strict=True):
        assert np.linalg.norm(pos - fake_grasps[box]) <= 0.03
    # the simulator's files, and every frame
    for name in ("config.json", "scenes.jsonl", "results.json", "robot.json"):
        assert (out / name).is_file()
    results = json.loads((out / "results.json").read_text())
    assert results["grasps_succeeded"] == 2 and results["objects_total"] == 2
    frames = sorted((out / "frames" / "scene_000").glob("phase_*/*.npz"))
    assert len(frames) >= 3 * (1 + METHOD["L"]) - METHOD["L"]
    # a second run without --resume is refused, with it appended: the folder holds both
    with pytest.raises(RobotConfigError, match="--resume"):
        execute(cfg, out, objects=1, drivers=rig.drivers())
    again = make_rig()
    try:
        second = execute(cfg, out, objects=1, resume=True, drivers=again.drivers())
    finally:
        again.server.close()
    assert second["scene"] == 1
    lines = (out / "scenes.jsonl").read_text().splitlines()
    assert [json.loads(line)["scene"] for line in lines] == [0, 1]
    results = json.loads((out / "results.json").read_text())
    assert results["objects_total"] == 3  # both runs' objects
    assert json.loads((out / "config.json").read_text())["scenes"] == 2
    assert replay(out)["phases_replayed"] >= len(record["phases"]) + 1


def test_a_protective_stop_stops_the_run_and_keeps_the_record(rig: Rig, tmp_path: Path) -> None:
    cfg = robot_toml(tmp_path, method=METHOD)
    out = tmp_path / "run"
    rig.ctl.protective_on = ("moveL", 3)  # in the first grasp's moves
    with pytest.raises(ProtectiveStop):
        execute(cfg, out, objects=2, drivers=rig.drivers())
    (record,) = [json.loads(line) for line in (out / "scenes.jsonl").read_text().splitlines()]
    assert "ProtectiveStop" in record["error"]
    assert record["phases_planned"]  # what was planned before the stop
    assert list((out / "frames" / "scene_000").glob("phase_*/*.npz"))
    results = json.loads((out / "results.json").read_text())
    assert results["scenes_failed"][0]["error"].startswith("ProtectiveStop")
    # the arm was told to stop, and the gripper's socket closed
    assert "servoStop" in rig.ctl.names() or "stopL" in rig.ctl.names()
    assert not rig.grippers[-1].connected


def test_replay_plans_the_recorded_phases_again(rig: Rig, tmp_path: Path) -> None:
    cfg = robot_toml(tmp_path, method=METHOD)
    out = tmp_path / "run"
    record = execute(cfg, out, objects=2, drivers=rig.drivers())
    same = replay(out)
    assert same["phases_replayed"] == len(record["phases"])
    for row, phase in zip(same["phases"], record["phases"], strict=True):
        assert row["recorded_outcome"] == phase["outcome"]
        if phase["grasp_position"] is not None:
            assert row["grasp_moved_m"] == pytest.approx(0.0, abs=1e-9)
    assert (out / "replay.json").is_file()
    changed = replay(out, {"lam": 0.5, "roof_radius": 0.0}, out=tmp_path / "r.json")
    assert "lam: 0.9 -> 0.5" in changed["changes"]
    assert changed["phases_replayed"] == len(record["phases"])
    changes = ["--set", "lam=0.7", "--out", str(tmp_path / "c.json")]
    assert main(["robot", "replay", str(out), *changes]) == 0
    assert main(["robot", "replay", str(out), "--set", "lamb=0.7"]) == 2  # a typo is named
    # frames missing or damaged: refused by name, not replayed from what is left
    phase = out / "frames" / "scene_000" / "phase_000"
    first = phase / "000_look.npz"
    kept = first.read_bytes()
    for damage, named in (
        (lambda: first.unlink(), "recording 000 is missing"),
        (lambda: first.write_bytes(kept[: len(kept) // 2]), "cannot be read"),
        (lambda: first.write_bytes(b""), "cannot be read"),
    ):
        damage()
        with pytest.raises(RobotConfigError, match=named):
            replay(out, out=tmp_path / "damaged.json")
        first.write_bytes(kept)
    assert not (tmp_path / "damaged.json").exists()
    last = sorted(phase.glob("*.npz"))[-1]
    last.unlink()  # the last capture of the phase: its frames are short
    with pytest.raises(RobotConfigError, match="frames were recorded"):
        replay(out, out=tmp_path / "damaged.json")


def test_check_reports_every_device(rig: Rig, tmp_path: Path) -> None:
    cfg = robot_toml(tmp_path, method=METHOD)
    items = {i["item"]: i for i in check(cfg, drivers=rig.drivers())}
    assert all(i["ok"] for i in items.values()), items
    assert "inside the box" in items["arm"]["detail"]
    assert rig.motions() == []
    rig.server.close()
    items = {i["item"]: i for i in check(cfg, drivers=rig.drivers())}
    assert not items["gripper"]["ok"] and "ConnectionLost" in items["gripper"]["detail"]
    assert items["arm"]["ok"] and items["camera"]["ok"]


def test_the_settings_a_real_robot_cannot_have_are_refused(tmp_path: Path) -> None:
    with pytest.raises(RobotConfigError, match="segmentation"):
        load(robot_toml(tmp_path, network=False))
    with pytest.raises(RobotConfigError, match="oracle"):
        load(robot_toml(tmp_path, method={"view_planner": "oracle"}))
    with pytest.raises(RobotConfigError, match="tool_speed"):
        load(robot_toml(tmp_path, method={"max_velocity": 0.5}))
    with pytest.raises(RobotConfigError, match="depth"):
        load(robot_toml(tmp_path, method={"method": "vgn"}))
    with pytest.raises(RobotConfigError, match="unknown parameter 'lamda'"):
        load(robot_toml(tmp_path, method={"lamda": 0.5}))


def test_robot_init_writes_a_template_that_loads(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "robot.toml"
    assert main(["robot", "init", str(path)]) == 0
    assert path.read_text() == ROBOT_TOML
    config = RobotConfig.load(path)
    # no address filled in for the user: nothing is contacted that they did not name
    assert config.arm.host == "" and config.gripper_host == "" and not config.calibration.done
    assert main(["robot", "init", str(path)]) == 2  # never overwritten silently
    # a run on it names what is missing before touching any device
    assert main(["robot", "run", "--config", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "segmentation" in capsys.readouterr().err
    executed = ["robot", "run", "--config", str(path), "--out", str(tmp_path / "x")]
    assert main([*executed, "--execute", "--objects", "2"]) == 2
    err = capsys.readouterr().err
    assert "segmentation" in err and f"nothing was written to {tmp_path / 'x'}" in err
    assert "kept in" not in err
    # so does the check, for the arm and the gripper, and connects to neither
    contacted: list[str] = []

    def touch(device: str) -> Any:
        contacted.append(device)
        raise RuntimeError(f"{device} contacted")

    drivers = Drivers(
        arm=lambda host, tcp: touch("arm"),
        gripper=lambda robot: touch("gripper"),
        camera=lambda settings: touch("camera"),
    )
    items = {i["item"]: i for i in check(path, drivers=drivers)}
    assert contacted == ["camera"]  # the camera is a USB device, no address
    contacted.clear()
    assert not items["arm"]["ok"] and "[arm] host is empty" in items["arm"]["detail"]
    assert not items["gripper"]["ok"] and "set [arm] host" in items["gripper"]["detail"]
    with pytest.raises(RobotConfigError, match=r"\[arm\] host is empty"):
        HardwareRobot.connect(config, drivers)
    assert contacted == []


class BoardCamera(SceneCamera):
    """The rig's camera looking at a ChArUco board lying where the workspace is."""

    def __init__(self, rig: Rig, board: CharucoBoard, spec: CameraSpec) -> None:
        super().__init__(rig.ctl, rig.scene, spec)
        board2world = np.linalg.inv(world_in_board(board))

        def render(cam2world: np.ndarray) -> np.ndarray:
            grey = render_board(board, spec, np.linalg.inv(cam2world) @ board2world, noise=1.0)
            return np.repeat(grey[..., None], 3, axis=2)

        self.render = render


def test_calibration_on_the_arm_recovers_the_extrinsic(rig: Rig, tmp_path: Path) -> None:
    board = CharucoBoard()
    rig.camera = BoardCamera(rig, board, CameraSpec.still())
    # the operator jogged the arm so the camera looks down at the board from 0.42 m
    centre = np.linalg.inv(world_in_board(board)) @ np.r_[board.center, 1.0]
    cam = np.diag([1.0, -1.0, -1.0, 1.0])
    cam[:3, 3] = centre[:3] + np.array([0.0, 0.0, 0.42])
    set_world_pose(rig.ctl, WORLD2BASE, cam @ np.linalg.inv(CAM2TCP))
    path = robot_toml(tmp_path, method=METHOD)
    text = path.read_text()
    start = text.index("[calibration]")
    end = text.index("[networks]")
    path.write_text(text[:start] + text[end:])  # not calibrated yet
    before = path.read_text()
    plan = calibrate_robot(path, tmp_path / "cal", drivers=rig.drivers())
    assert not plan["executed"] and rig.motions() == [] and path.read_text() == before
    assert all(c["ok"] for c in plan["checks"])
    report = calibrate_robot(path, tmp_path / "cal", drivers=rig.drivers(), execute=True)
    assert report["detected"] == report["images"] >= 12
    written = RobotConfig.load(path)
    assert (tmp_path / "robot.toml.bak").read_text() == before
    assert written.calibration.done
    err_mm = 1000 * np.linalg.norm(written.calibration.cam2tcp[:3, 3] - CAM2TCP[:3, 3])
    rel = written.calibration.cam2tcp[:3, :3].T @ CAM2TCP[:3, :3]
    err_deg = math.degrees(math.acos(min(1.0, (np.trace(rel) - 1) / 2)))
    assert err_mm <= 1.0 and err_deg <= 0.1, (err_mm, err_deg)
    assert np.abs(written.calibration.world2base - WORLD2BASE)[:3, 3].max() <= 0.002
    assert "[networks]" in path.read_text()  # the rest of the file is kept
    load(path)  # and the run settings still load
    # taught poses instead of generated ones: the first 8 reached, as the pendant shows them
    taught = tmp_path / "taught.json"
    visited = [a[0] for n, a in rig.ctl.log if n == "moveL"][:8]
    taught.write_text(json.dumps(visited))
    again = calibrate_robot(
        path, tmp_path / "cal2", drivers=rig.drivers(), execute=True, taught=read_taught(taught)
    )
    assert again["poses"] == 8 and again["detected"] == 8
    taught.write_text("[[0, 0, 0.3, 0, 0]]")
    with pytest.raises(RobotConfigError, match="at least 3 poses"):
        read_taught(taught)
    taught.write_text(json.dumps([[0, 0, 0.3, 0, 0, 0]] * 2 + [[0, 0, "x", 0, 0, 0]]))
    with pytest.raises(RobotConfigError, match="entry 2 must be"):
        read_taught(taught)


def test_calibrate_synthetic_rehearsal_runs_from_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["robot", "calibrate", "--synthetic", "--out", str(tmp_path), "--poses", "10"]) == 0
    report = json.loads((tmp_path / "calibration.json").read_text())
    assert report["recovery_error_mm"] <= 1.0 and report["recovery_error_deg"] <= 0.1
    assert "recovered to" in capsys.readouterr().out


def test_robot_board_writes_a_printable_board_the_detector_finds(tmp_path: Path) -> None:
    import cv2

    path = tmp_path / "board.png"
    assert main(["robot", "board", str(path), "--dpi", "100"]) == 0
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    board = CharucoBoard()
    per_square = round(board.square / 0.0254 * 100)
    assert image.shape == (
        board.squares_y * per_square + 2 * (per_square // 2),
        board.squares_x * per_square + 2 * (per_square // 2),
    )
    _, ids, _, _ = cv2.aruco.CharucoDetector(board.cv()).detectBoard(image)
    assert ids is not None and len(ids) == (board.squares_x - 1) * (board.squares_y - 1)


def test_replay_refuses_a_simulated_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.run import run

    out = tmp_path / "sim"
    config = RunConfig(method="no-vp", objects=1, layout="packed", max_attempts=1, look_again=0)
    run(config, out, progress=False)
    before = sorted(p.name for p in out.iterdir())
    assert main(["robot", "replay", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no recorded frames" in err and "robot run --execute" in err
    assert sorted(p.name for p in out.iterdir()) == before  # no replay.json


def test_a_bad_network_file_is_refused_before_any_device(rig: Rig, tmp_path: Path) -> None:
    cfg = robot_toml(tmp_path, method=METHOD)
    (tmp_path / "bad.onnx").write_bytes(np.random.default_rng(0).bytes(512))
    text = cfg.read_text().replace(
        'segmentation = "red.onnx"', 'segmentation = "red.onnx"\nview = "bad.onnx"'
    )
    cfg.write_text(text)
    with pytest.raises(RobotConfigError, match=r"\[networks\].*bad\.onnx"):
        execute(cfg, tmp_path / "run", objects=1, drivers=rig.drivers())
    assert rig.server.sent() == []  # the gripper was not even connected to
    assert rig.motions() == []
    assert not (tmp_path / "run").exists()
    with pytest.raises(RobotConfigError, match=r"bad\.onnx"):
        dry_run(cfg, tmp_path / "dry", drivers=rig.drivers(), viz=False)
    items = {i["item"]: i for i in check(cfg, drivers=rig.drivers())}
    assert not items["grasp and view planners"]["ok"]
    assert "bad.onnx" in items["grasp and view planners"]["detail"]


def test_check_names_a_silent_gripper_and_a_silent_camera(rig: Rig, tmp_path: Path) -> None:
    # a gripper address that accepts the connection and never answers, a camera that
    # starts and never delivers: check reports both, each within its timeout, and goes on
    import socket

    from heapgrasp.robot.robotiq import Robotiq2F140

    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen()  # the kernel accepts; nobody reads or answers
    port = silent.getsockname()[1]

    class SilentCamera(type(rig.camera)):  # type: ignore[misc]
        def _emit_due(self) -> None:  # the device never sends a frame
            pass

    extra = "[camera]\ntimeout = 0.2\n[gripper]\ntimeout = 0.3\n"
    cfg = robot_toml(tmp_path, method=METHOD, extra=extra)
    base = rig.drivers()
    drivers = Drivers(
        arm=base.arm,
        camera=lambda settings: SilentCamera(rig.ctl, rig.scene),
        gripper=lambda config: Robotiq2F140("127.0.0.1", port, timeout=config.gripper.timeout),
        clock=base.clock,
        sleep=base.sleep,
    )
    try:
        items = {i["item"]: i for i in check(cfg, drivers=drivers)}
    finally:
        silent.close()
    assert not items["camera"]["ok"] and "no frame within 0.2 s" in items["camera"]["detail"]
    gripper = items["gripper"]
    assert not gripper["ok"] and f"127.0.0.1:{port}" in gripper["detail"]
    assert "0.3 s" in gripper["detail"]
    assert items["arm"]["ok"]  # the other devices are still checked
