"""One object pose of the viewsphere benchmark: every policy's episode from it.

:func:`run_pose` places the object at one of the protocol's yaws in a
:class:`~heapgrasp.viewsphere.world.ViewsphereWorld`, runs each policy's episode from
the start view (Natarajan et al. §4.1: 20° moves until the fused views yield a grasp, or 6
moves) and, unless told not to, executes the grasp it found with the free-flying hand
(:mod:`heapgrasp.viewsphere.execute`). :mod:`heapgrasp.viewsphere.bench` runs it over
objects and poses; :mod:`heapgrasp.viewsphere.report` summarises what it returns.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from heapgrasp.viewsphere.grasps import ViewsphereConfig

__all__ = ["LEARNED", "POLICIES", "SENSORS", "VIEWPOINT_POLICIES", "PoseTask", "run_pose"]

#: The policies, in the order they are reported.
POLICIES = (
    "random",
    "brick",
    "heuristic-2d",
    "heuristic-3d",
    "information-gain",
    "pca-lr",
    "pca-lda",
    "dqn",
    "imitation",
    "heapgrasp-net",
    "heapgrasp-oracle",
    "bfs",
)
#: Policies whose steps are viewpoints flown to, not 20° moves: their success per
#: step is not comparable with the others' and they stay out of Fig. 11 (Table 1
#: compares their path in steps).
VIEWPOINT_POLICIES = ("information-gain",)
#: The learned policies: each runs a policy file (shipped, or ``--weights MODEL=FILE``).
LEARNED = ("pca-lr", "pca-lda", "dqn", "imitation")
#: The sensor options: the paper's ideal depth, or our depth sensor's model with the
#: object of that optical category.
SENSORS = ("ideal", "opaque", "transparent", "specular")


@dataclass(frozen=True)
class PoseTask:
    """One object pose: every policy's episode from it."""

    object_name: str
    meshes: tuple[tuple[Any, Any], ...]
    """The object's meshes at rest (yaw 0)."""
    pose: int
    yaw_deg: float
    policies: tuple[str, ...]
    config: dict[str, Any]
    seed: int
    sensor: str
    execute: bool
    weights: tuple[tuple[str, str], ...] = ()
    """The learned policies' files, ``(model, path)``."""
    perception: str = "depth"
    """What the synthesis reads (:data:`~heapgrasp.viewsphere.grasps.PERCEPTIONS`)."""


def _policy(
    name: str, world: Any, config: ViewsphereConfig, weights: Mapping[str, str] | None = None
) -> Any:
    """The policy ``name`` for episodes in ``world`` (a learned one from ``weights``)."""
    from heapgrasp.viewsphere import heuristics as vh
    from heapgrasp.viewsphere.policies import BrickPolicy, RandomPolicy

    if name in ("random", "brick"):
        return {"random": RandomPolicy, "brick": BrickPolicy}[name]()
    scorer = config.view_scorer(world.sphere, world.camera)
    if name == "heuristic-2d":
        return vh.Heuristic2D(scorer)
    if name == "heuristic-3d":
        return vh.Heuristic3D(scorer, half_length=world.grasps.gripper.max_opening)
    if name == "information-gain":
        return vh.InformationGain(scorer)
    if name in ("heapgrasp-oracle", "heapgrasp-net"):
        from heapgrasp.viewsphere.heapgrasp_views import HeapgraspViewPolicy

        network = None
        if name == "heapgrasp-net":
            from heapgrasp.inference import shipped_weights
            from heapgrasp.planning.view_network import NetworkViewScorer

            path = shipped_weights("view-network")
            if path is None:
                raise ValueError("heapgrasp-net needs the shipped view network; none ships")
            network = NetworkViewScorer(str(path))
        return HeapgraspViewPolicy(
            world.sphere,
            world.camera,
            world.silhouette,
            "oracle" if name == "heapgrasp-oracle" else "network",
            scene=world.objects_scene,
            network=network,
        )
    if name in LEARNED:
        from heapgrasp.viewsphere.learned import LearnedPolicy

        if not weights or name not in weights:
            raise ValueError(f"no policy file for {name}")
        return LearnedPolicy.from_file(weights[name], scorer, name)
    raise ValueError(f"unknown policy {name!r}")


class _Timed:
    """A policy whose decisions are timed (seconds per call, in ``times``)."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.name = policy.name
        self.times: list[float] = []

    @property
    def agreement(self) -> list[bool] | None:
        """The HEAPGrasp network policy's agreement with the oracle, per decision."""
        out: list[bool] | None = getattr(self.policy, "agreement", None)
        return out

    def reset(self, seed: int) -> None:
        self.times = []
        self.policy.reset(seed)

    def choose(self, state: Any) -> int:
        t = time.perf_counter()
        out: int = self.policy.choose(state)
        self.times.append(time.perf_counter() - t)
        return out

    def choose_view(self, state: Any) -> Any:
        t = time.perf_counter()
        out = self.policy.choose_view(state)
        self.times.append(time.perf_counter() - t)
        return out


def run_pose(task: PoseTask) -> dict[str, Any]:
    """Every policy's episode on one object pose (module doc): the pose's record."""
    import math

    from heapgrasp.sim.optics import Category
    from heapgrasp.viewsphere.policies import (
        breadth_first,
        run_episode,
        run_viewpoint_episode,
    )
    from heapgrasp.viewsphere.sphere import DIRECTIONS
    from heapgrasp.viewsphere.world import ViewsphereWorld

    config = ViewsphereConfig.from_dict(task.config)
    sensor = None if task.sensor == "ideal" else Category(task.sensor)
    t0 = time.perf_counter()
    yaw = math.radians(task.yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    world = ViewsphereWorld(
        [(np.asarray(v) @ turn.T, f) for v, f in task.meshes],
        config=config,
        sensor=sensor,
        seed=task.seed * 1000 + task.pose,
        perception=task.perception,
    )
    record: dict[str, Any] = {"pose": task.pose, "yaw_deg": task.yaw_deg, "policies": {}}
    executor = _Executor(task) if task.execute else None
    for name in task.policies:
        t = time.perf_counter()
        sets_before = world.grasps.sets_evaluated
        decisions: list[float] = []
        agreement: list[bool] | None = None
        if name == "bfs":
            episode = breadth_first(
                world.grasp_found,
                sphere=world.sphere,
                start=world.start,
                max_steps=config.max_steps,
                max_sets=config.bfs_max_sets,
            )
        else:
            policy = _Timed(_policy(name, world, config, dict(task.weights)))
            run = run_viewpoint_episode if name == "information-gain" else run_episode
            episode = run(
                policy,
                world.grasp_found,
                sphere=world.sphere,
                start=world.start,
                max_steps=config.max_steps,
                seed=task.seed * 1000 + task.pose,
                observe=world.grasps.fused,
            )
            decisions = policy.times
            agreement = policy.agreement
        grasp = world.grasp(list(episode.poses)) if episode.found else None
        seconds = time.perf_counter() - t
        entry: dict[str, Any] = {
            "path": [DIRECTIONS[d] for d in episode.directions],
            "views_deg": [
                [round(math.degrees(p.azimuth), 3), round(math.degrees(p.polar), 3)]
                for p in episode.poses
            ],
            "steps": episode.steps,
            "travelled_steps": round(episode.travelled / world.sphere.step, 4),
            "found": episode.found,
            "complete": episode.complete,
            "grasp": None if grasp is None else grasp.to_dict(),
            "quality_deg": None if grasp is None else round(grasp.quality, 4),
            "executed": None,
            "seconds": round(seconds, 4),
            "decisions_s": [round(t, 5) for t in decisions],
            **({"oracle_agreement": agreement} if agreement else {}),
            "sets_synthesised": world.grasps.sets_evaluated - sets_before,
        }
        if executor is not None and grasp is not None:
            entry["executed"] = executor.outcome(grasp)
        record["policies"][name] = entry
    record["seconds"] = round(time.perf_counter() - t0, 4)
    return record


class _Executor:
    """Executes found grasps on the pose's object with the simulated hand; the same grasp
    (two policies ending on one set of views) is executed once."""

    def __init__(self, task: PoseTask) -> None:
        self.task = task
        self._done: dict[bytes, str] = {}

    def outcome(self, grasp: Any) -> str:
        from heapgrasp.viewsphere.execute import execute_found_grasp

        key = np.round(grasp.pose, 9).tobytes()
        if key not in self._done:
            self._done[key] = execute_found_grasp(
                self.task.object_name,
                list(self.task.meshes),
                float(np.radians(self.task.yaw_deg)),
                grasp,
            )
        return self._done[key]


# --------------------------------------------------------------------------------------
# Summary
# --------------------------------------------------------------------------------------
