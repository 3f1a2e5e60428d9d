"""Next-pose selection, HEAPGrasp eq. 16-19, on hand-made cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from heapgrasp.planning.selection import (
    detour,
    pose_distance,
    progress_rate,
    select_next_waypoint,
    select_target,
    top_scoring,
)
from heapgrasp.planning.volumes import GraspCandidate


def pose(position: tuple[float, float, float], yaw: float = 0.0) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    m[:3, 3] = position
    return m


def cand(position: tuple[float, float, float], score: float, yaw: float = 0.0) -> GraspCandidate:
    return GraspCandidate(pose(position, yaw), 0.05, score, (0, 0, 0))


def test_eq17_translation_plus_sign_invariant_quaternion_term() -> None:
    a = pose((0, 0, 0))
    b = pose((0.3, 0.4, 0))
    assert pose_distance(a, b, 0.2) == pytest.approx(0.5)
    # A yaw of 90°: q = (0, 0, sin 45°, cos 45°) vs (0, 0, 0, 1).
    c = pose((0, 0, 0), math.pi / 2)
    qa, qc = (
        np.array([0, 0, 0, 1.0]),
        np.array([0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)]),
    )
    expect = 0.2 * min(np.linalg.norm(qa + qc), np.linalg.norm(qa - qc))
    assert pose_distance(a, c, 0.2) == pytest.approx(expect)
    # A full turn is the same rotation: q and -q give distance 0.
    assert pose_distance(a, pose((0, 0, 0), 2 * math.pi), 0.2) == pytest.approx(0.0, abs=1e-12)
    # Broadcasting over leading axes.
    d = pose_distance(np.stack([a, b, c]), a[None], 0.2)
    assert d.shape == (3,)
    with pytest.raises(ValueError, match="gamma1"):
        pose_distance(a, b, -1.0)


def test_eq16_keeps_the_candidate_closest_to_the_previous_target() -> None:
    prev = cand((0.10, 0.10, 0.05), 0.9)
    near_low = cand((0.11, 0.10, 0.05), 0.81)
    far_high = cand((0.25, 0.20, 0.05), 0.99)
    assert select_target([far_high, near_low], prev, 0.2) is near_low
    # Without a previous target (first waypoint), the best score wins.
    assert select_target([near_low, far_high], None) is far_high
    assert top_scoring([near_low, far_high]) is far_high
    assert select_target([], prev) is None
    # The orientation term decides between equally far candidates.
    origin = cand((0.0, 0.0, 0.0), 0.9)
    same_yaw = cand((0.02, 0.0, 0.0), 0.85, yaw=0.0)
    turned = cand((-0.02, 0.0, 0.0), 0.95, yaw=math.pi / 2)
    assert select_target([turned, same_yaw], origin, 0.2) is same_yaw
    assert select_target([same_yaw, turned], origin, 0.0) is turned  # tie → better score


def test_eq19_progress_rate() -> None:
    target = pose((0.0, 0.0, 0.0))
    current = pose((1.0, 0.0, 0.0))
    cands = np.stack([pose((0.5, 0.0, 0.0)), pose((1.0, 0.0, 0.0)), pose((2.0, 0.0, 0.0))])
    h = progress_rate(cands, current, target, 0.2)
    np.testing.assert_allclose(h, [0.5, 0.0, -1.0])
    # At the target already: no progress possible, h = 0.
    np.testing.assert_allclose(progress_rate(cands, target, target), 0.0)


def test_eq18_trades_view_score_against_progress() -> None:
    target = pose((0.0, 0.0, 0.0))
    current = pose((1.0, 0.0, 0.0))
    cands = np.stack([pose((0.2, 0.0, 0.0)), pose((1.5, 0.0, 0.0))]).reshape(2, 1, 4, 4)
    scores = np.array([[0.5], [0.7]])  # the far view sees more
    assert select_next_waypoint(scores, cands, current, target, 0.0) == (1, 0)
    assert select_next_waypoint(scores, cands, current, None, 0.35) == (1, 0)
    # h = 0.8 and -0.5: 0.5 + 0.35*0.8 = 0.78 > 0.7 - 0.175.
    assert select_next_waypoint(scores, cands, current, target, 0.35) == (0, 0)
    with pytest.raises(ValueError, match="view_scores"):
        select_next_waypoint(scores[:1], cands, current, target, 0.35)
    with pytest.raises(ValueError, match="NaN"):
        select_next_waypoint(np.array([[np.nan], [0.1]]), cands, current, target, 0.35)
    with pytest.raises(ValueError, match="gamma2"):
        select_next_waypoint(scores, cands, current, target, -0.1)


def test_detour_is_the_path_a_waypoint_adds_on_the_way_to_the_grasp() -> None:
    current = pose((1.0, 0.0, 0.0))
    grasp = pose((0.0, 0.0, 0.0), yaw=1.0)  # the orientation plays no part
    cands = np.stack(
        [
            pose((0.5, 0.0, 0.0)),  # on the way: nothing added
            pose((1.0, 0.0, 0.0)),  # staying put: nothing added
            pose((1.0, 1.0, 0.0)),  # 1 there, sqrt(2) on, 1 saved
            pose((2.0, 0.0, 0.0)),  # 1 there and 1 back
        ]
    ).reshape(2, 2, 4, 4)
    d = detour(cands, current, grasp)
    assert d.shape == (2, 2)
    np.testing.assert_allclose(d.ravel(), [0.0, 0.0, math.sqrt(2.0), 2.0], atol=1e-12)
    with pytest.raises(ValueError, match="candidate_poses"):
        detour(np.zeros((3, 3)), current, grasp)
    bad = grasp.copy()
    bad[0, 3] = np.nan
    with pytest.raises(ValueError, match="target_pose"):
        detour(cands, current, bad)
