"""The robot rehearsal (``heapgrasp robot ... --sim``): the UR5e kinematics it answers
with, its controller's RTDE surface, and the whole real-robot path — ``robot init``,
``check``, ``calibrate``, a dry run, an executed run, ``replay`` and ``show`` — run
against the simulator from the command line, on the template ``robot.toml``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import rtde_control
import rtde_receive
from heapgrasp.cli import main
from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.real.stages import load
from heapgrasp.robot.errors import RobotConfigError
from heapgrasp.sim.rehearsal.controller import SimControl, SimReceive
from heapgrasp.sim.rehearsal.rig import BASE2WORLD, TRUE_CAM2TCP, Rehearsal
from heapgrasp.sim.rehearsal.ur5e import DH_A, DH_D, UR5e
from scipy.spatial.transform import Rotation

# ---------------------------------------------------------------- kinematics


def test_the_ur5e_at_zero_joints_is_where_universal_robots_puts_it() -> None:
    # all joints at zero: the arm stretched along the base's -x, the flange turned down y
    pose = UR5e().forward([0.0] * 6)
    expected = (DH_A[1] + DH_A[2], -(DH_D[3] + DH_D[5]), DH_D[0] - DH_D[4])
    assert np.allclose(pose[:3, 3], expected, atol=1e-9)
    assert np.allclose(expected, (-0.8172, -0.2329, 0.0628), atol=1e-4)


def test_the_jacobian_is_the_derivative_of_the_forward_kinematics() -> None:
    tcp = np.eye(4)
    tcp[2, 3] = 0.2
    kin = UR5e(tcp)
    q = np.array([0.3, -1.2, 1.4, -1.9, -1.5, 0.4])
    jac = kin.jacobian(q)
    h = 1e-7
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        a, b = kin.forward(q + dq), kin.forward(q - dq)
        assert np.allclose((a[:3, 3] - b[:3, 3]) / (2 * h), jac[:3, i], atol=1e-6)
        rot = Rotation.from_matrix(a[:3, :3] @ b[:3, :3].T).as_rotvec() / (2 * h)
        assert np.allclose(rot, jac[3:, i], atol=1e-6)


def test_the_inverse_finds_reachable_poses_and_refuses_far_ones() -> None:
    tcp = np.eye(4)
    tcp[2, 3] = 0.2
    kin = UR5e(tcp)
    rng = np.random.default_rng(5)
    for _ in range(20):
        q = rng.uniform(-2.5, 2.5, 6)
        goal = kin.forward(q)
        found = kin.inverse(goal, q + rng.normal(0.0, 0.15, 6))
        assert found is not None
        assert np.allclose(kin.forward(found), goal, atol=1e-4)
    far = np.eye(4)
    far[:3, 3] = (1.6, 0.0, 0.3)  # twice the UR5e's reach
    assert kin.inverse(far) is None
    with pytest.raises(ValueError, match="6 joints"):
        kin.forward([0.0] * 5)


def test_the_rotation_vector_matches_scipys_to_the_half_turn() -> None:
    from heapgrasp.sim.rehearsal.ur5e import _rotvec

    rng = np.random.default_rng(1)
    for i in range(500):
        v = Rotation.random(random_state=rng).as_rotvec()
        if i % 3 == 0:  # within a hair of a half turn, where the log map is delicate
            v = v / np.linalg.norm(v) * (math.pi - 10 ** rng.uniform(-9, -2))
        if i % 5 == 0:  # and near no rotation at all
            v = v * 1e-8
        assert np.allclose(_rotvec(Rotation.from_rotvec(v).as_matrix()), v, atol=1e-7)


def test_the_controller_offers_only_what_ur_rtde_has() -> None:
    for sim, real in (
        (SimControl, rtde_control.RTDEControlInterface),
        (SimReceive, rtde_receive.RTDEReceiveInterface),
    ):
        names = [n for n in vars(sim) if not n.startswith("_")]
        missing = [n for n in names if not hasattr(real, n)]
        assert not missing, f"{sim.__name__} offers what ur_rtde lacks: {missing}"


# ---------------------------------------------------------------- the rig


def _template(tmp_path: Path, *, fps: int = 30) -> Path:
    """``robot init``'s file, the camera at ``fps`` (fewer frames render faster)."""
    path = tmp_path / "robot.toml"
    assert main(["robot", "init", str(path)]) == 0
    path.write_text(path.read_text().replace("fps = 30", f"fps = {fps}"))
    return path


def test_the_rig_places_its_scene_and_answers_as_a_controller(tmp_path: Path) -> None:
    robot, cfg = load(_template(tmp_path), simulated=True)
    with Rehearsal(robot, cfg, seed=2, objects=3) as rig:
        assert 1 <= len(rig.placed) <= 3
        d = rig.drivers()
        assert d.hand == PANDA_HAND and d.scene is rig
        control, receive = d.arm("", robot.arm.tcp)  # no host needed
        start = np.asarray(rig.hand.tcp).copy()
        # the controller reports the hand's pose in its base frame
        tcp_base = np.linalg.inv(BASE2WORLD) @ start
        assert np.allclose(receive.getActualTCPPose()[:3], tcp_base[:3, 3], atol=1e-9)
        # a blocking moveL takes its time on the world's clock and gets there
        goal = tcp_base.copy()
        goal[2, 3] += 0.05
        t0 = receive.getTimestamp()
        from heapgrasp.robot.ur import pose_to_rtde

        assert control.moveL(pose_to_rtde(goal), 0.1, 1.0)
        assert receive.getTimestamp() - t0 >= 0.05 / 0.1
        assert np.allclose(receive.getActualTCPPose()[:3], goal[:3, 3], atol=1e-6)
        # a pose out of the UR5e's reach is refused, not moved to
        far = goal.copy()
        far[:3, 3] = (2.0, 0.0, 0.5)
        assert not control.isPoseWithinSafetyLimits(pose_to_rtde(far))
        assert not control.moveL(pose_to_rtde(far), 0.1, 1.0)
        assert control.getInverseKinematics(pose_to_rtde(far)) == []
        # the camera renders where the true extrinsic puts it, on the controller's clock
        from heapgrasp.robot.hardware import camera_settings

        cam = d.camera(camera_settings(robot))
        cam.start()
        shot = cam.wait(1.0)
        assert shot.rgb.shape == (robot.camera.height, robot.camera.width, 3)
        assert math.isclose(shot.time, receive.getTimestamp())
        assert np.allclose(rig.true_camera(), rig.hand.tcp @ TRUE_CAM2TCP)
        assert rig.silhouettes.silhouette(type("F", (), {"time": shot.time})()).any()
        with pytest.raises(Exception, match="no silhouette"):
            rig.silhouettes.silhouette(type("F", (), {"time": -1.0})())
    with pytest.raises(ValueError, match="at least 1"):
        Rehearsal(robot, cfg, objects=0)


# ---------------------------------------------------------------- end to end


def test_the_whole_robot_path_rehearses_from_the_command_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    toml = _template(tmp_path, fps=15)
    config = ["--config", str(toml), "--sim"]
    # before calibrating: check says so, and a run is refused naming the fix
    assert main(["robot", "check", *config]) == 1
    out = capsys.readouterr().out
    assert "FAIL calibration" in out and "ok   arm" in out and "ok   camera" in out
    assert main(["robot", "run", *config, "--out", str(tmp_path / "early")]) == 2
    assert "robot calibrate" in capsys.readouterr().err

    # the calibration finds the rig's true extrinsic and base from the board
    assert main(["robot", "calibrate", *config, "--out", str(tmp_path / "cal")]) == 0
    assert "\n[calibration]" not in toml.read_text()  # a dry calibration writes nothing
    assert main(["robot", "calibrate", *config, "--execute", "--out", str(tmp_path / "cal")]) == 0
    robot, _ = load(toml, simulated=True)
    cal = robot.calibration
    assert cal.cam2tcp is not None and cal.world2base is not None
    assert np.linalg.norm(cal.cam2tcp[:3, 3] - TRUE_CAM2TCP[:3, 3]) < 0.002
    assert np.linalg.norm(cal.world2base[:3, 3] - np.linalg.inv(BASE2WORLD)[:3, 3]) < 0.003
    assert main(["robot", "check", *config]) == 0
    capsys.readouterr()

    # a dry run moves nothing; views the UR5e cannot reach are skipped, not fatal
    dry = tmp_path / "dry"
    assert main(["robot", "run", *config, "--no-viz", "--out", str(dry)]) == 0
    result = json.loads((dry / "dry_run.json").read_text())
    assert result["rehearsal"] and result["motion_commands_sent"] == 0
    assert not result["refused"]

    # an executed run: the protocol on the simulated arm, with the simulator's account
    run = tmp_path / "run"
    argv = ["robot", "run", *config, "--execute", "--objects", "2", "--seed", "4"]
    assert main([*argv, "--out", str(run)]) == 0
    printed = capsys.readouterr().out
    assert "the simulator:" in printed
    record = json.loads((run / "scenes.jsonl").read_text().splitlines()[0])
    truth = record["rehearsal"]
    assert truth["objects_placed"] == record["objects_total"]
    succeeded = sum(p["outcome"] == "success" for p in record["phases"])
    assert truth["objects_removed"] == succeeded  # each success went into the bin
    assert json.loads((run / "robot.json").read_text())["hand"] == "panda"
    summary = json.loads((run / "results.json").read_text())
    assert summary["grasps_succeeded"] == succeeded
    # the folder reads as a simulated run's: a summary page and its figure
    assert "success (%)" in (run / "summary.md").read_text()
    assert (run / "summary.png").stat().st_size > 0

    # replay plans every phase again from the recorded frames and silhouettes: the same
    # grasps where nothing changed
    assert main(["robot", "replay", str(run)]) == 0
    replayed = json.loads((run / "replay.json").read_text())
    assert replayed["phases_replayed"] == len(record["phases"])
    moved = [r["grasp_moved_m"] for r in replayed["phases"] if r["grasp_moved_m"] is not None]
    assert moved and max(moved) < 1e-6
    # show records the replanned phases for the viewer
    pytest.importorskip("rerun")
    assert main(["show", str(run)]) == 0
    assert (run / "viz" / "scene-000.rrd").stat().st_size > 0
    assert main(["show", str(run), "--scene", "3"]) == 2


def test_a_real_run_cannot_be_replayed_with_the_simulators_silhouettes(tmp_path: Path) -> None:
    # a rehearsal's recording replays with truth; the real robot's (no silhouettes) names
    # the fix
    from heapgrasp.real.recording import Recorded, RecordedSilhouettes

    empty = RecordedSilhouettes([Recorded("look", [], 0.0, tmp_path / "x.npz")])
    assert not empty
    with pytest.raises(RobotConfigError, match="no recorded silhouette"):
        empty.silhouette(type("F", (), {"time": 1.0})())  # type: ignore[arg-type]


def test_a_rehearsal_refuses_what_a_robot_toml_gets_wrong(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    toml = _template(tmp_path)
    assert main(["robot", "run", "--config", str(toml), "--sim", "--objects", "0"]) == 2
    assert "--objects must be at least 1, got 0" in capsys.readouterr().err
    toml.write_text(toml.read_text().replace('view_planner = "network"', 'view_planner = "x"'))
    assert main(["robot", "run", "--config", str(toml), "--sim"]) == 2
    assert "view_planner" in capsys.readouterr().err


def test_a_robot_run_killed_outright_loses_nothing_and_mixes_nothing(tmp_path: Path) -> None:
    # kill -9 mid-run records nothing for that run; its frames were left where the next
    # run writes its own, and a replay mixed them in. Now they are set aside, the next run
    # records cleanly, and the folder replays.
    import os
    import random
    import signal
    import subprocess
    import sys

    toml = _template(tmp_path, fps=15)
    with toml.open("a") as f:  # the rig's true calibration, as `calibrate --sim` finds it
        f.write(
            f"\n[calibration]\ncam2tcp = {TRUE_CAM2TCP.tolist()}\n"
            f"world2base = {np.linalg.inv(BASE2WORLD).tolist()}\n"
        )
    run = tmp_path / "run"
    argv = [sys.executable, "-m", "heapgrasp", "robot", "run", "--config", str(toml), "--sim"]
    argv += ["--execute", "--objects", "1", "--resume", "--out", str(run)]
    rng = random.Random(0)
    for _ in range(2):
        proc = subprocess.Popen(
            argv, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        try:
            proc.wait(timeout=rng.uniform(6.0, 10.0))
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    done = subprocess.run(argv, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = (run / "scenes.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]  # every line whole
    assert records and records[-1].get("stop_reason")
    frames = run / "frames"
    aside = sorted(p.name for p in frames.iterdir() if ".unrecorded-" in p.name)
    recorded = sorted(p.name for p in frames.iterdir() if ".unrecorded-" not in p.name)
    assert recorded == [f"scene_{r['scene']:03d}" for r in records]
    assert len(aside) + len(records) >= 1
    assert all(
        r.get("frames_set_aside") in (None, *[f"frames/{a}" for a in aside]) for r in records
    )
    assert main(["robot", "replay", str(run)]) == 0
    replayed = json.loads((run / "replay.json").read_text())
    assert replayed["phases_replayed"] == sum(len(r["phases"]) for r in records)
