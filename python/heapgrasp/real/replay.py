"""``heapgrasp robot replay RUN_DIR``: perception and planning rerun on a recorded real run.

Each recorded phase is planned again from its saved frames with the run's settings,
changed by ``--set`` (a segmentation network, λ, the grasp planner, the critic …): the
replayed arm (:class:`ReplayArm`) hands the pipeline the phase's recorded look and
captures in the order they were taken, whatever pose it asks for, and notes how far the
asked-for views are from the recorded ones. Grasp memory follows the recording (each
phase's recorded outcome is told to the pipeline), so phase ``k`` is planned as the
robot would have planned it after the same history.

The result says, per phase, which grasp the changed settings pick and how far it is
from the grasp the robot executed (and how that ended). Views the new settings would
have taken elsewhere cannot be seen; where they differ, the replay is only as good as
the recorded frames, and ``view_offsets_m`` says by how much.

A rehearsal's recording (``robot run --sim --execute``) holds each frame's exact
silhouette: where the run's (changed) settings segment with the simulator's
silhouettes (``segmenter = "truth"``), the replay segments with the recorded ones; the
planners plan for the hand the run used (``robot.json``'s ``hand``).
"""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.gripper import ROBOTIQ_2F140, GripperGeometry, gripper_named
from heapgrasp.geometry.motion import TimedPath
from heapgrasp.loop.config import RunConfig
from heapgrasp.loop.methods import method_of
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.perception.segmenters import Segmenter
from heapgrasp.real.recording import Recorded, RecordedSilhouettes, load_phase, phase_dirs
from heapgrasp.real.stages import make_segmenter, real_pipeline
from heapgrasp.results.records import RunDir, write_json
from heapgrasp.robot.errors import RobotConfigError
from heapgrasp.robot.grasping import Grasp
from heapgrasp.robot.interfaces import Contact, UnreachableError

__all__ = ["ReplayArm", "replay"]

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class _Camera:
    spec: CameraSpec
    depth: bool


class ReplayArm:
    """Serves a recorded phase's frames to the pipeline (see the module docstring)."""

    def __init__(self, items: list[Recorded]) -> None:
        if not items or not items[0].frames:
            raise RobotConfigError("a recorded phase has no frames")
        first = items[0].frames[0]
        self._camera = _Camera(first.camera, first.depth is not None)
        self.items = deque(items)
        self.view_offsets: list[float] = []
        self.beyond = 0
        self._clock = first.time
        self._tcp = np.eye(4)

    @property
    def camera(self) -> _Camera:
        return self._camera

    @property
    def clock(self) -> float:
        return self._clock

    @property
    def tcp(self) -> F64:
        return self._tcp

    def park(self) -> None:
        pass

    def _next(self, asked: F64) -> Recorded:
        if not self.items:
            self.beyond += 1
            raise UnreachableError("the recording holds no more frames for this phase")
        item = self.items.popleft()
        end = item.frames[-1].cam2world if item.frames else asked
        self.view_offsets.append(float(np.linalg.norm(end[:3, 3] - asked[:3, 3])))
        if item.frames:
            self._clock = item.frames[-1].time
        return item

    def look(self, cam2world: F64) -> Frame:
        item = self._next(cam2world)
        return item.frames[0]

    def follow(self, path: TimedPath) -> Capture:
        return self._next(path.poses[-1]).capture()

    def move_to(self, tcp: F64, *, opening: float) -> None:
        raise RobotConfigError("a replay never moves")

    def move_linear(self, tcp: F64, *, speed: float = 0.1, stop_on_contact: bool = False) -> bool:
        raise RobotConfigError("a replay never moves")

    def contact(self) -> Contact | None:
        return None


@dataclass
class _Gripper:
    """The recorded run's hand (its shape is all the planners read)."""

    geometry: GripperGeometry = ROBOTIQ_2F140

    def open(self) -> None:
        raise RobotConfigError("a replay never moves")

    def close(self, width: float | None = None) -> None:
        raise RobotConfigError("a replay never moves")

    def holding(self) -> bool:
        return False


@dataclass
class _Robot:
    arm: ReplayArm
    gripper: _Gripper


def _distance(a: Any, b: Any) -> float | None:
    if a is None or b is None:
        return None
    return float(np.linalg.norm(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)))


def _hand(run_dir: Path) -> GripperGeometry:
    """The hand the run planned for (``robot.json``'s ``hand``; a run recorded before
    it was written used the Robotiq 2F-140)."""
    try:
        name = json.loads((run_dir / "robot.json").read_text()).get("hand")
    except (OSError, ValueError, AttributeError):
        name = None
    if not isinstance(name, str):
        return ROBOTIQ_2F140
    try:
        return gripper_named(name)
    except ValueError as exc:
        raise RobotConfigError(f"{run_dir / 'robot.json'}: {exc}") from None


def _needs_silhouettes(config: RunConfig) -> bool:
    """Whether ``config`` segments with the simulator's silhouettes (a rehearsal's)."""
    return method_of(config).true_silhouettes


def replay(
    run_dir: str | Path,
    changes: Mapping[str, Any] | None = None,
    *,
    out: str | Path | None = None,
    observer: Any = None,
    scenes: Sequence[int] | None = None,
) -> dict[str, Any]:
    """Replays every recorded phase of ``run_dir`` with the run's settings changed by
    ``changes``; writes the result to ``out`` (default ``RUN_DIR/replay.json``) and
    returns it. ``observer``: a phase observer (``heapgrasp show`` passes its Rerun
    recorder); ``scenes``: only these runs of the directory (default all)."""
    rundir = RunDir(run_dir)
    saved = rundir.read_config()
    if saved is None:
        raise RobotConfigError(f"{rundir.path}: no config.json; is this a `robot run` directory?")
    if not (rundir.path / "frames").is_dir():
        raise RobotConfigError(
            f"{rundir.path}: no recorded frames (frames/): replay reruns a robot run "
            "(`heapgrasp robot run --execute --out DIR`), which records every frame; a "
            "simulated run (`heapgrasp run`) records none — run it again with other "
            "settings instead"
        )
    config = saved.replace(dict(changes or {}), source="--set")
    records = rundir.records()
    if scenes is not None:
        records = [r for r in records if int(r["scene"]) in set(scenes)]
    hand = _hand(rundir.path)
    frames_dir = rundir.path / "frames"
    rows: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    for record in records:
        scene = int(record["scene"])
        recorded = record.get("phases") or record.get("phases_planned") or []
        dirs = phase_dirs(frames_dir, scene)
        if len(dirs) < len(recorded):
            raise RobotConfigError(
                f"{frames_dir / f'scene_{scene:03d}'}: {len(recorded)} phase(s) recorded, "
                f"the frames of {len(dirs)} there: replay needs every phase's frames"
            )
        pipeline = None
        silhouettes = RecordedSilhouettes([])
        segmenter: Segmenter | None = None
        if _needs_silhouettes(config):
            segmenter = make_segmenter(config, silhouettes)
        for k, phase_dir in enumerate(dirs):
            items = load_phase(phase_dir)
            silhouettes.replace(items)
            if segmenter is not None and items and not silhouettes:
                raise RobotConfigError(
                    f"{phase_dir}: segmenter = {config.segmenter!r} needs the simulator's "
                    "silhouettes, which only a rehearsal (`robot run --sim`) records; replay "
                    "a real run with --set segmenter=network --set seg_weights=FILE"
                )
            if not items or not items[0].frames:
                continue
            seen = recorded[k].get("frames") if k < len(recorded) else None
            served = sum(len(item.frames) for item in items)
            if isinstance(seen, int) and served < seen:
                raise RobotConfigError(
                    f"{phase_dir}: {seen} frames were recorded, {served} are there: replay "
                    "needs every frame the phase saw"
                )
            arm = ReplayArm(items)
            if pipeline is None:
                pipeline = real_pipeline(
                    config,
                    _Robot(arm, _Gripper(hand)),
                    segmenter=segmenter,
                    observer=observer,
                )
            pipeline.robot = _Robot(arm, _Gripper(hand))
            plan = pipeline.plan()
            before = recorded[k] if k < len(recorded) else {}
            new = None if plan.grasp is None else plan.grasp.pose[:3, 3].tolist()
            rows.append(
                {
                    "scene": scene,
                    "phase": k,
                    "recorded_grasp": before.get("grasp_position"),
                    "recorded_outcome": before.get("outcome"),
                    "replayed_grasp": new,
                    "replayed_width": None if plan.grasp is None else plan.grasp.width,
                    "grasp_moved_m": _distance(new, before.get("grasp_position")),
                    "frames_used": int(plan.extra.get("frames", 0)),
                    "view_offsets_m": arm.view_offsets,
                    "views_beyond_recording": arm.beyond,
                    "compute_time_s": plan.compute_time,
                }
            )
            pos, outcome = before.get("grasp_position"), before.get("outcome")
            if pos is not None and outcome:
                pose = np.eye(4)
                pose[:3, 3] = pos
                pipeline.record_outcome(Grasp(pose, 0.0), outcome)
    moved = [r["grasp_moved_m"] for r in rows if r["grasp_moved_m"] is not None]
    result = {
        "run": str(rundir.path),
        "changes": saved.changes_to(config),
        "phases": rows,
        "phases_replayed": len(rows),
        "same_grasp_within_1cm": sum(1 for m in moved if m <= 0.01),
        "grasp_moved_m_mean": float(np.mean(moved)) if moved else None,
        "wall_time_s": time.perf_counter() - t0,
    }
    target = Path(out) if out is not None else rundir.path / "replay.json"
    write_json(target, result)
    return result
