"""``heapgrasp robot run``: the dry run (the default) and the executed clutter removal.

**Dry run** (:func:`dry_run`): connects every device, activates nothing and sends no
motion. The arm stands where it is; every frame is what the camera sees from there. The
loop plans its first phase as it would (HEAPGrasp §IV: the grid, the view waypoints of
eq. 18, the grasp of eq. 16) and every motion it asks for is *checked* instead of sent:
the start pose, each timed camera path (the workspace box, the speed caps, the joint
speeds from the controller's inverse kinematics) and the grasp's pre-grasp and grasp
poses. A refused camera path is a view the loop would skip (``skipped_views``); any
other refusal (``refused``) would stop the run. It writes ``dry_run.json`` (each check,
the waypoints, the grasp), the frames, and
a Rerun recording of the phase (grid, views, grasp) where ``rerun-sdk`` is installed.

**Executed run** (:func:`execute`, ``--execute``): the clutter-removal protocol of §VI-C
(:func:`heapgrasp.loop.protocol.run_clutter_removal`) on the arm; the operator says how
many objects were placed (rule (i) needs a count the robot cannot see). It writes what
the simulator writes — ``config.json``, ``scenes.jsonl`` (one record per run, appended
and synced), ``results.json`` — plus ``robot.json`` (the robot config) and every frame
(:mod:`heapgrasp.real.recording`). A device error, a protective stop or Ctrl-C stops
the arm; the record of that run keeps the error and every phase planned so far, and the
frames stay on disk. ``--resume`` appends the next run to the same directory.

**Rehearsal** (``--sim``): the same two functions with the simulator's drivers
(:class:`~heapgrasp.robot.hardware.Drivers` with a ``scene``, :mod:`heapgrasp.sim.rehearsal`):
the planners plan for the drivers' hand, the frames are recorded with their exact
silhouettes, and an executed run's record gains ``rehearsal``, what the simulator saw
become of the objects.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.motion import TimedPath
from heapgrasp.loop.config import RunConfig
from heapgrasp.loop.protocol import PlanResult, run_clutter_removal
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.real.recording import ArmWrapper, RecordingArm
from heapgrasp.real.stages import load, open_networks, real_pipeline
from heapgrasp.results.records import RunDir, write_json
from heapgrasp.results.summary import summarize
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import RobotConfigError, RobotError
from heapgrasp.robot.grasping import PREGRASP_DISTANCE, translate
from heapgrasp.robot.hardware import Drivers, HardwareRobot, hand_name
from heapgrasp.robot.interfaces import Contact, UnreachableError
from heapgrasp.robot.ur import URArm, continuous_roll

__all__ = ["DryRunArm", "dry_run", "execute", "robot_record"]

F64 = npt.NDArray[np.float64]

ROBOT_FILE = "robot.json"
DRY_RUN_FILE = "dry_run.json"


@dataclass
class _Robot:
    arm: Any
    gripper: Any


class DryRunArm(ArmWrapper):
    """The arm of a dry run: checks every motion the loop asks for and sends none.

    :meth:`look` and :meth:`follow` return the frame the camera sees where the arm
    stands (a follow returns it twice: the loop carves the frames after the first, and
    reads where the camera ended from the last)."""

    def __init__(self, arm: URArm) -> None:
        super().__init__(arm)
        self.arm: URArm = arm
        self.checks: list[dict[str, Any]] = []

    def _log(self, kind: str, ok: bool, detail: str = "", **extra: Any) -> None:
        self.checks.append({"motion": kind, "ok": ok, "detail": detail, **extra})

    def check_pose(self, kind: str, tcp: F64, *, straight_from_here: bool = False) -> bool:
        """Checks a TCP pose (and the straight move there) against the box and reach."""
        try:
            poses = self.arm.straight_poses(self.arm.tcp, tcp) if straight_from_here else tcp
            self.arm.check_poses(poses)
            self.arm.check_reachable(tcp)
        except UnreachableError as exc:
            self._log(kind, False, str(exc), position=tcp[:3, 3].tolist())
            return False
        self._log(kind, True, position=tcp[:3, 3].tolist())
        return True

    def park(self) -> None:
        self.check_pose("park", self.arm.park_pose())

    def _here(self) -> Frame:
        return self.arm.still_frame()

    def look(self, cam2world: F64) -> Frame:
        goal = continuous_roll(np.asarray(cam2world)[None], self.arm.tcp @ self.arm.cam2tcp)[0]
        tcp = goal @ np.linalg.inv(self.arm.cam2tcp)
        if not self.check_pose("look", tcp, straight_from_here=True):
            raise UnreachableError(self.checks[-1]["detail"])
        return self._here()

    def follow(self, path: TimedPath) -> Capture:
        try:
            times, _, slowed = self.arm.plan_path(path)
        except UnreachableError as exc:
            self._log("path", False, str(exc), end=path.poses[-1][:3, 3].tolist())
            raise
        self._log(
            "path",
            True,
            end=path.poses[-1][:3, 3].tolist(),
            duration_s=path.duration * slowed,
            slowdown=slowed,
            samples=len(times),
        )
        frame = self._here()
        return Capture(np.array([frame.time, frame.time]), [frame, frame], duration=0.0)

    def move_to(self, tcp: F64, *, opening: float) -> None:
        raise RobotError("a dry run never moves (move_to)")

    def move_linear(self, tcp: F64, *, speed: float = 0.1, stop_on_contact: bool = False) -> bool:
        raise RobotError("a dry run never moves (move_linear)")

    def contact(self) -> Contact | None:
        return None


def _viz(out: Path, config: RunConfig) -> Any:
    """A Rerun recorder of the phase where rerun-sdk is installed; else None."""
    try:
        from heapgrasp.geometry.grid import GridFrame
        from heapgrasp.viz.recorder import RerunRecorder

        grid = GridFrame((0.0, 0.0, 0.0), config.cube_size, config.resolution)
        return RerunRecorder(out / "dry_run.rrd", grid, config.lam, name="dry-run")
    except ImportError:
        return None


def dry_run(
    config_path: str | Path, out: str | Path, *, drivers: Drivers | None = None, viz: bool = True
) -> dict[str, Any]:
    """Plans one phase on the robot without moving it (see the module docstring) and
    returns what ``dry_run.json`` holds."""
    d = drivers or Drivers()
    robot_cfg, cfg = load(config_path, simulated=d.scene is not None)
    networks = open_networks(cfg, d.hand, d.scene)  # every file checked before a device
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    recorder = _viz(out, cfg) if viz else None
    t0 = time.perf_counter()
    with HardwareRobot.connect(robot_cfg, d, activate=False) as hw:
        dry = DryRunArm(hw.arm)
        rec = RecordingArm(dry, out / "frames", 0, d.scene)
        robot = _Robot(rec, hw.gripper)
        pipeline = real_pipeline(cfg, robot, networks=networks, observer=recorder)
        rec.begin_phase()
        stopped: str | None = None
        plan: PlanResult | None = None
        try:
            plan = pipeline.plan()
        except UnreachableError as exc:  # the first look is refused: nothing to plan from
            stopped = str(exc)
        finally:
            if recorder is not None:
                recorder.close()
        grasp: dict[str, Any] | None = None
        if plan is not None and plan.grasp is not None:
            pose = plan.grasp.pose
            pre = pose @ translate(0.0, 0.0, -PREGRASP_DISTANCE)
            dry.check_pose("pregrasp", pre)
            dry.check_pose("grasp", pose)
            dry.check_pose("bin", robot_cfg.workspace.bin_pose())
            grasp = {"pose": pose.tolist(), "width": plan.grasp.width}
        sent = hw.arm.commands
    result = {
        "moved": sent > 0,
        "motion_commands_sent": sent,
        "config": str(config_path),
        "rehearsal": d.scene is not None,
        "method": cfg.method,
        "grasp": grasp,
        "checks": dry.checks,
        # a refused camera path is a view the loop skips; any other refusal stops a run
        "refused": [c for c in dry.checks if not c["ok"] and c["motion"] != "path"],
        "skipped_views": [c for c in dry.checks if not c["ok"] and c["motion"] == "path"],
        "frames": len(rec.saved),
        "stopped": stopped,
        "waypoints": [] if plan is None else plan.extra.get("waypoints", []),
        "target_grasp": None if plan is None else plan.extra.get("target_grasp"),
        # where the phase found no grasp and looked again (RunConfig.look_again)
        "looked_again": [] if plan is None else plan.extra.get("looked_again", []),
        "wall_time_s": time.perf_counter() - t0,
        "rerun": str(out / "dry_run.rrd") if recorder is not None else None,
    }
    write_json(out / DRY_RUN_FILE, _plain(result))
    return result


def _plain(data: Any) -> Any:
    """``data`` with numpy values as plain Python (JSON-ready)."""
    return json.loads(json.dumps(data, default=lambda o: np.asarray(o).tolist()))


def robot_record(robot: RobotConfig, drivers: Drivers | None = None) -> dict[str, Any]:
    """The robot config as plain data (``robot.json``), with the hand the planners
    planned for and whether the devices were a rehearsal's."""
    d = drivers or Drivers()
    data = dataclasses.asdict(robot)
    data["hand"] = hand_name(d.hand)
    data["rehearsal"] = d.scene is not None
    return _plain(data)  # type: ignore[no-any-return]


@dataclass
class _Planned:
    """What the phases planned so far (kept if the run stops half-way)."""

    phases: list[dict[str, Any]] = field(default_factory=list)

    def add(self, plan: PlanResult) -> None:
        g = plan.grasp
        self.phases.append(
            {
                "grasp_position": None if g is None else g.pose[:3, 3].tolist(),
                "outcome": None,
                "camera_path": np.asarray(plan.camera_positions).tolist(),
                **_plain(plan.extra),
            }
        )


def _set_aside(frames: Path) -> Path | None:
    """Frames under the next run's folder that no record claims — a run killed outright
    (``kill -9``, a power cut) records nothing — renamed beside it, so that the new run's
    frames are not mixed with them and nothing is lost; returns the new name."""
    if not frames.exists():
        return None
    for n in range(1, 10_000):
        aside = frames.with_name(f"{frames.name}.unrecorded-{n}")
        if not aside.exists():
            frames.rename(aside)
            return aside
    raise RobotConfigError(f"{frames}: too many unrecorded runs set aside beside it")


def execute(
    config_path: str | Path,
    out: str | Path,
    *,
    objects: int,
    resume: bool = False,
    drivers: Drivers | None = None,
) -> dict[str, Any]:
    """Runs the clutter-removal protocol on the robot and returns the run's record
    (see the module docstring). Raises the :class:`RobotError` that stopped it, after
    writing the record."""
    if objects < 1:
        raise RobotConfigError(f"--objects must be at least 1, got {objects}")
    d = drivers or Drivers()
    robot_cfg, cfg = load(config_path, simulated=d.scene is not None)
    networks = open_networks(cfg, d.hand, d.scene)  # every file checked before a device
    rundir = RunDir(out)
    rundir.path.mkdir(parents=True, exist_ok=True)
    with rundir:
        saved = rundir.read_config()
        records = rundir.records()
        if records and not resume:
            raise RobotConfigError(
                f"{rundir.path} already holds {len(records)} run(s); pass --resume to add "
                "one, or choose another --out"
            )
        scene = len(records)
        # the folder's run count: each executed run is a scene of the folder's records
        cfg = cfg.replace({"scenes": scene + 1}, source="the robot run's count")
        if resume and saved is not None and saved.replace({"scenes": cfg.scenes}) != cfg:
            raise RobotConfigError(
                f"--resume: the settings differ from {rundir.config_file} ({saved.changes_to(cfg)})"
            )
        rundir.write_config(cfg)
        write_json(rundir.path / ROBOT_FILE, robot_record(robot_cfg, d))
        aside = _set_aside(rundir.path / "frames" / f"scene_{scene:03d}")
        planned = _Planned()
        t0 = time.perf_counter()
        record: dict[str, Any] = {
            "scene": scene,
            "seed": None,
            "category": "real",
            "objects_requested": objects,
            "objects_total": objects,
            "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        }
        if aside is not None:
            record["frames_set_aside"] = str(aside.relative_to(rundir.path))
        failure: BaseException | None = None
        try:
            with HardwareRobot.connect(robot_cfg, d) as hw:
                rec = RecordingArm(hw.arm, rundir.path / "frames", scene, d.scene)
                robot = _Robot(rec, hw.gripper)
                pipeline = real_pipeline(cfg, robot, networks=networks)

                def plan() -> PlanResult:
                    rec.begin_phase()
                    result = pipeline.plan()
                    planned.add(result)
                    return result

                def outcome(grasp: Any, result: Any) -> None:
                    planned.phases[-1]["outcome"] = str(result)
                    pipeline.record_outcome(grasp, result)

                phases, reason = run_clutter_removal(
                    robot,
                    plan,
                    max_attempts=cfg.max_attempts,
                    on_outcome=outcome,
                    bin_pose=robot_cfg.workspace.bin_pose(),
                )
                record.update(
                    stop_reason=reason.value,
                    phases=[p.to_dict() for p in phases],
                    motion_commands=hw.arm.commands,
                    path_slowdowns=hw.arm.slowdowns,
                )
        except (RobotError, KeyboardInterrupt) as exc:
            failure = exc
            record["error"] = f"{type(exc).__name__}: {exc}"
            record["phases_planned"] = planned.phases
        if d.scene is not None:
            record["rehearsal"] = d.scene.report()
        record["wall_time_s"] = time.perf_counter() - t0
        record["frames_dir"] = f"frames/scene_{scene:03d}"
        rundir.append(_plain(record))
        write_json(rundir.results_file, _plain(summarize(cfg, rundir.records())))
    if failure is not None:
        raise failure
    return record
