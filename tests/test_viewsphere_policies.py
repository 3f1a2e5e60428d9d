"""Seed 001's baseline policies and breadth-first search (viewsphere.policies)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from heapgrasp.viewsphere.policies import (
    BrickPolicy,
    RandomPolicy,
    ViewspherePolicy,
    breadth_first,
    pose_key,
    run_episode,
)
from heapgrasp.viewsphere.sphere import DIRECTIONS, START, DiscreteViewsphere

SPHERE = DiscreteViewsphere()


def _low_view(keys) -> bool:
    """A grasp shows once a view below 60° of polar angle has been seen."""
    return any(polar >= math.radians(60.0) for _, polar in keys)


def test_breadth_first_finds_the_fewest_moves():
    episode = breadth_first(_low_view)
    # START is 25.7° from the pole; two steps south reach 65.7°, one cannot.
    assert episode.found and episode.steps == 2
    assert {DIRECTIONS[d] for d in episode.directions} <= {"SE", "S", "SW"}  # southward
    assert _low_view({pose_key(p) for p in episode.poses})
    # No sequence of one move does it (checked exhaustively).
    for d in range(8):
        _, one = SPHERE.move(START, d)
        assert not _low_view({pose_key(START), pose_key(one)})


def test_breadth_first_asks_once_per_set_of_views_and_gives_up_after_max_steps():
    asked = []

    def never(keys) -> bool:
        asked.append(keys)
        return False

    episode = breadth_first(never, max_steps=3)
    assert not episode.found and episode.steps == 3 and episode.complete
    assert len(asked) == len(set(asked))  # each distinct set once
    assert breadth_first(lambda keys: True).steps == 0
    # A budget of sets stops the search, marked incomplete; a larger one changes nothing.
    asked.clear()
    cut = breadth_first(never, max_steps=3, max_sets=20)
    assert len(asked) == 20 and not cut.found and not cut.complete and cut.steps == 3
    assert breadth_first(_low_view, max_sets=1000) == breadth_first(_low_view)
    with pytest.raises(ValueError, match="max_sets"):
        breadth_first(never, max_sets=0)


def test_breadth_first_is_no_worse_than_any_policy():
    def needs_two_sides(keys) -> bool:  # views on both sides of the x axis, low enough
        az = [a for a, p in keys if p >= math.radians(40.0)]
        return any(math.sin(a) > 0.3 for a in az) and any(math.sin(a) < -0.3 for a in az)

    best = breadth_first(needs_two_sides)
    assert best.found
    for path in itertools.product(range(8), repeat=min(best.steps, 4)):
        poses = [START]
        for d in path:
            poses.append(SPHERE.move(poses[-1], d)[1])
        if needs_two_sides({pose_key(p) for p in poses}):
            assert len(path) >= best.steps


def test_the_brick_goes_north_east_and_random_repeats_with_its_seed():
    brick = run_episode(BrickPolicy(), _low_view)
    assert set(brick.directions) <= {1, 0, 2, 7, 3}  # NE, or its fallbacks
    assert brick.directions[0] == DIRECTIONS.index("NE")
    a = run_episode(RandomPolicy(), _low_view, seed=7)
    b = run_episode(RandomPolicy(), _low_view, seed=7)
    assert a == b
    runs = {run_episode(RandomPolicy(), _low_view, seed=s).directions for s in range(10)}
    assert len(runs) > 1
    assert isinstance(RandomPolicy(), ViewspherePolicy) and isinstance(
        BrickPolicy(), ViewspherePolicy
    )


def test_an_episode_stops_at_max_steps_and_counts_them():
    episode = run_episode(BrickPolicy(), lambda keys: False, max_steps=6)
    assert not episode.found and episode.steps == 6 and len(episode.poses) == 7
    assert all(SPHERE.valid(p) for p in episode.poses)
    with pytest.raises(ValueError, match="max_steps must be an int >= 0"):
        run_episode(BrickPolicy(), _low_view, max_steps=-1)
    with pytest.raises(ValueError, match="is not a valid pose"):
        breadth_first(_low_view, start=START._replace(polar=math.radians(89.0)))


def test_a_policy_sees_the_fused_state_when_the_episode_has_one():
    seen = []

    class Looking:
        name = "looking"

        def reset(self, seed: int) -> None:
            pass

        def choose(self, state) -> int:
            obj, unexplored = state.fused()
            seen.append((len(state.visited), obj.shape, unexplored.shape))
            return 0

    def observe(poses):
        return np.zeros((len(poses), 3)), np.ones((2 * len(poses), 3))

    episode = run_episode(Looking(), lambda keys: False, max_steps=2, observe=observe)
    assert seen == [(1, (1, 3), (2, 3)), (2, (2, 3), (4, 3))] and episode.steps == 2
    with pytest.raises(ValueError, match="no fused state"):
        run_episode(Looking(), lambda keys: False, max_steps=1)
