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
3. plan grasps on the final grid: ``heapgrasp`` keeps the target of eq. 16, the
   baselines take the top-scoring grasp.

The extensions (:mod:`heapgrasp.loop.extensions`) are asked at fixed points: the early
stop at each view waypoint from the second on, the rim sweep after the last one. Where
step 3 finds no candidate, the phase looks again (``RunConfig.look_again``): the camera
moves to the start turned about the scene (:data:`LOOK_AGAIN_TURNS`) and steps 2–3 run
once more on the same grid. Where the last look finds none either, a silhouette method
with the analytic planner plans the final grid once more with the grasp's opening
measured finer (``RunConfig.fine_width``, :meth:`Pipeline.fine_width_grasp`), before
the phase reports no candidate.

Every method forgets candidates within ``failed_grasp_radius`` of a grasp that failed
since the last success (:meth:`Pipeline.record_outcome`): an empty grasp usually leaves
the scene as it was.

The phase runs on any :class:`~heapgrasp.robot.interfaces.Robot`. Scene truth
(:class:`~heapgrasp.robot.interfaces.SceneTruth`, simulation only) is optional: the
oracle view scorer needs its meshes, and the phase's record names the object under the
grasp where it is given.

The camera path of the phase is every captured camera position followed by the grasp
position (the camera reaches the grasp with the hand). The phase's compute time is the
measured time of perception, grasp planning, view planning and selection (not the time
spent simulating the camera); its motion time is the ruckig duration of every camera
motion plus the straight approach to the pre-grasp pose.

The pipeline reads what it needs of its method from a
:class:`~heapgrasp.loop.stages.Method` and of its stages from the stages themselves (a
grasp planner's grid, σ, ε, hull check: :class:`~heapgrasp.planning.volumes.GraspPlanner`),
never the names in the configuration. :func:`heapgrasp.loop.stages.build_pipeline`
assembles one from a :class:`~heapgrasp.loop.config.RunConfig` and a robot; every stage
can also be passed in (any object satisfying its protocol).
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.motion import MotionLimits, ViewSphere, plan_waypoints, time_path
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.extensions import EarlyStop, RimSweep
from heapgrasp.loop.methods import Method
from heapgrasp.loop.observe import PhaseObserver
from heapgrasp.loop.protocol import PlanResult
from heapgrasp.perception.depth import DepthPerception
from heapgrasp.perception.frames import Capture, Frame
from heapgrasp.perception.segmenters import Segmenter
from heapgrasp.perception.silhouette import SilhouettePerception, grid_agreement
from heapgrasp.planning.critic import GraspCritic
from heapgrasp.planning.hull_check import HullCheck
from heapgrasp.planning.selection import select_next_waypoint, select_target, top_scoring
from heapgrasp.planning.surface_contacts import TsdfContactCheck
from heapgrasp.planning.views import ViewContext, ViewScorer, fixed_waypoints
from heapgrasp.planning.volumes import GraspCandidate, GraspPlanner, select_candidates
from heapgrasp.robot.grasping import PREGRASP_DISTANCE, Grasp, GraspOutcome
from heapgrasp.robot.interfaces import Robot, SceneTruth, UnreachableError

if TYPE_CHECKING:
    pass

__all__ = [
    "FINE_WIDTH_CUBE",
    "FINE_WIDTH_DIVISOR",
    "FINE_WIDTH_MARGIN",
    "FINE_WIDTH_PASSES",
    "FINE_WIDTH_TRIES",
    "LOOK_AGAIN_TURNS",
    "MEMORY_TOLERANCE",
    "SILHOUETTE_VIEWS",
    "Pipeline",
]

F64 = npt.NDArray[np.float64]

#: Where a phase finds no grasp candidate, each look again (``RunConfig.look_again``)
#: moves the camera to the start pose turned by the next of these angles about the
#: scene's vertical axis (rad) — the far side first — and views from there as the phase
#: did (eq. 16-19, or the fixed methods' waypoints turned alike), carving the same grid.
LOOK_AGAIN_TURNS = (np.pi, np.pi / 2, 3 * np.pi / 2)

#: :meth:`Pipeline.fine_width_grasp`: the silhouettes are carved again in a cube of this
#: side (m; larger where the open fingers, swept from the pre-grasp pose, need it)
#: around each candidate, with voxels this many times smaller than the grid's, for at
#: most this many candidates.
FINE_WIDTH_CUBE = 0.16
FINE_WIDTH_DIVISOR = 3
FINE_WIDTH_TRIES = 8
#: :meth:`Pipeline.fine_width_grasp` plans on the grid grown by this many voxels on every
#: side but the table's (6 cm at Table I's 7.5 mm).
FINE_WIDTH_MARGIN = 8
#: :meth:`Pipeline.fine_width_grasp`'s passes, in order: the voxel as the grid's divided
#: by this, and whether the critic scores the candidates.
FINE_WIDTH_PASSES = ((1, True), (2, False))
#: Frames (evenly spaced over the phase) that check the trimmed hull against their
#: silhouettes (:func:`heapgrasp.perception.roofs.keep_silhouettes`).
SILHOUETTE_VIEWS = 24
#: With the scene memory: the most voxels the first frames of a phase may need beyond the
#: remembered hull before the memory is dropped.
MEMORY_TOLERANCE = 8


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
    robot: Robot
    grasp_planner: GraspPlanner
    segmenter: Segmenter
    method: Method
    """What the method senses, grasps on and how it views
    (:func:`~heapgrasp.loop.methods.method_of`)."""
    view_scorer: ViewScorer | None = None
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))
    critic: GraspCritic | None = None
    """Drops candidates unlikely to hold an object (``RunConfig.grasp_critic``)."""
    truth: SceneTruth | None = None
    """The simulator's scene truth (the oracle's meshes, the object under a grasp)."""
    observer: PhaseObserver | None = None
    """Told what the phase does as it runs (:mod:`heapgrasp.loop.observe`)."""
    reference_segmenter: Segmenter | None = None
    """Silhouette methods: a second segmenter (in simulation the noise-free silhouettes)
    whose grid is carved from the same frames, each phase afresh, and compared with the
    run's ``Ŝ≥λ`` at the end of every phase (the phase's ``reference_grid``: Table V's
    MSE and IoU). Not part of the method: it steers nothing and its time is not counted."""
    wide_planner: GraspPlanner | None = None
    """``RunConfig.fine_width``: the grasp planner measuring openings one voxel wider,
    planned where a phase would end with no candidate (:meth:`fine_width_grasp`); None:
    the phase ends."""

    def __post_init__(self) -> None:
        cfg = self.config
        self.frame = GridFrame((0.0, 0.0, 0.0), cfg.cube_size, cfg.resolution)
        self.sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), cfg.cube_size, radius=cfg.radius)
        self.candidates = self.sphere.candidates(cfg.U, cfg.V, cfg.theta_max)
        self.limits = MotionLimits(cfg.max_velocity, cfg.max_acceleration, cfg.max_jerk)
        self.camera: CameraSpec = self.robot.arm.camera.spec
        self.uses_depth = self.method.depth
        if self.uses_depth != self.robot.arm.camera.depth:
            need = "needs a depth camera" if self.uses_depth else "takes no depth"
            raise ConfigError(
                f"method {self.method.name!r} {need}; the robot's camera does not match"
            )
        if self.uses_depth:
            self.perception: SilhouettePerception | DepthPerception = DepthPerception(self.frame)
        else:
            self.perception = SilhouettePerception(
                self.frame,
                self.segmenter,
                cfg.lam,
                roof_radius=cfg.roof_radius,
                silhouette_views=SILHOUETTE_VIEWS,
                memory=cfg.scene_memory,
                memory_tolerance=MEMORY_TOLERANCE,
            )
        self.reference: SilhouettePerception | None = None
        if self.reference_segmenter is not None and not self.uses_depth:
            self.reference = SilhouettePerception(self.frame, self.reference_segmenter, cfg.lam)
        self.adaptive = self.method.views == "planned"
        self.early_stop = EarlyStop.from_config(cfg) if self.adaptive else None
        self.sweep = RimSweep.from_config(cfg) if self.adaptive else None
        self.joint_path_errors = 0
        self.unreachable_waypoints = 0
        self.phases_planned = 0
        self.failed_grasps: list[F64] = []
        if self.adaptive and self.view_scorer is None:
            raise ConfigError(f"view_planner {cfg.view_planner!r} needs a view scorer")

    # ------------------------------------------------------------------ pieces
    def initial_pose(self, turn: float = 0.0) -> F64:
        """``p⁰`` (``RunConfig.start``), looking at the centre of the scene; ``turn``
        (rad) turns it about the scene's vertical axis (a look again,
        :data:`LOOK_AGAIN_TURNS`)."""
        distance, theta, phi = self.config.start_pose
        start = dataclasses.replace(self.sphere, radius=distance)
        return start.pose(phi + turn, theta)

    def fixed_waypoints(self, turn: float = 0.0) -> F64:
        """Waypoints of a fixed-view method (or view planner), from the start's azimuth
        turned by ``turn`` (rad)."""
        cfg = self.config
        return fixed_waypoints(
            self.method.views, self.sphere, L=cfg.L, phi0=cfg.start_pose[2] + turn, rng=self.rng
        )

    def _perceive(self, frames: list[Frame]) -> float:
        if self.reference is not None:  # not the method's time: before the clock starts
            self.reference.update(frames)
        t0 = time.perf_counter()
        if self.observer is None:
            self.perception.update(frames)
            return time.perf_counter() - t0
        # Frame by frame for the observer: the same grid (the counts add up alike).
        for frame in frames:
            self.perception.update([frame])
            if isinstance(self.perception, SilhouettePerception):
                self.observer.frame(frame, self.perception.last_mask, self.perception.grid)
            else:
                self.observer.frame(frame, None, None)
        return time.perf_counter() - t0

    def grasp_candidates(self) -> list[GraspCandidate]:
        """Grasp planning on the current grid and eq. 15's post-processing; with a
        critic, its probabilities are the scores."""
        high = None
        if isinstance(self.perception, DepthPerception) and self.grasp_planner.input_kind == "tsdf":
            grid = self.perception.tsdf_values()
        else:
            grid = self.perception.grasp_input()
        if isinstance(self.perception, SilhouettePerception):
            high = self.perception.grid.high_confidence(self.config.lam)
        elif self.grasp_planner.needs_hull_check:
            # The TSDF network's regressed poses are checked against what the depth
            # measured: the surfaces' observed shells, the analytic planner's grid.
            high = self.perception.grasp_input()
        cands = self._candidates(self.grasp_planner, grid, high, self.frame, self.critic)
        if self.observer is not None:
            self.observer.candidates(cands)
        return cands

    def _candidates(
        self,
        planner: GraspPlanner,
        grid: npt.NDArray[np.float32],
        high: npt.NDArray[np.float32] | None,
        frame: GridFrame,
        critic: GraspCritic | None,
    ) -> list[GraspCandidate]:
        """:meth:`grasp_candidates` on ``grid`` at ``frame`` by ``planner``, scored by
        ``critic`` where there is one; ``high``: the measured occupancy of the same cube
        the hand must avoid (the hull check's; the silhouette methods' ``Ŝ≥λ``, also the
        critic's, or the TSDF's observed shells for a depth network), None for none."""
        cfg = self.config
        volumes = planner.predict(grid, frame)
        sigma = cfg.sigma if cfg.sigma is not None else planner.sigma
        if cfg.epsilon is not None:
            eps = cfg.epsilon
        elif critic is not None:  # the critic's own ε applies to its probabilities
            eps = critic.candidate_epsilon
        else:
            eps = planner.epsilon
        gripper = self.robot.gripper.geometry
        reject: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.bool_]] | None = None
        if planner.needs_hull_check and high is not None:
            # A network's regressed poses, unlike the analytic planner's, are not checked
            # against the hull; against Ŝ≥λ before its roofs were trimmed, which holds
            # the objects (the trimmed grid the network reads need not).
            reject = HullCheck(
                high > 0,
                frame,
                gripper=gripper,
                pregrasp_distance=PREGRASP_DISTANCE,
            )
            if isinstance(self.perception, DepthPerception):
                # The TSDF's normals also judge the contacts the shells' faces cannot.
                tsdf = self.perception.tsdf
                reject = _either(
                    reject, TsdfContactCheck(tsdf.values(), tsdf.weights(), frame, gripper=gripper)
                )
        cands = select_candidates(
            volumes,
            epsilon=float(eps),
            sigma=float(sigma),
            nms_window=cfg.nms_window,
            max_width=gripper.max_opening,
            reject=reject,
        )
        if self.failed_grasps and cfg.failed_grasp_radius > 0.0:
            failed = np.asarray(self.failed_grasps)
            cands = [
                c
                for c in cands
                if np.min(np.linalg.norm(failed - c.position, axis=1)) > cfg.failed_grasp_radius
            ]
        if critic is not None and high is not None:
            assert isinstance(self.perception, SilhouettePerception)  # vgn has no critic
            cands = critic.rescore(cands, grid, high, frame, self.perception.camera_positions())
        return cands

    @contextlib.contextmanager
    def planning_as(
        self, config: RunConfig, planner: GraspPlanner, critic: GraspCritic | None
    ) -> Iterator[None]:
        """Within the block, :meth:`grasp_candidates` plans as ``config``'s grasp planner
        and critic would (``planner``, ``critic``) on the grid as it stands, with no
        observer told; the pipeline's own are restored after. For measuring other
        planners on the loop's own grids (``heapgrasp bench topk``, ``heapgrasp grasps
        loop-data``)."""
        saved = (self.config, self.grasp_planner, self.critic, self.observer)
        self.config, self.grasp_planner, self.critic = config, planner, critic
        self.observer = None
        try:
            yield
        finally:
            self.config, self.grasp_planner, self.critic, self.observer = saved

    def record_outcome(self, grasp: Grasp, outcome: GraspOutcome | str) -> None:
        """Remembers a failed grasp (its candidates are dropped by
        :meth:`grasp_candidates` from now on); a success clears the memory, since the
        scene has changed. ``run_clutter_removal``'s ``on_outcome`` hook."""
        if self.observer is not None:
            self.observer.grasp(grasp, GraspOutcome(outcome))
        if GraspOutcome(outcome) == GraspOutcome.SUCCESS:
            self.failed_grasps.clear()
        else:
            self.failed_grasps.append(np.asarray(grasp.pose, dtype=np.float64)[:3, 3].copy())

    def _move(self, start: F64, goal: F64) -> tuple[Capture, float] | None:
        """Moves the camera to ``goal`` capturing; None if the arm cannot get there."""
        (path,) = plan_waypoints(start, [goal], self.sphere, self.limits, self.config.fps)
        try:
            cap = self.robot.arm.follow(path)
        except UnreachableError:  # skip this waypoint
            self.unreachable_waypoints += 1
            return None
        if not cap.timing_kept:
            self.joint_path_errors += 1  # followed at the Cartesian timing
        return cap, self._perceive(cap.frames[1:])

    # ------------------------------------------------------------------ one phase
    def _visit(
        self, phase: _PhaseLog, goal: F64, kind: str = "view"
    ) -> tuple[Capture, float] | None:
        """Moves the camera to ``goal`` capturing (:meth:`_move`) and logs the motion in
        ``phase``; returns the capture and its duration, or None if unreachable."""
        if self.observer is not None:
            self.observer.waypoint(goal, kind)
        moved = self._move(phase.current, goal)
        if moved is None:
            return None
        cap, carve = moved
        phase.compute += carve
        phase.motion += cap.duration
        phase.positions.extend(cap.positions[1:])
        phase.current = cap.poses[-1]
        return cap, cap.duration

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
        stop: EarlyStop | None = None,
    ) -> bool:
        """Eq. 18-19 from the current pose toward ``target``, then the move there with
        continuous capture; ``cands``: the grasps planned here (None: not planned);
        ``t0``/``t1``: when grasp planning began and ended. ``trusted``: the target may
        steer the view scores (the oracle's target column). With ``stop`` and a target
        it considers, no move is made where it says no candidate is worth one
        (:class:`~heapgrasp.loop.extensions.EarlyStop`). Returns False when it stopped."""
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
            None if self.truth is None else self.truth.meshes(),
            target=None if target is None or not trusted else target.pose,
        )
        scores: npt.NDArray[np.float32] | None = None
        if stop is not None and target is not None and stop.considers(target):
            # The stop test counts eq. 14 on the target's region, whether or not that
            # region steers the choice below (it does not where gamma2 = 0).
            region_ctx = ctx if trusted else dataclasses.replace(ctx, target=target.pose)
            region_scores = self.view_scorer.scores(region_ctx)
            worth = stop.worth(region_scores, self.candidates, phase.current, target.pose)
            if trusted:
                scores = region_scores
            if stop.stops(worth):
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
                if cands is not None:
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

    def _sweep(self, phase: _PhaseLog, sweep: RimSweep) -> None:
        """The rim sweep (:class:`~heapgrasp.loop.extensions.RimSweep`), capturing, until
        the grasp planned at one of its waypoints is sure."""
        cfg = self.config
        goals = sweep.waypoints(
            self.sphere, phase.current, np.asarray(phase.positions), cfg.theta_max, cfg.V
        )
        for goal in goals:
            visited = self._visit(phase, goal, "sweep")
            if visited is None:
                continue
            cap, duration = visited
            record: dict[str, Any] = {
                "sweep": True,
                "position": goal[:3, 3].tolist(),
                "frames": len(cap),
                "duration_s": duration,
            }
            phase.waypoints.append(record)
            t0 = time.perf_counter()
            cands = self.grasp_candidates()
            phase.compute += time.perf_counter() - t0
            top = top_scoring(cands)
            record["best_score"] = None if top is None else top.score
            # planned on the grid as it is: the final grasp's, if no move follows
            phase.final_candidates = cands
            if sweep.sure(top):
                return

    def _final_choice(
        self, cands: list[GraspCandidate], target: GraspCandidate | None
    ) -> tuple[GraspCandidate | None, GraspCandidate | None]:
        """The top-scoring candidate and the one to execute: for HEAPGrasp, eq. 16 once
        more toward the last waypoint's ``target`` (the grasp its views were planned
        for); for the fixed-view methods the top-scoring one."""
        best = top_scoring(cands)
        if self.adaptive:
            return best, select_target(cands, target, self.config.gamma1)
        return best, best

    def _adaptive_views(self, phase: _PhaseLog) -> GraspCandidate | None:
        """HEAPGrasp's view waypoints (eq. 16-19), then the rim sweep where it applies;
        returns the last target grasp."""
        cfg = self.config
        target: GraspCandidate | None = None
        for ell in range(cfg.L):
            t0 = time.perf_counter()
            gamma2 = cfg.gamma2_first if ell == 0 else cfg.gamma2
            # The early stop plans a target even where gamma2 = 0, so that its region
            # can be checked for views that would still carve it.
            stop = self.early_stop if self.early_stop and self.early_stop.applies(ell) else None
            if gamma2 == 0.0 and stop is None:
                # §VI-B: with gamma2 = 0 a grasp planned here steers nothing (eq. 18
                # uses s alone, the oracle counts the whole grid) and anchors no
                # later target (below), so it is not planned at all: at p0 with
                # Table I's gamma2_first, and at every waypoint with gamma2 = 0.
                cands = None
            else:
                cands = self.grasp_candidates()
                # No candidate at this waypoint: no target, and eq. 18 uses s alone.
                target = select_target(cands, target, cfg.gamma1)
                if self.observer is not None:
                    self.observer.target(target)
            # A target planned where gamma2 = 0 is unreliable (§VI-B): no region.
            moved = self._view_step(
                phase,
                cands,
                target,
                gamma2,
                t0,
                time.perf_counter(),
                trusted=gamma2 > 0,
                stop=stop,
            )
            if not moved:
                return target
            if gamma2 == 0.0:
                # §VI-B: grasps planned before the first view waypoint are unreliable,
                # which is why gamma2 = 0 there; neither may such a grasp anchor the
                # target of eq. 16 at the next waypoint.
                target = None
        # The sweep is for a grasp the phase is unsure of: where the plan before the last
        # move found none, the phase ends as it would without the sweep.
        planned = bool(phase.waypoints and phase.waypoints[-1].get("grasp_candidates"))
        if self.sweep is not None and planned:
            self._sweep(phase, self.sweep)
        return target

    def fine_width_grasp(self) -> tuple[GraspCandidate | None, dict[str, Any]]:
        """``RunConfig.fine_width``, where a phase would end with no candidate: a grasp
        whose opening is measured finer than the grid's voxel, and a record of the search.

        The analytic planner measures an opening at the outer faces of the extreme
        voxels, but carving keeps a voxel when its *centre* projects inside every
        silhouette, so the object may end anywhere within half a voxel of that centre:
        the faces count up to one voxel (7.5 mm) too many, and a lying box whose side is
        within a voxel of the hand's opening gets no grasp; two touching objects merge
        into one blob (``docs/experiments.md``, "Clearing the table"). The phase's
        silhouettes are carved again into a grid reaching :data:`FINE_WIDTH_MARGIN`
        voxels beyond the scene cube on every side but the table's (an object whose
        origin lies in the cube may reach out of it, and the planner takes no grasp
        whose closing touches the grid's side) and planned by :attr:`wide_planner` (the
        opening one voxel wider, i.e. measured at the extreme centres), in two passes
        (:data:`FINE_WIDTH_PASSES`): at the grid's voxel, scored by the critic; then,
        where that finds nothing, at half of it, by the planner's own score (the
        critic reads crops of the grid's voxel). Each pass's candidates, best first,
        are checked with the hand fully open against the silhouettes carved again
        around each (:meth:`~heapgrasp.perception.silhouette.SilhouettePerception.local_input`,
        the voxel :data:`FINE_WIDTH_DIVISOR` times smaller than the grid's); the first
        whose hand touches nothing of that finer hull and closes on some of it is
        taken. At most :data:`FINE_WIDTH_TRIES` are checked per pass."""
        assert self.wide_planner is not None
        record: dict[str, Any] = {"found": False, "passes": []}
        perception = self.perception
        if not isinstance(perception, SilhouettePerception):
            return None, record
        v = self.frame.voxel_size
        size = self.frame.size + 2 * FINE_WIDTH_MARGIN * v
        centre = np.asarray(self.frame.origin) + self.frame.size / 2
        centre[2] = self.frame.origin[2] + size / 2  # the table's side stays where it is
        gripper = self.robot.gripper.geometry
        # the check's cube holds the fingers, open, from the pre-grasp pose to the grasp
        low = gripper.finger_base - PREGRASP_DISTANCE
        reach = max(gripper.finger_tip - low, gripper.max_opening + 2 * gripper.base_thickness)
        check_size = max(FINE_WIDTH_CUBE, reach + 0.02)
        check_resolution = FINE_WIDTH_DIVISOR * round(check_size / v)
        for divisor, use_critic in FINE_WIDTH_PASSES:
            resolution = divisor * (self.frame.resolution + 2 * FINE_WIDTH_MARGIN)
            grid, frame = perception.local_grid(centre, size, resolution)
            high = grid.high_confidence(self.config.lam)
            cands = self._candidates(
                self.wide_planner,
                perception.planner_input(high, frame),
                high,
                frame,
                self.critic if use_critic else None,
            )
            tried = {"voxel_m": frame.voxel_size, "candidates": len(cands), "checked": 0}
            record["passes"].append(tried)
            for cand in cands[:FINE_WIDTH_TRIES]:
                tried["checked"] += 1
                middle = cand.pose[:3, 3] + 0.5 * (low + gripper.finger_tip) * cand.pose[:3, 2]
                occ, near = perception.local_input(middle, check_size, check_resolution)
                check = HullCheck(
                    occ > 0, near, gripper=gripper, pregrasp_distance=PREGRASP_DISTANCE
                )
                if not bool(check(cand.pose[None])[0]):
                    record.update(found=True, score=cand.score, voxel_m=frame.voxel_size)
                    return cand, record
        return None, record

    def _fixed_views(self, phase: _PhaseLog, turn: float = 0.0) -> None:
        """The fixed-view methods' waypoints (turned by ``turn``, rad)."""
        for goal in self.fixed_waypoints(turn):
            visited = self._visit(phase, goal, "fixed")
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

    def _look(
        self, phase: _PhaseLog, turn: float = 0.0
    ) -> tuple[
        list[GraspCandidate],
        GraspCandidate | None,
        GraspCandidate | None,
        list[GraspCandidate] | None,
        float,
    ]:
        """The phase's view waypoints (the fixed methods' turned by ``turn``, rad), then
        grasp planning on the final grid. Returns the candidates, the top-scoring one,
        the one to execute (None: no candidate), the candidates planned where viewing
        stopped early (None: the final grid was planned again) and the final planning
        time (s)."""
        target = self._adaptive_views(phase) if self.adaptive else None
        if not self.adaptive:
            self._fixed_views(phase, turn)
        t0 = time.perf_counter()
        # Where viewing stopped early (or the sweep became sure) the grid is the one just
        # planned there.
        final = phase.final_candidates
        cands = final if final is not None else self.grasp_candidates()
        best, chosen = self._final_choice(cands, target)
        final_latency = time.perf_counter() - t0
        if self.observer is not None:
            self.observer.target(chosen)
        phase.compute += final_latency
        return cands, best, chosen, final, final_latency

    def plan(self) -> PlanResult:
        """Runs one phase up to the grasp (see the module docstring)."""
        self.robot.arm.park()
        self.perception.reset()
        if self.reference is not None:
            self.reference.reset()
        self.joint_path_errors = 0
        self.unreachable_waypoints = 0
        start = self.initial_pose()
        if self.observer is not None:
            self.observer.phase_started(self.phases_planned, start)
        self.phases_planned += 1
        first = self.robot.arm.look(start)
        phase = _PhaseLog(first.cam2world, [first.cam2world[:3, 3]])
        phase.compute += self._perceive([first])
        cands, best, chosen, final, final_latency = self._look(phase)
        looks: list[dict[str, Any]] = []
        for turn in LOOK_AGAIN_TURNS[: self.config.look_again]:
            if chosen is not None:
                break
            # No candidate: the scene has not changed, so the grid is kept and carved
            # further from the start turned about the scene, before the phase gives up.
            n_waypoints = len(phase.waypoints)
            turned = self.initial_pose(turn)
            visited = self._visit(phase, turned, "look-again")
            if visited is not None:
                phase.waypoints.append(
                    {
                        "look_again": len(looks) + 1,
                        "position": turned[:3, 3].tolist(),
                        "frames": len(visited[0]),
                        "duration_s": visited[1],
                    }
                )
            phase.final_candidates, phase.stopped = None, None
            # the look that found nothing: its final grid's planning (one call)
            before = {"final_planning_s": final_latency, "final_replanned": final is None}
            cands, best, chosen, final, final_latency = self._look(phase, turn)
            looks.append(
                {
                    "previous_look": before,
                    "turn_deg": float(np.degrees(turn)),
                    "waypoints": len(phase.waypoints) - n_waypoints,
                    "final_candidates": len(cands),
                    "found": chosen is not None,
                }
            )
        fine: dict[str, Any] | None = None
        if chosen is None and self.wide_planner is not None:
            t0 = time.perf_counter()
            chosen, fine = self.fine_width_grasp()
            fine["time_s"] = time.perf_counter() - t0
            phase.compute += fine["time_s"]
            if chosen is not None:
                best = chosen
                if self.observer is not None:
                    self.observer.target(chosen)
        memory: dict[str, Any] | None = None
        if isinstance(self.perception, SilhouettePerception):
            memory = self.perception.memory_record
            self.perception.remember()
        positions, motion = phase.positions, phase.motion
        extra: dict[str, Any] = {
            "waypoints": phase.waypoints,
            "frames": self.perception.frames_seen,
            "final_candidates": len(cands),
            "final_planning_s": final_latency,
            # whether that time planned grasps again (not where viewing stopped early or
            # the sweep became sure: those candidates were planned at the last waypoint)
            "final_replanned": final is None,
            "stopped_early": phase.stopped,
            "joint_path_errors": self.joint_path_errors,
            "unreachable_waypoints": self.unreachable_waypoints,
            "target_grasp": _candidate_record(chosen),
            "best_grasp": _candidate_record(best),
            "looked_again": looks,
        }
        if fine is not None:
            extra["fine_width"] = fine
        if self.config.scene_memory:
            extra["memory"] = memory
        if self.reference is not None and isinstance(self.perception, SilhouettePerception):
            lam = self.config.lam
            extra["reference_grid"] = grid_agreement(
                self.perception.grid.high_confidence(lam) > 0,
                self.reference.grid.high_confidence(lam) > 0,
            )
        if chosen is None:
            if self.observer is not None:
                self.observer.phase_ended(None)
            return PlanResult(
                None, np.asarray(positions), motion, compute_time=phase.compute, extra=extra
            )
        grasp_position = chosen.pose[:3, 3]
        # The camera travels with the hand to the pre-grasp pose, then approaches.
        pregrasp = chosen.pose.copy()
        pregrasp[:3, 3] -= PREGRASP_DISTANCE * chosen.pose[:3, 2]
        approach = np.stack([phase.current, phase.current.copy()])
        approach[1, :3, 3] = pregrasp[:3, 3]
        motion += time_path(approach, self.limits).duration
        positions.append(grasp_position)
        opening = self.robot.gripper.geometry.max_opening
        # A planner whose grasps were labelled with the hand fully open (the grasp
        # network, as VGN) has them executed so; the others open to their width + 1 cm.
        width = opening if self.grasp_planner.opens_fully else chosen.width
        grasp = Grasp(chosen.pose, min(width, opening))
        if self.observer is not None:
            self.observer.phase_ended(grasp)
        return PlanResult(
            grasp,
            np.asarray(positions),
            motion,
            target_object=None if self.truth is None else self.truth.object_near(grasp_position),
            compute_time=phase.compute,
            extra=extra,
        )


def _either(
    first: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.bool_]],
    second: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.bool_]],
) -> Callable[[npt.NDArray[np.float64]], npt.NDArray[np.bool_]]:
    """A grasp check rejecting what ``first`` or ``second`` rejects; ``second`` judges
    only the poses ``first`` kept."""

    def check(poses: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
        out = np.asarray(first(poses), dtype=bool).copy()
        kept = ~out
        if kept.any():
            out[kept] = second(poses[kept])
        return out

    return check
