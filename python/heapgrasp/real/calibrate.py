"""``heapgrasp robot calibrate``: the hand-eye extrinsic and the workspace frame, on the arm.

The procedure (``docs/real_robot.md``, "Calibration"):

1. the operator lays the ChArUco board flat where the scene will be and jogs the arm so
   the camera sees the whole board from about 0.4 m;
2. from that first view the board's place is estimated (through the extrinsic guessed
   in ``[calibration] cam2tcp``, or a camera 10 cm behind the TCP);
3. :func:`~heapgrasp.robot.calibration.calibration_poses` spreads ``--poses`` TCP poses
   around the board (or ``--taught FILE`` lists poses taught on the pendant); a dry run
   (the default) checks each against the workspace box and the arm's reach and moves
   nothing; with ``--execute`` the arm visits each, rests, and takes a still frame;
4. :func:`~heapgrasp.robot.calibration.calibrate` detects the board, runs every method
   of ``cv2.calibrateHandEye`` and keeps the one with the smallest residual;
5. the result goes into ``robot.toml``'s ``[calibration]`` table (the rest of the file,
   comments included, is kept; the old file is saved as ``robot.toml.bak``), and the
   report, with every image, into the output directory.

The workspace (world) frame is the board's, turned face up, with its origin at the
board's bottom-left outer corner as printed (:func:`world_in_board`): the scene cube's
minimum corner sits there, the cube over the board. Remove the board before a run.

``--synthetic`` rehearses steps 3-5 without hardware: the board images are rendered at
the generated poses through a known extrinsic, and the report says how well it was
recovered (``docs/benchmarks.md``).
"""

from __future__ import annotations

import datetime
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.results.records import write_json
from heapgrasp.robot.calibration import (
    CharucoBoard,
    HandEyeResult,
    calibrate,
    calibration_poses,
    detect_board,
    render_board,
    world_in_board,
)
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import DeviceError, RobotConfigError
from heapgrasp.robot.hardware import Drivers, camera_settings
from heapgrasp.robot.ur import URArm, pose_from_rtde

__all__ = [
    "DEFAULT_CAM2TCP",
    "calibrate_robot",
    "read_taught",
    "rehearse",
    "world_in_board",
    "write_calibration",
]

F64 = npt.NDArray[np.float64]

#: The extrinsic guessed where ``[calibration] cam2tcp`` is not set: the camera 10 cm
#: behind the TCP and 6 cm beside it, looking along the approach.
DEFAULT_CAM2TCP = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0.06], [0, 0, 1.0, -0.10], [0, 0, 0, 1.0]])


def read_taught(path: str | Path) -> list[F64]:
    """Taught calibration poses from a JSON file: a list of TCP poses in the base frame,
    each ``[x, y, z, rx, ry, rz]`` as the teach pendant shows them (m, rotation vector),
    at least 3. Errors name the file and the entry."""
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except FileNotFoundError:
        raise RobotConfigError(f"taught poses: {p} not found") from None
    except json.JSONDecodeError as exc:
        raise RobotConfigError(f"taught poses: {p} is not JSON: {exc}") from None
    if not isinstance(data, list) or len(data) < 3:
        raise RobotConfigError(f"taught poses: {p} must hold a list of at least 3 poses")
    out = []
    for i, entry in enumerate(data):
        ok = (
            isinstance(entry, list)
            and len(entry) == 6
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in entry)
            and all(math.isfinite(v) for v in entry)
        )
        if not ok:
            raise RobotConfigError(
                f"taught poses: {p} entry {i} must be [x, y, z, rx, ry, rz], got {entry!r}"
            )
        out.append(pose_from_rtde(entry))
    return out


def _mat(v: F64) -> list[list[float]]:
    return [[float(x) for x in row] for row in v]


def write_calibration(
    path: Path, result: HandEyeResult, world2base: F64, extra: dict[str, Any]
) -> Path:
    """Writes ``[calibration]`` into ``robot.toml`` (tomlkit keeps the rest of the file
    and its comments); the previous file is kept as ``robot.toml.bak``. Returns the
    backup's path."""
    try:
        import tomlkit
    except ImportError as exc:
        raise DeviceError(
            f"writing robot.toml needs tomlkit: pip install 'heapgrasp[robot]' ({exc})"
        ) from None
    text = path.read_text()
    doc = tomlkit.parse(text)
    table = tomlkit.table()
    table.add(tomlkit.comment(f"written by `heapgrasp robot calibrate` on {extra['date']}"))
    table["cam2tcp"] = _mat(result.cam2tcp)
    table["world2base"] = _mat(world2base)
    table["method"] = result.method
    table["residual_mm_mean"] = float(np.mean(result.residuals_mm))
    table["residual_mm_max"] = float(np.max(result.residuals_mm))
    table["residual_deg_max"] = float(np.max(result.residuals_deg))
    for key, value in extra.items():
        table[key] = value
    doc["calibration"] = table
    backup = path.with_name(path.name + ".bak")
    backup.write_text(text)
    path.write_text(tomlkit.dumps(doc))
    RobotConfig.load(path)  # what was written reads back
    return backup


def _report(result: HandEyeResult, observations: list[Any], poses: int) -> dict[str, Any]:
    return {
        "result": result.to_dict(),
        "images": poses,
        "detected": sum(1 for o in observations if o is not None),
        "corners": [None if o is None else o.corners for o in observations],
        "reprojection_px": [None if o is None else o.reprojection_px for o in observations],
    }


def rehearse(
    out: Path,
    *,
    poses: int = 15,
    board: CharucoBoard | None = None,
    camera: CameraSpec | None = None,
    seed: int = 0,
) -> dict[str, Any]:
    """The calibration without hardware: board images rendered at generated poses
    through a known extrinsic (the default guess turned by 3° and moved by 7 mm), then
    recovered. Returns the report with the recovery error."""
    board = board or CharucoBoard()
    camera = camera or CameraSpec.still()
    rng = np.random.default_rng(seed)
    board2base = np.eye(4)
    board2base[:3, 3] = (0.45, -0.1, 0.02)
    truth = DEFAULT_CAM2TCP.copy()
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    from scipy.spatial.transform import Rotation

    truth[:3, :3] = Rotation.from_rotvec(axis * math.radians(3)).as_matrix() @ truth[:3, :3]
    truth[:3, 3] += rng.normal(size=3) * 0.004
    tcps = calibration_poses(board2base, DEFAULT_CAM2TCP, n=poses, seed=seed, board=board)
    images: list[npt.NDArray[np.uint8]] = []
    for tcp in tcps:
        board2cam = np.linalg.inv(tcp @ truth) @ board2base
        images.append(render_board(board, camera, board2cam, noise=2.0, seed=len(images)))
    result, observations = calibrate(images, tcps, board, camera)
    err_mm = 1000 * float(np.linalg.norm(result.cam2tcp[:3, 3] - truth[:3, 3]))
    rel = result.cam2tcp[:3, :3].T @ truth[:3, :3]
    err_deg = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(rel) - 1) / 2))))
    report = _report(result, observations, len(images))
    report.update(
        synthetic=True,
        truth_cam2tcp=_mat(truth),
        recovery_error_mm=err_mm,
        recovery_error_deg=err_deg,
    )
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "calibration.json", json.loads(json.dumps(report)))
    return report


def calibrate_robot(
    config_path: str | Path,
    out: str | Path,
    *,
    poses: int = 15,
    execute: bool = False,
    board: CharucoBoard | None = None,
    drivers: Drivers | None = None,
    seed: int = 0,
    taught: Sequence[F64] | None = None,
) -> dict[str, Any]:
    """Steps 1-5 of the module docstring on the robot; without ``execute`` the poses are
    generated and checked, nothing moves and nothing is written to ``robot.toml``.
    ``taught``: TCP poses (base frame, ``(4, 4)``) to visit instead of generated ones
    (:func:`read_taught`)."""
    path = Path(config_path)
    config = RobotConfig.load(path)
    board = board or CharucoBoard()
    d = drivers or Drivers()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    guess = (
        config.calibration.cam2tcp if config.calibration.cam2tcp is not None else DEFAULT_CAM2TCP
    )
    camera = d.camera(camera_settings(config))
    camera.start()
    control = receive = None
    try:
        control, receive = d.arm(config.arm.host, config.arm.tcp)
        first = camera.wait(config.camera.timeout)
        spec: CameraSpec = camera.spec
        distortion = getattr(camera, "distortion", None)
        seen = detect_board(first.rgb, board, spec, distortion)
        if seen is None:
            raise DeviceError(
                "the board is not in view: jog the arm so the camera sees the whole board "
                "from about 0.4 m, then run the command again"
            )
        tcp2base = pose_from_rtde(receive.getActualTCPPose())
        board2base = tcp2base @ guess @ seen.board2cam
        world2base = board2base @ world_in_board(board)
        provisional = RobotConfig(
            arm=config.arm,
            workspace=config.workspace,
            limits=config.limits,
            camera=config.camera,
            gripper=config.gripper,
            calibration=type(config.calibration)(guess, world2base, {}),
            networks=config.networks,
            method=config.method,
            source=config.source,
        )
        arm = URArm(control, receive, camera, provisional, clock=d.clock, sleep=d.sleep)
        targets = (
            list(taught)
            if taught is not None
            else calibration_poses(board2base, guess, n=poses, seed=seed, board=board)
        )
        checks: list[dict[str, Any]] = []
        for i, tcp_base in enumerate(targets):
            tcp_world = arm.base2world @ tcp_base
            try:
                arm.check_poses(
                    arm.straight_poses(
                        arm.tcp if i == 0 else arm.base2world @ targets[i - 1], tcp_world
                    )
                )
                arm.check_reachable(tcp_world)
                checks.append({"pose": i, "ok": True})
            except Exception as exc:
                checks.append({"pose": i, "ok": False, "detail": str(exc)})
        report: dict[str, Any] = {"poses": len(targets), "checks": checks, "executed": execute}
        if not execute:
            write_json(out / "calibration_plan.json", report)
            return report
        images: list[npt.NDArray[np.uint8]] = []
        reached: list[F64] = []
        lim = config.limits
        for i, tcp_base in enumerate(targets):
            if not checks[i]["ok"]:
                continue
            arm.move_l(arm.base2world @ tcp_base, min(0.1, lim.tool_speed), lim.tool_acceleration)
            frame = arm.still_frame()
            if frame.rgb is None:
                raise DeviceError("the camera delivered a frame without colour")
            images.append(frame.rgb)
            reached.append(pose_from_rtde(receive.getActualTCPPose()))
            np.save(out / f"image_{i:02d}.npy", images[-1])
        result, observations = calibrate(images, reached, board, spec, distortion=distortion)
        world2base = result.board2base @ world_in_board(board)
        report.update(_report(result, observations, len(images)))
        date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        extra = {
            "date": date,
            "board": f"{board.squares_x}x{board.squares_y} {board.square} m {board.dictionary}",
            "poses": len(images),
            "tcp": list(config.arm.tcp),
        }
        backup = write_calibration(path, result, world2base, extra)
        report.update(written=str(path), backup=str(backup))
        write_json(out / "calibration.json", json.loads(json.dumps(report)))
        return report
    finally:
        camera.stop()
        for iface in (control, receive):
            if iface is not None:
                try:
                    iface.disconnect()
                except Exception:
                    pass
