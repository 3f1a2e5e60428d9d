"""``robot.toml`` → the loop's settings, its segmenter, and the pipeline on hardware.

:func:`run_config` is the :class:`~heapgrasp.loop.config.RunConfig` a real run uses:
the defaults, ``[method]``, the files of ``[networks]`` (relative to ``robot.toml``) and
the camera's frame rate, then checked against what a real robot has:

* no scene truth: the oracle view planner and the simulator's segmenters are refused
  (the silhouette methods need ``[networks] segmentation``);
* the ``vgn`` baseline needs ``[camera] depth = true``;
* the camera paths' speed and acceleration (``max_velocity``, ``max_acceleration``) may
  not exceed ``[limits]`` (the arm would refuse every path).

A rehearsal (``simulated=True``, :mod:`heapgrasp.sim.rehearsal`) has the simulator's scene
truth: without ``[networks] segmentation`` its frames are segmented by their exact
silhouettes (``segmenter = "truth"``, with ``noise`` where set), as ``heapgrasp run``'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from heapgrasp.geometry.gripper import ROBOTIQ_2F140, GripperGeometry
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.methods import method_of
from heapgrasp.loop.phase import Pipeline
from heapgrasp.loop.stages import build_pipeline, make_critic, make_grasp_planner, make_view_scorer
from heapgrasp.loop.stages import make_segmenter as loop_segmenter
from heapgrasp.perception.segmenters import MaskSource, Segmenter
from heapgrasp.planning.critic import GraspCritic
from heapgrasp.planning.views import ViewScorer
from heapgrasp.planning.volumes import GraspPlanner
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import RobotConfigError
from heapgrasp.robot.interfaces import Robot

__all__ = ["Networks", "load", "make_segmenter", "open_networks", "real_pipeline", "run_config"]


def run_config(robot: RobotConfig, *, simulated: bool = False) -> RunConfig:
    """The loop's settings for ``robot`` (see the module docstring; ``simulated``: a
    rehearsal's); every problem is a :class:`RobotConfigError` naming the file and the
    key."""
    src = robot.source
    base = Path(src).parent if src.endswith(".toml") else Path.cwd()
    changes: dict[str, Any] = dict(robot.method)
    files = {
        "seg_weights": robot.networks.segmentation,
        "view_weights": robot.networks.view,
        "grasp_weights": robot.networks.grasp,
    }
    for key, value in files.items():
        if not value:
            continue
        if key in changes:
            raise RobotConfigError(f"{src}: [method] {key} and [networks] both name a file")
        p = Path(value).expanduser()
        changes[key] = str(p if p.is_absolute() else base / p)
    if robot.networks.segmentation:
        changes.setdefault("segmenter", "network")
    changes.setdefault("fps", float(robot.camera.fps))
    try:
        cfg = RunConfig().replace(changes, source=f"{src} [method]")
    except ConfigError as exc:
        raise RobotConfigError(str(exc)) from None
    method = method_of(cfg)
    if method.oracle_views:
        raise RobotConfigError(
            f"{src}: [method] view_planner = 'oracle' scores views on the true meshes, which "
            "only the simulator has; use 'network', 'circle' or 'hemisphere6'"
        )
    if method.depth:
        if not robot.camera.depth:
            raise RobotConfigError(
                f"{src}: the vgn baseline needs depth: set [camera] depth = true"
            )
    elif method.true_silhouettes and not simulated:
        raise RobotConfigError(
            f"{src}: a real camera's frames are segmented by the network: set [networks] "
            "segmentation to the ONNX file `heapgrasp seg train` wrote"
        )
    lim = robot.limits
    if cfg.max_velocity > lim.tool_speed:
        raise RobotConfigError(
            f"{src}: [method] max_velocity {cfg.max_velocity} m/s is above [limits] "
            f"tool_speed {lim.tool_speed}: the arm would refuse every camera path"
        )
    if cfg.max_acceleration > lim.tool_acceleration:
        raise RobotConfigError(
            f"{src}: [method] max_acceleration {cfg.max_acceleration} m/s² is above [limits] "
            f"tool_acceleration {lim.tool_acceleration}"
        )
    if cfg.mount != "free" or (cfg.noise > 0 and not simulated):
        raise RobotConfigError(
            f"{src}: [method] mount and noise are the simulator's settings; leave them out"
        )
    return cfg


def load(path: str | Path, *, simulated: bool = False) -> tuple[RobotConfig, RunConfig]:
    """Reads ``robot.toml`` and derives the loop's settings; both checked whole
    (``simulated``: for a rehearsal, :func:`run_config`)."""
    robot = RobotConfig.load(path)
    used = robot.calibration.report.get("tcp")
    if used is not None and list(used) != list(robot.arm.tcp):
        raise RobotConfigError(
            f"{robot.source}: [calibration] was measured with the TCP {list(used)}, but [arm] "
            f"tcp is {list(robot.arm.tcp)}: calibrate again (heapgrasp robot calibrate)"
        )
    return robot, run_config(robot, simulated=simulated)


def make_segmenter(config: RunConfig, truth: MaskSource | None = None) -> Segmenter | None:
    """The segmentation network of ``config`` (None for the depth baseline); with a
    rehearsal's ``truth``, the simulator's segmenters too."""
    if method_of(config).depth:
        return None
    try:
        return loop_segmenter(config, truth)
    except ConfigError as exc:
        raise RobotConfigError(f"[networks] segmentation: {exc}") from None


class _NoSegmenter:
    """The depth baseline segments nothing."""

    name = "none"

    def segment(self, frame: Any) -> Any:
        raise AssertionError("the vgn baseline does not segment")


@dataclass(frozen=True)
class Networks:
    """Every network file a run reads, opened and checked (:func:`open_networks`)."""

    segmenter: Segmenter | None
    grasp_planner: GraspPlanner
    view_scorer: ViewScorer | None
    critic: GraspCritic | None


def open_networks(
    config: RunConfig,
    gripper: GripperGeometry = ROBOTIQ_2F140,
    truth: MaskSource | None = None,
) -> Networks:
    """Opens the segmentation, grasp, view and critic files of ``config`` for a robot with
    ``gripper``, before any device is touched: a bad file is a
    :class:`~heapgrasp.robot.errors.RobotConfigError` naming it, with nothing activated.
    ``truth``: a rehearsal's silhouettes (:func:`make_segmenter`)."""
    segmenter = make_segmenter(config, truth)
    try:
        return Networks(
            segmenter,
            make_grasp_planner(config, gripper),
            make_view_scorer(config),
            make_critic(config),
        )
    except ConfigError as exc:
        raise RobotConfigError(f"[networks] {exc}") from None


def real_pipeline(
    config: RunConfig,
    robot: Robot,
    *,
    segmenter: Segmenter | None = None,
    observer: Any = None,
    networks: Networks | None = None,
) -> Pipeline:
    """The loop's pipeline on a real (or replayed) robot: no scene truth; ``networks``
    already opened (:func:`open_networks`), or opened here."""
    if networks is not None:
        segmenter = networks.segmenter
    seg = segmenter if segmenter is not None else make_segmenter(config)
    try:
        return build_pipeline(
            config,
            robot,
            segmenter=seg if seg is not None else _NoSegmenter(),
            observer=observer,
            grasp_planner=None if networks is None else networks.grasp_planner,
            view_scorer=None if networks is None else networks.view_scorer,
            critic=None if networks is None else networks.critic,
        )
    except ConfigError as exc:
        raise RobotConfigError(str(exc)) from None
