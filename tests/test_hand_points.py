"""hand_point_counts (core hand_points): points inside the hand's boxes at grasp poses."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from heapgrasp import HeapgraspError, hand_point_counts
from heapgrasp.geometry.gripper import PANDA_HAND
from scipy.spatial.transform import Rotation

HAND = dataclasses.asdict(PANDA_HAND)


def _boxes(opening: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """The hand's boxes in the TCP frame, from GripperGeometry's fields (the reference)."""
    g = PANDA_HAND
    fx, fy = g.palm_front_half
    bx, by = g.palm_back_half
    hw, o2 = g.finger_width / 2, opening / 2
    out = [
        (np.array([-fx, -fy, g.palm_split]), np.array([fx, fy, g.palm_front])),
        (np.array([-bx, -by, g.palm_back]), np.array([bx, by, g.palm_split])),
    ]
    for sign in (1.0, -1.0):
        for thick, z0, z1 in (
            (g.tip_thickness, g.finger_split, g.finger_tip),
            (g.base_thickness, g.finger_base, g.finger_split),
        ):
            a, b = sign * o2, sign * (o2 + thick)
            out.append((np.array([-hw, min(a, b), z0]), np.array([hw, max(a, b), z1])))
    return out


def _reference(poses, openings, points):
    counts = []
    for pose, w in zip(poses, openings, strict=True):
        local = (points - pose[:3, 3]) @ pose[:3, :3]
        counts.append(
            sum(int(((local > lo) & (local < hi)).all(axis=1).sum()) for lo, hi in _boxes(w))
        )
    return np.array(counts)


@pytest.mark.parametrize("seed", [0, 1])
def test_counts_match_a_brute_force_reference(seed):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.12, 0.12, (5000, 3))
    n = 60
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.random(n, random_state=seed).as_matrix()
    poses[:, :3, 3] = rng.uniform(-0.05, 0.05, (n, 3))
    openings = rng.uniform(0.01, 0.08, n)
    got = hand_point_counts(HAND, poses, openings, points)
    np.testing.assert_array_equal(got, _reference(poses, openings, points))
    assert got.dtype == np.uint32 and (got > 0).any()
    # The index's cell size and the thread count change nothing.
    np.testing.assert_array_equal(
        hand_point_counts(HAND, poses, openings, points, cell=0.003, threads=1), got
    )


def test_bad_input_raises_named_errors():
    pose = np.eye(4)[None]
    pts = np.zeros((3, 3))
    with pytest.raises(HeapgraspError, match="opening"):
        hand_point_counts(HAND, pose, np.array([0.2]), pts)
    with pytest.raises(HeapgraspError, match="openings"):
        hand_point_counts(HAND, pose, np.array([0.02, 0.03]), pts)
    with pytest.raises(HeapgraspError, match="points"):
        hand_point_counts(HAND, pose, np.array([0.02]), np.zeros((3, 2)))
    with pytest.raises(HeapgraspError, match="points"):
        hand_point_counts(HAND, pose, np.array([0.02]), np.array([[0.0, np.nan, 0.0]]))
    with pytest.raises(HeapgraspError, match="cell"):
        hand_point_counts(HAND, pose, np.array([0.02]), pts, cell=0.0)
    with pytest.raises(HeapgraspError, match="hand"):
        hand_point_counts({"finger_width": 0.02}, pose, np.array([0.02]), pts)
    assert hand_point_counts(HAND, pose, np.array([0.02]), np.zeros((0, 3))).tolist() == [0]


def test_an_inflated_hand_grows_outward_and_keeps_its_opening():
    m = 0.003
    big = PANDA_HAND.inflated(m)
    assert big.max_opening == PANDA_HAND.max_opening
    assert PANDA_HAND.inflated(0.0) == PANDA_HAND
    g = PANDA_HAND
    # Just outside the bare hand, TCP frame: in front of the palm's face, beside the
    # palm, beyond a fingertip, outside a finger; and between the pads at 4 cm.
    outside = np.array(
        [
            [0.0, 0.0, g.palm_front + m / 2],
            [g.palm_front_half[0] + m / 2, 0.0, (g.palm_front + g.palm_split) / 2],
            [0.0, 0.02 + g.tip_thickness / 2, g.finger_tip + m / 2],
            [0.0, 0.02 + g.tip_thickness + m / 2, g.finger_tip - 0.005],
        ]
    )
    between = np.array([[0.0, 0.02 - m / 2, g.finger_tip - 0.005]])
    pose = np.eye(4)[None]
    for p in outside:
        assert hand_point_counts(HAND, pose, np.array([0.04]), p[None])[0] == 0
        assert hand_point_counts(dataclasses.asdict(big), pose, np.array([0.04]), p[None])[0] == 1
    assert hand_point_counts(dataclasses.asdict(big), pose, np.array([0.04]), between)[0] == 0
    with pytest.raises(ValueError, match="margin"):
        PANDA_HAND.inflated(-0.001)
