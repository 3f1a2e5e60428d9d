"""The closed loop of HEAPGrasp (Fig. 2, §IV) and its baselines (§VI-B), one phase at a time.

A phase starts with the hand-eye camera at its initial pose ``p⁰`` and ends at the
grasp (footnote 3 of the paper). :class:`Pipeline.plan` runs it:

1. capture at ``p⁰`` and update the grid (perception, §IV-A);
2. for ``heapgrasp`` (view planning): at every view waypoint ``ℓ = 0 .. L-1`` plan
   grasps on ``Ŝ≥λ`` (eq. 11, 15; not where ``γ2 = 0``, whose target would steer
   nothing), keep the target grasp closest to the previous one (eq. 16-17), score
   the U×V candidates (eq. 13/14) and move to ``argmax s + γ2 h`` (eq. 18-19;
   ``γ2 = gamma2_first`` at ``ℓ = 0``), capturing continuously along the
   interpolated, ruckig-timed path (eq. 8);
   for the fixed-view methods (``no-vp``, ``vgn``, ``hemisphere6``) visit the fixed
   waypoints the same way;
3. plan grasps on the final grid: ``heapgrasp`` keeps the target of eq. 16
   (``final_grasp = "best"`` takes the top-scoring one instead), the baselines take the
   top-scoring grasp. With ``confirm_below`` > 0 (not in the paper), a HEAPGrasp grasp
   scoring below it, or none at all, sends the camera to one more view waypoint toward
   it (eq. 18-19, ``confirm_gamma2``), and the final grid is planned again, at most
   ``confirm_waypoints`` times.

Every method forgets candidates within ``failed_grasp_radius`` of a grasp that failed
since the last success (:meth:`Pipeline.record_outcome`): the simulation is
deterministic, and an empty grasp leaves the scene as it was.

The camera path of the phase is every captured camera position followed by the grasp
position (the camera reaches the grasp with the hand). The phase's compute time is the
measured time of perception, grasp planning, view planning and selection (not the time
spent simulating the camera); its motion time is the ruckig duration of every camera
motion plus the straight approach to the pre-grasp pose.

:func:`build_pipeline` assembles a pipeline from a :class:`~heapgrasp.config.RunConfig`;
every stage can also be passed in (any object satisfying its protocol).
"""

from __future__ import annotations

import dataclasses
import importlib
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp import HeapgraspError
from heapgrasp.config import ConfigError, RunConfig
from heapgrasp.grasping.critic import DEFAULT_CRITIC, GraspCritic
from heapgrasp.grasping.volumes import (
    GraspCandidate,
    GraspPlanner,
    GridFrame,
    select_candidates,
)
from heapgrasp.perception import (
    DepthPerception,
    IdealSegmenter,
    NoisySegmenter,
    Segmenter,
    SilhouettePerception,
)
from heapgrasp.selection import detour, select_next_waypoint, select_target, top_scoring
from heapgrasp.sim.camera import CameraSpec
from heapgrasp.sim.gripper import Grasp, GraspOutcome
from heapgrasp.sim.motion import MotionLimits, ViewSphere, plan_waypoints, time_path
from heapgrasp.sim.protocol import PlanResult
from heapgrasp.sim.robot import Robot
from heapgrasp.sim.world import Capture, Frame, SimWorld
from heapgrasp.viewplan import (
    OracleViewScorer,
    ViewContext,
    ViewScorer,
    fixed_waypoints,
    sweep_waypoints,
)

__all__ = [
    "Pipeline",
    "build_pipeline",
    "make_grasp_planner",
    "make_robot",
    "make_segmenter",
    "make_view_scorer",
]

F64 = npt.NDArray[np.float64]

#: Distance of the pre-grasp pose behind the grasp along its approach axis (m).
PREGRASP_DISTANCE = 0.05


def _candidate_record(c: GraspCandidate | None) -> dict[str, Any] | None:
    if c is None:
        return None
    return {
        "position": c.position.tolist(),
        "quaternion": c.quaternion.tolist(),
        "width": c.width,
        "score": c.score,
    }


@dataclass
class _PhaseLog:
    """What one phase has done so far: where the camera is, where it has been."""

    current: F64
    positions: list[F64]
    waypoints: list[dict[str, Any]] = field(default_factory=list)
    compute: float = 0.0
    motion: float = 0.0
    stopped: dict[str, Any] | None = None
    """Where ``stop_below`` ended the viewing early, and why; None: it did not."""
    final_candidates: list[GraspCandidate] | None = None
    """The grasps planned where the viewing stopped early, when they are those of a final
    grid (scored by the critic, if any): the final grid is not planned again."""


@dataclass
class Pipeline:
    """One method's phase planner (see the module docstring)."""

    config: RunConfig
    world: SimWorld
    robot: Robot
    grasp_planner: GraspPlanner
    view_scorer: ViewScorer | None = None
    segmenter: Segmenter = field(default_factory=IdealSegmenter)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    critic: GraspCritic | None = None
    """Drops candidates unlikely to hold an object (``RunConfig.grasp_critic``)."""

    def __post_init__(self) -> None:
        cfg = self.config
        self.frame = GridFrame((0.0, 0.0, 0.0), cfg.cube_size, cfg.resolution)
        self.sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), cfg.cube_size, radius=cfg.radius)
        self.candidates = self.sphere.candidates(cfg.U, cfg.V, cfg.theta_max)
        self.limits = MotionLimits(cfg.max_velocity, cfg.max_acceleration, cfg.max_jerk)
        self.uses_depth = cfg.method == "vgn"
        if self.uses_depth:
            # VGN's depth camera: 640×480 at 30 fps (HEAPGrasp §VI-B).
            self.camera = CameraSpec.still()
            self.perception: SilhouettePerception | DepthPerception = DepthPerception(self.frame)
        else:
            self.camera = (
                CameraSpec.continuous() if cfg.camera == "continuous" else CameraSpec.still()
            )
            self.perception = SilhouettePerception(
                self.frame,
                self.segmenter,
                cfg.lam,
                roof_radius=cfg.roof_radius,
                silhouette_views=cfg.silhouette_views,
                memory=cfg.scene_memory,
                memory_tolerance=cfg.memory_tolerance,
            )
        self.adaptive = cfg.method == "heapgrasp" and cfg.view_planner in ("oracle", "network")
        self.joint_path_errors = 0
        self.unreachable_waypoints = 0
        self.failed_grasps: list[F64] = []
        if self.adaptive and self.view_scorer is None:
            raise ConfigError(f"view_planner {cfg.view_planner!r} needs a view scorer")

    # ------------------------------------------------------------------ pieces
    def initial_pose(self) -> F64:
        """``p⁰``: ``initial_radius`` from the sphere's centre at ``(initial_phi,
        initial_theta)``, looking at the centre of the scene."""
        cfg = self.config
        start = dataclasses.replace(self.sphere, radius=cfg.initial_radius)
        return start.pose(cfg.initial_phi, cfg.initial_theta)

    def fixed_waypoints(self) -> F64:
        """Waypoints of a fixed-view method (or view planner)."""
        cfg = self.config
        kind = cfg.view_planner if cfg.method == "heapgrasp" else cfg.method
        kind = {"no-vp": "circle", "vgn": "circle"}.get(kind, kind)
        return fixed_waypoints(
            kind,
            self.sphere,
            L=cfg.L,
            circle_theta=cfg.circle_theta,
            circle_closed=cfg.circle_closed,
            phi0=cfg.initial_phi,
            rng=self.rng,
            hemisphere_radius=cfg.hemisphere_radius,
            hemisphere_theta=cfg.hemisphere_theta,
            hemisphere_views=cfg.hemisphere_views,
        )

    def _capture(self, pose: F64) -> Frame:
        return self.world.capture(self.robot.move_camera(pose), self.camera, depth=self.uses_depth)

    def _perceive(self, frames: list[Frame]) -> float:
        t0 = time.perf_counter()
        self.perception.update(frames)
        return time.perf_counter() - t0

    def grasp_candidates(self, *, final: bool = True) -> list[GraspCandidate]:
        """Grasp planning on the current grid and eq. 15's post-processing; with a
        critic, its probabilities are the scores, at the final grid and (when
        ``critic_at_waypoints``) at the view waypoints too."""
        cfg = self.config
        critic = self.critic if (final or cfg.critic_at_waypoints) else None
        if (
            isinstance(self.perception, DepthPerception)
            and getattr(self.grasp_planner, "input_kind", "occupancy") == "tsdf"
        ):
            grid = self.perception.tsdf_values()
        else:
            grid = self.perception.grasp_input()
        volumes = self.grasp_planner.predict(grid, self.frame)
        sigma = cfg.sigma if cfg.sigma is not None else getattr(self.grasp_planner, "sigma", 1.0)
        if cfg.epsilon is not None:
            eps = cfg.epsilon
        elif critic is not None:  # the critic's own ε applies to its probabilities
            eps = critic.candidate_epsilon
        else:
            eps = getattr(self.grasp_planner, "epsilon", 0.8)
        cands = select_candidates(
            volumes, epsilon=float(eps), sigma=float(sigma), nms_window=cfg.nms_window
        )
        if self.failed_grasps and cfg.failed_grasp_radius > 0.0:
            failed = np.asarray(self.failed_grasps)
            cands = [
                c
                for c in cands
                if np.min(np.linalg.norm(failed - c.position, axis=1)) > cfg.failed_grasp_radius
            ]
        if critic is not None and isinstance(self.perception, SilhouettePerception):
            cands = critic.rescore(
                cands,
                grid,
                self.perception.grid.high_confidence(cfg.lam),
                self.frame,
                self.perception.camera_positions(),
            )
        return cands

    def record_outcome(self, grasp: Grasp, outcome: GraspOutcome | str) -> None:
        """Remembers a failed grasp (its candidates are dropped by
        :meth:`grasp_candidates` from now on); a success clears the memory, since the
        scene has changed. ``run_clutter_removal``'s ``on_outcome`` hook."""
        if GraspOutcome(outcome) == GraspOutcome.SUCCESS:
            self.failed_grasps.clear()
        else:
            self.failed_grasps.append(np.asarray(grasp.pose, dtype=np.float64)[:3, 3].copy())

    def _move(self, start: F64, goal: F64) -> tuple[Capture, float, float] | None:
        """Moves the camera to ``goal`` capturing; None if the arm cannot get there."""
        (path,) = plan_waypoints(start, [goal], self.sphere, self.limits, self.config.fps)
        if self.config.mount == "arm":
            from heapgrasp.sim.arm import JointPathError, PandaArm, retime_for_arm

            if isinstance(self.robot, PandaArm):
                try:  # slow down until the joint limits hold
                    path = retime_for_arm(path, self.robot)
                except JointPathError:
                    self.joint_path_errors += 1  # followed kinematically, Cartesian timing
        clock = self.world.time
        try:
            cap = self.world.follow(path, self.camera, mount=self.robot, depth=self.uses_depth)
        except HeapgraspError:  # the arm's UnreachableError: skip this waypoint
            self.world.time = clock
            self.unreachable_waypoints += 1
            self.robot.move_camera(start)
            return None
        return cap, path.duration, self._perceive(cap.frames[1:])

    def _object_near(self, point: F64) -> int | None:
        best, best_d = None, 0.03
        for oid in self.world.objects:
            pose = self.world.object_pose(oid)
            verts = self.world.object_vertices(oid) @ pose[:3, :3].T + pose[:3, 3]
            d = float(np.min(np.linalg.norm(verts - point, axis=1)))
            if d < best_d:
                best, best_d = oid, d
        return best

    # ------------------------------------------------------------------ one phase
    def _visit(self, phase: _PhaseLog, goal: F64) -> tuple[Capture, float] | None:
        """Moves the camera to ``goal`` capturing (:meth:`_move`) and logs the motion in
        ``phase``; returns the capture and its duration, or None if unreachable."""
        moved = self._move(phase.current, goal)
        if moved is None:
            return None
        cap, duration, carve = moved
        phase.compute += carve
        phase.motion += duration
        phase.positions.extend(cap.positions[1:])
        phase.current = cap.poses[-1]
        return cap, duration

    def _view_step(
        self,
        phase: _PhaseLog,
        cands: list[GraspCandidate] | None,
        target: GraspCandidate | None,
        gamma2: float,
        t0: float,
        t1: float,
        *,
        trusted: bool,
        stop_below: float = 0.0,
    ) -> bool:
        """Eq. 18-19 from the current pose toward ``target``, then the move there with
        continuous capture; ``cands``: the grasps planned here (None: not planned);
        ``t0``/``t1``: when grasp planning began and ended. ``trusted``: the target may
        steer the view scores (the oracle's target column). With ``stop_below`` > 0 and a
        target, no move is made when no candidate's score on the target's region reaches
        it (``RunConfig.stop_below``). Returns False when it stopped there."""
        cfg = self.config
        assert self.view_scorer is not None
        assert isinstance(self.perception, SilhouettePerception)
        ctx = ViewContext(
            self.perception.grid,
            phase.current,
            self.candidates,
            self.sphere,
            self.camera,
            cfg.lam,
            self.world.object_scene,
            target=None if target is None or not trusted else target.pose,
        )
        scores: npt.NDArray[np.float32] | None = None
        if stop_below > 0.0 and target is not None and target.score >= cfg.stop_confidence:
            # The stop test counts eq. 14 on the target's region, whether or not that
            # region steers the choice below (it does not where gamma2 = 0).
            region_ctx = ctx if trusted else dataclasses.replace(ctx, target=target.pose)
            region_scores = self.view_scorer.scores(region_ctx)
            worth = region_scores - cfg.stop_detour_weight * detour(
                self.candidates, phase.current, target.pose
            )
            if trusted:
                scores = region_scores
            if float(worth.max()) < stop_below:
                t2 = time.perf_counter()
                phase.compute += t2 - t0
                phase.stopped = {
                    "target": _candidate_record(target),
                    "grasp_candidates": None if cands is None else len(cands),
                    "region_score_max": float(region_scores.max()),
                    "worth_max": float(worth.max()),
                    "grasp_planning_s": t1 - t0,
                    "view_planning_s": t2 - t1,
                }
                if cands is not None and (cfg.critic_at_waypoints or self.critic is None):
                    phase.final_candidates = cands
                return False
        if scores is None:
            scores = self.view_scorer.scores(ctx)
        t2 = time.perf_counter()
        objective = scores
        if cfg.move_weight > 0.0:
            move = np.linalg.norm(self.candidates[..., :3, 3] - phase.current[:3, 3], axis=-1)
            objective = scores - cfg.move_weight * move
        u, v = select_next_waypoint(
            objective,
            self.candidates,
            phase.current,
            None if target is None else target.pose,
            gamma2,
            cfg.gamma1,
        )
        t3 = time.perf_counter()
        phase.compute += t3 - t0
        goal = self.candidates[u, v]
        visited = self._visit(phase, goal)
        if visited is None:
            return True
        cap, duration = visited
        phase.waypoints.append(
            {
                "index": [u, v],
                "position": goal[:3, 3].tolist(),
                "view_score": float(scores[u, v]),
                "view_score_max": float(scores.max()),
                "gamma2": gamma2,
                "target": _candidate_record(target),
                "grasp_candidates": None if cands is None else len(cands),
                "frames": len(cap),
                "duration_s": duration,
                "grasp_planning_s": t1 - t0,
                "view_planning_s": t2 - t1,
                "latency_s": t3 - t0,
            }
        )
        return True

    def _sweep(self, phase: _PhaseLog) -> None:
        """``RunConfig.sweep_degrees``: on along the rim of the candidates, capturing."""
        cfg = self.config
        rim = cfg.theta_max * (cfg.V - 1) / cfg.V
        goals = sweep_waypoints(
            self.sphere,
            phase.current,
            np.asarray(phase.positions),
            degrees=cfg.sweep_degrees,
            step=cfg.sweep_step,
            theta=rim,
        )
        for goal in goals:
            visited = self._visit(phase, goal)
            if visited is None:
                continue
            phase.final_candidates = None  # the grid has changed
            cap, duration = visited
            record: dict[str, Any] = {
                "sweep": True,
                "position": goal[:3, 3].tolist(),
                "frames": len(cap),
                "duration_s": duration,
            }
            phase.waypoints.append(record)
            if cfg.sweep_stop:
                t0 = time.perf_counter()
                cands = self.grasp_candidates()
                phase.compute += time.perf_counter() - t0
                top = top_scoring(cands)
                record["best_score"] = None if top is None else top.score
                # planned on the grid as it is: the final grasp's, if no move follows
                phase.final_candidates = cands
                if top is not None and top.score >= cfg.stop_confidence:
                    return

    def _final_choice(
        self, cands: list[GraspCandidate], target: GraspCandidate | None
    ) -> tuple[GraspCandidate | None, GraspCandidate | None]:
        """The top-scoring candidate and the one to execute (eq. 16 toward ``target``
        for HEAPGrasp with ``final_grasp = "target"``, else the top-scoring one)."""
        best = top_scoring(cands)
        if self.adaptive and self.config.final_grasp == "target":
            return best, select_target(cands, target, self.config.gamma1)
        return best, best

    def plan(self) -> PlanResult:
        """Runs one phase up to the grasp (see the module docstring)."""
        cfg = self.config
        self.robot.park()
        self.perception.reset()
        self.joint_path_errors = 0
        self.unreachable_waypoints = 0
        first = self._capture(self.initial_pose())
        phase = _PhaseLog(first.cam2world, [first.cam2world[:3, 3]])
        phase.compute += self._perceive([first])
        target: GraspCandidate | None = None
        if self.adaptive:
            for ell in range(cfg.L):
                t0 = time.perf_counter()
                gamma2 = cfg.gamma2_first if ell == 0 else cfg.gamma2
                # Early stop (not in the paper): from the stop_after-th waypoint on, a
                # target is planned even where gamma2 = 0, so that its region can be
                # checked for views that would still carve it.
                stop_test = cfg.stop_below > 0.0 and ell >= cfg.stop_after
                if gamma2 == 0.0 and not stop_test:
                    # §VI-B: with gamma2 = 0 a grasp planned here steers nothing (eq. 18
                    # uses s alone, the oracle counts the whole grid) and anchors no
                    # later target (below), so it is not planned at all: at p0 with
                    # Table I's gamma2_first, and at every waypoint with gamma2 = 0.
                    cands = None
                else:
                    cands = self.grasp_candidates(final=False)
                    # No candidate at this waypoint: no target, and eq. 18 uses s alone.
                    target = select_target(cands, target, cfg.gamma1)
                # A target planned where gamma2 = 0 is unreliable (§VI-B): no region.
                moved = self._view_step(
                    phase,
                    cands,
                    target,
                    gamma2,
                    t0,
                    time.perf_counter(),
                    trusted=gamma2 > 0,
                    stop_below=cfg.stop_below if stop_test else 0.0,
                )
                if not moved:
                    break
                if gamma2 == 0.0:
                    # §VI-B: grasps planned before the first view waypoint are unreliable,
                    # which is why gamma2 = 0 there; neither may such a grasp anchor the
                    # target of eq. 16 at the next waypoint.
                    target = None
            else:
                # With sweep_stop the sweep is for a grasp the phase is unsure of: where
                # the plan before the last move found none, the phase ends as it would
                # without the sweep (the record is that step's plan, not the final grid's).
                planned = bool(phase.waypoints and phase.waypoints[-1].get("grasp_candidates"))
                if cfg.sweep_degrees > 0.0 and (planned or not cfg.sweep_stop):
                    self._sweep(phase)
        else:
            for goal in self.fixed_waypoints():
                visited = self._visit(phase, goal)
                if visited is None:
                    continue
                cap, duration = visited
                phase.waypoints.append(
                    {
                        "position": goal[:3, 3].tolist(),
                        "frames": len(cap),
                        "duration_s": duration,
                    }
                )
        t0 = time.perf_counter()
        # Where viewing stopped early the grid is the one just planned there.
        final = phase.final_candidates
        cands = final if final is not None else self.grasp_candidates()
        best, chosen = self._final_choice(cands, target)
        confirmations = 0
        while (
            self.adaptive
            and cfg.confirm_below > 0.0
            and confirmations < cfg.confirm_waypoints
            and (chosen is None or chosen.score < cfg.confirm_below)
        ):
            # Not confident in the grasp on the final grid: one more view waypoint
            # toward it (eq. 18-19), then plan again.
            confirmations += 1
            target = chosen if chosen is not None else target
            self._view_step(
                phase, cands, target, cfg.confirm_gamma2, t0, time.perf_counter(), trusted=True
            )
            t0 = time.perf_counter()
            cands = self.grasp_candidates()
            best, chosen = self._final_choice(cands, target)
        final_latency = time.perf_counter() - t0
        phase.compute += final_latency
        memory: dict[str, Any] | None = None
        if isinstance(self.perception, SilhouettePerception):
            memory = self.perception.memory_record
            self.perception.remember()
        current, positions = phase.current, phase.positions
        waypoints, compute, motion = phase.waypoints, phase.compute, phase.motion
        extra: dict[str, Any] = {
            "waypoints": waypoints,
            "frames": self.perception.frames_seen,
            "final_candidates": len(cands),
            "final_planning_s": final_latency,
            "confirmation_waypoints": confirmations,
            "stopped_early": phase.stopped,
            "joint_path_errors": self.joint_path_errors,
            "unreachable_waypoints": self.unreachable_waypoints,
            "target_grasp": _candidate_record(chosen),
            "best_grasp": _candidate_record(best),
        }
        if self.config.scene_memory:
            extra["memory"] = memory
        if chosen is None:
            return PlanResult(
                None,
                np.asarray(positions),
                motion,
                compute_time=compute,
                extra=extra,
            )
        grasp_position = chosen.pose[:3, 3]
        # The camera travels with the hand to the pre-grasp pose, then approaches.
        pregrasp = chosen.pose.copy()
        pregrasp[:3, 3] -= PREGRASP_DISTANCE * chosen.pose[:3, 2]
        approach = np.stack([current, current.copy()])
        approach[1, :3, 3] = pregrasp[:3, 3]
        motion += time_path(approach, self.limits).duration
        positions.append(grasp_position)
        return PlanResult(
            Grasp(chosen.pose, min(chosen.width, 0.08)),
            np.asarray(positions),
            motion,
            target_object=self._object_near(grasp_position),
            compute_time=compute,
            extra=extra,
        )


# --------------------------------------------------------------------------- builders


def make_segmenter(config: RunConfig, seed: int = 0) -> Segmenter:
    """Ideal masks, or masks with pixel-flip noise ``config.noise`` (Table V)."""
    if config.noise > 0:
        return NoisySegmenter(config.noise, seed=seed)
    return IdealSegmenter()


def _weights(path: str | None, kind: str, option: str) -> Path:
    if path:
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"{option}: weights file not found: {p}")
        return p
    from heapgrasp.nets.weights import find_default

    found = find_default(kind)  # type: ignore[arg-type]
    if found is None:
        raise ConfigError(
            f"{option}: no {kind}-network weights ship with this version; pass a weights "
            f"file, or use the analytic/oracle planners"
        )
    return found


def net_device(config: RunConfig) -> str:
    """The device the networks run on (:attr:`RunConfig.net_device`; ``auto`` resolved by
    :func:`heapgrasp.nets.resolve_device`). A CUDA device that PyTorch cannot see is a
    :class:`ConfigError`, not a quiet run on the CPU."""
    # heapgrasp.nets first: without PyTorch it raises the "install heapgrasp[nets]" hint.
    nets = importlib.import_module("heapgrasp.nets")
    try:
        device: str = nets.resolve_device(config.net_device)
    except ValueError as err:
        raise ConfigError(f"net_device: {err}") from None
    return device


def make_grasp_planner(config: RunConfig) -> GraspPlanner:
    """The configured grasp planner (``antipodal`` or ``network``)."""
    if config.grasp_planner == "antipodal":
        from heapgrasp.grasping.antipodal import AntipodalPlanner

        return AntipodalPlanner()
    from heapgrasp.grasping.network import NetworkGraspPlanner

    weights = _weights(config.grasp_weights, "grasp", "grasp_weights")
    planner = NetworkGraspPlanner(weights, device=net_device(config))
    if config.method == "vgn":
        planner.input_kind = "tsdf"
    return planner


def make_critic(config: RunConfig) -> GraspCritic | None:
    """The configured grasp critic (:attr:`RunConfig.critic`); None where there is none."""
    source = config.critic
    if source is None:
        return None
    path = DEFAULT_CRITIC if source == "default" else Path(source)
    critic = GraspCritic.load(path)
    if config.critic_threshold is not None:
        critic.threshold = config.critic_threshold
    return critic


def make_view_scorer(config: RunConfig) -> ViewScorer | None:
    """The configured view scorer; None for fixed-view methods."""
    if config.method != "heapgrasp" or config.view_planner in ("circle", "hemisphere6"):
        return None
    if config.view_planner == "oracle":
        return OracleViewScorer(
            frames_per_candidate=config.oracle_frames,
            target_radius=config.target_radius,
            target_region=config.target_region,
        )
    from heapgrasp.viewplan_network import NetworkViewScorer

    weights = _weights(config.view_weights, "view", "view_weights")
    return NetworkViewScorer(weights, device=net_device(config))


def make_robot(config: RunConfig, world: SimWorld) -> Robot:
    """The free-flying hand or the Panda arm (``config.mount``)."""
    if config.mount == "arm":
        from heapgrasp.sim.arm import ArmConfig, PandaArm

        # The arm picks the camera roll about the viewing axis: paths leaving the top of
        # the view sphere would otherwise spin the wrist past its limits.
        return PandaArm(world, ArmConfig(camera_roll="free"))
    from heapgrasp.sim.gripper import PandaHand

    return PandaHand(world)


def build_pipeline(
    config: RunConfig,
    world: SimWorld,
    *,
    robot: Robot | None = None,
    grasp_planner: GraspPlanner | None = None,
    view_scorer: ViewScorer | None = None,
    segmenter: Segmenter | None = None,
    critic: GraspCritic | None = None,
    seed: int = 0,
) -> Pipeline:
    """A :class:`Pipeline` for ``config`` in ``world`` (after ``world.reset``); any stage
    passed explicitly replaces the configured one."""
    return Pipeline(
        config=config,
        world=world,
        robot=robot if robot is not None else make_robot(config, world),
        grasp_planner=grasp_planner if grasp_planner is not None else make_grasp_planner(config),
        view_scorer=view_scorer if view_scorer is not None else make_view_scorer(config),
        segmenter=segmenter if segmenter is not None else make_segmenter(config, seed),
        rng=np.random.default_rng(seed),
        critic=critic if critic is not None else make_critic(config),
    )
