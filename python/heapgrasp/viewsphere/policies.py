"""Natarajan et al.'s baseline policies on the discrete viewsphere, and its episodes.

The benchmark of seed ``001_95c7dd5c6a7c3646.txt`` (§4.1) starts the camera at
:data:`~heapgrasp.viewsphere.sphere.START`, looks for a grasp on what it has seen, and
while none is found moves one step (:meth:`DiscreteViewsphere.move`, with its fallbacks)
in the direction a policy picks, for at most ``max_steps`` moves (6 in the paper). A
policy maps the episode's state to one of the 8 directions
(:data:`~heapgrasp.viewsphere.sphere.DIRECTIONS`):

- :class:`RandomPolicy`: uniform over the 8, from a seeded generator;
- :class:`BrickPolicy`: always north-east (the paper's naive baseline);
- :func:`breadth_first`: not a policy but the exhaustive search the others are measured
  against, the fewest moves from the start to a set of views that yields a grasp.

Whether a set of views yields a grasp is the caller's (``grasp_found``): the world
renders the views, fuses them and runs the synthesis. Fusion is order-free, so
:func:`breadth_first` asks once per distinct set of visited poses.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp.viewsphere.sphere import (
    DIRECTIONS,
    START,
    DiscreteViewsphere,
    SpherePose,
)

__all__ = [
    "BrickPolicy",
    "Episode",
    "Fused",
    "RandomPolicy",
    "ViewState",
    "ViewpointPolicy",
    "ViewspherePolicy",
    "breadth_first",
    "pose_key",
    "run_episode",
    "run_viewpoint_episode",
]

#: Decimal places of a pose's angles in :func:`pose_key` (radians).
_KEY_DIGITS = 6

PoseKey = tuple[float, float]
GraspFound = Callable[[frozenset[PoseKey]], bool]


def pose_key(pose: SpherePose) -> PoseKey:
    """A hashable key of ``pose`` (angles rounded; the azimuth of a pole is 0)."""
    polar = round(pose.polar, _KEY_DIGITS)
    azimuth = 0.0 if polar == 0.0 else round(pose.azimuth % (2 * math.pi), _KEY_DIGITS)
    return (azimuth, polar)


#: The fused state of a set of views: the object's points and the unexplored region's
#: points, ``(N, 3)`` and ``(M, 3)`` world coordinates.
Fused = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]


@dataclass(frozen=True)
class ViewState:
    """What a policy sees: the camera's pose, the poses visited (in order, the current
    one last), the moves made so far, and (:meth:`fused`) what the views show."""

    pose: SpherePose
    visited: tuple[SpherePose, ...]
    step: int
    observe: Callable[[tuple[SpherePose, ...]], Fused] | None = None
    """The episode's perception, when it has one (computed only when asked)."""

    def fused(self) -> Fused:
        """The object's and the unexplored region's points after the visited views."""
        if self.observe is None:
            raise ValueError("this episode runs without perception: no fused state")
        return self.observe(self.visited)


@runtime_checkable
class ViewspherePolicy(Protocol):
    """Picks the next direction (an index of ``DIRECTIONS``)."""

    name: str

    def reset(self, seed: int) -> None:
        """Starts a new episode (a policy with randomness draws from ``seed``)."""

    def choose(self, state: ViewState) -> int:
        """The direction to move in next."""


@runtime_checkable
class ViewpointPolicy(Protocol):
    """Picks the next viewpoint itself, anywhere on the sphere (the information gain
    comparison), rather than a direction to step in."""

    name: str

    def reset(self, seed: int) -> None:
        """Starts a new episode."""

    def choose_view(self, state: ViewState) -> SpherePose:
        """The viewpoint to fly to next (not one visited)."""


@dataclass
class RandomPolicy:
    """A uniformly random direction at each step."""

    name: str = "random"
    _rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(0))

    def reset(self, seed: int) -> None:
        self._rng = np.random.default_rng(seed)

    def choose(self, state: ViewState) -> int:
        return int(self._rng.integers(len(DIRECTIONS)))


@dataclass
class BrickPolicy:
    """Always north-east (Natarajan et al.'s "brick on the gas pedal")."""

    name: str = "brick"

    def reset(self, seed: int) -> None:
        pass

    def choose(self, state: ViewState) -> int:
        return DIRECTIONS.index("NE")


@dataclass(frozen=True)
class Episode:
    """One episode: the poses visited (the start first), the directions taken, and the
    moves until a grasp was found (``max_steps`` when none was)."""

    poses: tuple[SpherePose, ...]
    directions: tuple[int, ...]
    steps: int
    found: bool
    complete: bool = True
    """False when a search stopped at its budget before an answer (not found)."""
    travelled: float = 0.0
    """The camera's path along the sphere, as the angle seen from the centre (radians;
    one step is the sphere's ``step``)."""


def _checked(
    max_steps: int, sphere: DiscreteViewsphere | None, start: SpherePose
) -> DiscreteViewsphere:
    """The episode's sphere (the default one when None); ValueError on a bad
    ``max_steps`` or a start off the sphere."""
    if not (isinstance(max_steps, int) and max_steps >= 0):
        raise ValueError(f"max_steps must be an int >= 0, got {max_steps!r}")
    sphere = DiscreteViewsphere() if sphere is None else sphere
    if not sphere.valid(start):
        raise ValueError(f"start {start} is not a valid pose of the viewsphere")
    return sphere


def _episode(
    grasp_found: GraspFound,
    step: Callable[[ViewState], tuple[int | None, SpherePose]],
    sphere: DiscreteViewsphere,
    start: SpherePose,
    max_steps: int,
    observe: Callable[[tuple[SpherePose, ...]], Fused] | None,
) -> Episode:
    """The episode loop: ``step(state)`` gives the direction taken (None for a flight)
    and the next pose, until ``grasp_found`` holds or ``max_steps`` steps were made."""
    poses = [start]
    directions: list[int] = []
    travelled = 0.0
    while True:
        steps = len(poses) - 1
        if grasp_found(frozenset(pose_key(p) for p in poses)):
            return Episode(tuple(poses), tuple(directions), steps, True, True, travelled)
        if steps == max_steps:
            return Episode(tuple(poses), tuple(directions), max_steps, False, True, travelled)
        taken, nxt = step(ViewState(poses[-1], tuple(poses), steps, observe))
        travelled += sphere.arc(poses[-1], nxt)
        if taken is not None:
            directions.append(taken)
        poses.append(nxt)


def run_episode(
    policy: ViewspherePolicy,
    grasp_found: GraspFound,
    *,
    sphere: DiscreteViewsphere | None = None,
    start: SpherePose = START,
    max_steps: int = 6,
    seed: int = 0,
    observe: Callable[[tuple[SpherePose, ...]], Fused] | None = None,
) -> Episode:
    """Runs ``policy`` from ``start`` until ``grasp_found`` holds for the poses visited
    or ``max_steps`` moves were made; ``observe`` gives the policy the fused state of
    the views (:meth:`ViewState.fused`)."""
    sphere = _checked(max_steps, sphere, start)
    policy.reset(seed)

    def step(state: ViewState) -> tuple[int | None, SpherePose]:
        return sphere.move(state.pose, policy.choose(state))

    return _episode(grasp_found, step, sphere, start, max_steps, observe)


def run_viewpoint_episode(
    policy: ViewpointPolicy,
    grasp_found: GraspFound,
    *,
    sphere: DiscreteViewsphere | None = None,
    start: SpherePose = START,
    max_steps: int = 6,
    seed: int = 0,
    observe: Callable[[tuple[SpherePose, ...]], Fused] | None = None,
) -> Episode:
    """:func:`run_episode` for a policy that picks viewpoints: ``steps`` counts the
    viewpoints flown to (at most ``max_steps``), ``travelled`` the arcs between them,
    ``directions`` is empty. A viewpoint already visited or off the sphere is a
    ValueError naming it."""
    sphere = _checked(max_steps, sphere, start)
    policy.reset(seed)

    def step(state: ViewState) -> tuple[int | None, SpherePose]:
        nxt = policy.choose_view(state)
        if not sphere.valid(nxt) or pose_key(nxt) in {pose_key(p) for p in state.visited}:
            raise ValueError(f"{policy.name} chose {nxt}: visited or not on the viewsphere")
        return None, nxt

    return _episode(grasp_found, step, sphere, start, max_steps, observe)


def breadth_first(
    grasp_found: GraspFound,
    *,
    sphere: DiscreteViewsphere | None = None,
    start: SpherePose = START,
    max_steps: int = 6,
    max_sets: int | None = None,
) -> Episode:
    """The fewest moves from ``start`` to a set of visited poses for which
    ``grasp_found`` holds (ties: the first in direction order, level by level), asking
    ``grasp_found`` once per distinct set; ``found`` False after ``max_steps`` levels.

    ``max_sets`` bounds the distinct sets asked about (the levels grow about sevenfold
    each): past it the search stops, not found, with ``complete`` False."""
    if max_sets is not None and not (isinstance(max_sets, int) and max_sets >= 1):
        raise ValueError(f"max_sets must be an int >= 1 or None, got {max_sets!r}")
    sphere = _checked(max_steps, sphere, start)
    answers: dict[frozenset[PoseKey], bool] = {}

    class _Budget(Exception):
        pass

    def found(poses: Iterable[SpherePose]) -> bool:
        key = frozenset(pose_key(p) for p in poses)
        if key not in answers:
            if max_sets is not None and len(answers) >= max_sets:
                raise _Budget
            answers[key] = grasp_found(key)
        return answers[key]

    frontier: list[tuple[tuple[SpherePose, ...], tuple[int, ...]]] = [((start,), ())]
    if found(frontier[0][0]):
        return Episode((start,), (), 0, True)
    seen = {(pose_key(start), frozenset([pose_key(start)]))}
    try:
        for depth in range(1, max_steps + 1):
            nxt_frontier = []
            for poses, directions in frontier:
                for d in range(len(DIRECTIONS)):
                    taken, nxt = sphere.move(poses[-1], d)
                    if taken != d:  # the fallback leads where another direction does
                        continue
                    path = (*poses, nxt)
                    state = (pose_key(nxt), frozenset(pose_key(p) for p in path))
                    if state in seen:
                        continue
                    seen.add(state)
                    if found(path):
                        arc = depth * sphere.step
                        return Episode(path, (*directions, d), depth, True, True, arc)
                    nxt_frontier.append((path, (*directions, d)))
            frontier = nxt_frontier
    except _Budget:
        return Episode((start,), (), max_steps, False, complete=False)
    return Episode((start,), (), max_steps, False)
