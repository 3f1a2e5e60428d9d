"""The one factory of the loop: a method's stages built once from a :class:`RunConfig`.

Names in the configuration (``method``, ``view_planner``, ``grasp_planner``,
``segmenter``, ``critic``) are read here and nowhere else in the loop:

* :func:`method_of` turns the method's name into a :class:`Method`, what the loop needs
  to know of it (what it senses, the grid its grasp planner reads, how it chooses its
  views); :class:`~heapgrasp.loop.phase.Pipeline`, the simulator's and the robot's
  set-up read that, not the names;
* :func:`make_segmenter`, :func:`make_grasp_planner`, :func:`make_view_scorer` and
  :func:`make_critic` build the stages, each an object that declares what it needs (a
  grasp planner its grid, σ, ε, whether its poses need the hull check:
  :class:`~heapgrasp.planning.volumes.GraspPlanner`);
* :func:`build_pipeline` assembles them on a robot; any stage may be passed in instead.

Adding a grasp planner is a class satisfying the protocol and a branch in
:func:`make_grasp_planner`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np

from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry
from heapgrasp.inference import Kind, resolve_device, shipped_grasp_network, shipped_weights
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.methods import Method, method_of
from heapgrasp.loop.observe import PhaseObserver
from heapgrasp.loop.phase import Pipeline
from heapgrasp.perception.segmenters import IdealSegmenter, MaskSource, NoisySegmenter, Segmenter
from heapgrasp.planning.critic import DEFAULT_CRITIC, GraspCritic
from heapgrasp.planning.views import OracleViewScorer, ViewScorer
from heapgrasp.planning.volumes import GraspPlanner
from heapgrasp.robot.interfaces import Robot, SceneTruth

if TYPE_CHECKING:
    from heapgrasp.planning.grasp_network import NetworkGraspPlanner
    from heapgrasp.planning.view_network import NetworkViewScorer

__all__ = [
    "ORACLE_FRAMES",
    "Method",
    "build_pipeline",
    "make_critic",
    "make_grasp_planner",
    "make_segmenter",
    "make_view_scorer",
    "make_wide_planner",
    "method_of",
    "net_device",
]

#: Silhouettes per hypothetical path when the oracle scores a candidate (eq. 14), evenly
#: spaced along the path (``docs/experiments.md`` measures 10 against 40).
ORACLE_FRAMES = 10


def make_segmenter(config: RunConfig, truth: MaskSource | None, seed: int = 0) -> Segmenter:
    """The configured segmenter: with ``segmenter = "network"`` the segmentation network
    of ``config.seg_weights`` (:class:`~heapgrasp.perception.segnet.NetworkSegmenter`, on
    RGB frames), else the simulator's: exact silhouettes from ``truth``, with pixel-flip
    noise ``config.noise`` where it is > 0 (Table V), which needs ``truth``."""
    if config.segmenter == "network":
        from heapgrasp.inference.errors import WeightsError
        from heapgrasp.perception.segnet import NetworkSegmenter

        try:
            return NetworkSegmenter(str(config.seg_weights), device=net_device(config))
        except (FileNotFoundError, WeightsError) as err:
            raise ConfigError(f"seg_weights: {err}") from None
    if truth is None:
        raise ConfigError(
            "segmenter: the simulator's silhouettes need its scene truth; a real camera "
            "needs segmenter = 'network' and seg_weights"
        )
    if config.noise > 0:
        return NoisySegmenter(truth, config.noise, seed=seed)
    return IdealSegmenter(truth)


def _weights(path: str | None, kind: Kind, option: str) -> Path:
    if path:
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"{option}: weights file not found: {p}")
        return p
    found = shipped_weights(kind)
    if found is None:
        raise ConfigError(
            f"{option}: no {kind} weights ship with this version; pass an ONNX weights "
            f"file (heapgrasp.training.export_onnx writes one), or use the analytic/oracle planners"
        )
    return found


def net_device(config: RunConfig) -> str:
    """The device the networks run on (:attr:`RunConfig.net_device`; ``auto`` resolved by
    :func:`heapgrasp.inference.resolve_device`). A CUDA device onnxruntime cannot use is a
    :class:`ConfigError`, not a quiet run on the CPU."""
    try:
        return resolve_device(config.net_device)
    except ValueError as err:
        raise ConfigError(f"net_device: {err}") from None


def make_wide_planner(
    config: RunConfig, gripper: GripperGeometry = PANDA_HAND
) -> GraspPlanner | None:
    """``RunConfig.fine_width``'s second planner: the analytic planner measuring openings
    at the extreme voxel centres (the opening it may use one grid voxel wider), for a
    silhouette method whose planner is the analytic one; None elsewhere."""
    if not config.fine_width or config.grasp_planner_in_use != "antipodal":
        return None
    if method_of(config).depth:
        return None
    from heapgrasp.planning.antipodal import AntipodalPlanner

    voxel = config.cube_size / config.resolution
    return AntipodalPlanner(max_opening=gripper.max_opening + voxel, gripper=gripper)


def make_grasp_planner(config: RunConfig, gripper: GripperGeometry = PANDA_HAND) -> GraspPlanner:
    """The configured grasp planner (``antipodal`` or ``network``); the analytic one plans
    for ``gripper`` (its shape and widest opening)."""
    if config.grasp_planner_in_use == "antipodal":
        from heapgrasp.planning.antipodal import AntipodalPlanner

        return AntipodalPlanner(max_opening=gripper.max_opening, gripper=gripper)
    from heapgrasp.planning.grasp_network import NetworkGraspPlanner

    grid = method_of(config).grid
    if config.grasp_weights:
        weights = _weights(config.grasp_weights, "grasp-network", "grasp_weights")
    else:
        shipped = shipped_grasp_network(grid)
        if shipped is None:
            raise ConfigError(
                f"grasp_weights: no grasp network for {grid} grids ships with this version; "
                f"pass one (heapgrasp grasps train --input {grid} writes it) or use "
                f"grasp_planner = 'antipodal'"
            )
        weights = shipped
    planner = _open_network(
        config, "grasp_weights", weights, lambda w, d: NetworkGraspPlanner(w, device=d)
    )
    from heapgrasp.geometry.gripper import GRIPPERS

    if GRIPPERS[planner.gripper].max_opening > gripper.max_opening + 1e-9:
        raise ConfigError(
            f"grasp_weights: {weights} was trained for the {planner.gripper} hand, which "
            f"opens to {GRIPPERS[planner.gripper].max_opening * 100:g} cm; the robot's "
            f"opens to {gripper.max_opening * 100:g} cm"
        )
    if planner.input_kind != grid:
        raise ConfigError(
            f"grasp_weights: {weights} was trained on {planner.input_kind} grids, but the "
            f"{config.method} method feeds it {grid} grids"
        )
    return planner


def make_critic(config: RunConfig) -> GraspCritic | None:
    """The configured grasp critic (:attr:`RunConfig.critic`); None where there is none. A
    missing or bad critic file is a :class:`ConfigError` naming the file and the problem."""
    source = config.critic
    if source is None:
        return None
    from heapgrasp.inference.errors import WeightsError

    path = DEFAULT_CRITIC if source == "default" else Path(source)
    try:
        return GraspCritic.load(path)
    except (WeightsError, FileNotFoundError) as err:  # checked whole, before any scene
        raise ConfigError(f"grasp_critic: {err}") from err


_Net = TypeVar("_Net", "NetworkGraspPlanner", "NetworkViewScorer")


def _open_network(
    config: RunConfig, setting: str, weights: Path, open_: Callable[[Path, str], _Net]
) -> _Net:
    """A network planner opened from ``weights`` on the configured device; a bad file, a
    device that cannot run it or a grid side other than the run's is a ConfigError naming
    ``setting``, before any scene."""
    from heapgrasp.inference.errors import WeightsError

    try:
        net = open_(weights, net_device(config))
    except WeightsError as err:  # a bad file is a bad setting: one clear error
        raise ConfigError(f"{setting}: {err}") from err
    except ValueError as err:  # the device cannot run it
        raise ConfigError(f"net_device: {err}") from err
    if net.resolution != config.resolution:
        raise ConfigError(
            f"{setting}: {weights} reads {net.resolution}³ grids, the run's grid is "
            f"{config.resolution}³ (resolution)"
        )
    return net


def make_view_scorer(config: RunConfig) -> ViewScorer | None:
    """The configured view scorer; None for fixed-view methods."""
    if method_of(config).views != "planned":
        return None
    if config.view_planner == "oracle":
        return OracleViewScorer(
            frames_per_candidate=ORACLE_FRAMES, target_radius=config.target_radius
        )
    from heapgrasp.planning.view_network import NetworkViewScorer

    weights = _weights(config.view_weights, "view-network", "view_weights")
    scorer = _open_network(
        config,
        "view_weights",
        weights,
        lambda w, d: NetworkViewScorer(w, device=d, target_radius=config.target_radius),
    )
    if scorer.view_shape != (config.U, config.V):
        u, v = scorer.view_shape
        raise ConfigError(
            f"view_weights: {weights} scores {u}×{v} candidates, the run has "
            f"{config.U}×{config.V} (U, V)"
        )
    if scorer.in_channels == 1 and config.target_radius > 0:
        raise ConfigError(
            f"view_weights: {weights} is a one-channel view network (occupancy only): it "
            f"cannot count eq. 14 on the target's column that target_radius = "
            f"{config.target_radius:g} asks for; set target_radius = 0 (the paper's eq. 14 "
            f"over the whole grid) or use weights with the region channel (2 or 3 channels)"
        )
    return scorer


def build_pipeline(
    config: RunConfig,
    robot: Robot,
    *,
    segmenter: Segmenter,
    truth: SceneTruth | None = None,
    grasp_planner: GraspPlanner | None = None,
    view_scorer: ViewScorer | None = None,
    critic: GraspCritic | None = None,
    observer: PhaseObserver | None = None,
    seed: int = 0,
    reference_segmenter: Segmenter | None = None,
) -> Pipeline:
    """A :class:`Pipeline` for ``config`` on ``robot``; any stage passed explicitly
    replaces the configured one. The oracle view planner needs ``truth``; ``observer``
    is told what each phase does (:mod:`heapgrasp.loop.observe`);
    ``reference_segmenter`` carves a grid to compare with (:attr:`Pipeline.reference_segmenter`)."""
    if view_scorer is None:
        view_scorer = make_view_scorer(config)
    if isinstance(view_scorer, OracleViewScorer) and truth is None:
        raise ConfigError(
            "view_planner: the oracle scores views on the true meshes, which only the "
            "simulator has; on a robot use view_planner = network, circle or hemisphere6"
        )
    return Pipeline(
        config=config,
        robot=robot,
        method=method_of(config),
        grasp_planner=grasp_planner
        if grasp_planner is not None
        else make_grasp_planner(config, robot.gripper.geometry),
        segmenter=segmenter,
        view_scorer=view_scorer,
        rng=np.random.default_rng(seed),
        critic=critic if critic is not None else make_critic(config),
        truth=truth,
        observer=observer,
        reference_segmenter=reference_segmenter,
        # with a planner passed in, the caller chose what plans: no second planner
        wide_planner=make_wide_planner(config, robot.gripper.geometry)
        if grasp_planner is None
        else None,
    )
