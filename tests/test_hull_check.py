"""The hull check of grasp poses (planning.hull_check) and select_candidates' reject."""

from __future__ import annotations

import numpy as np
import pytest
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.planning.hull_check import HullCheck, hull_boxes
from heapgrasp.planning.volumes import GraspVolumes, select_candidates

FRAME = GridFrame((0.0, 0.0, 0.0), 0.3, 40)  # 7.5 mm voxels, the table at z = 0


def _block(lo: tuple[int, int, int], hi: tuple[int, int, int]) -> np.ndarray:
    occ = np.zeros((40, 40, 40), dtype=bool)
    occ[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] = True
    return occ


def _top_down(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    """A TCP pose approaching straight down, the fingers closing along
    ``(cos yaw, sin yaw, 0)``."""
    c, s = np.cos(yaw), np.sin(yaw)
    y_axis = np.array([c, s, 0.0])
    z_axis = np.array([0.0, 0.0, -1.0])
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([np.cross(y_axis, z_axis), y_axis, z_axis])
    pose[:3, 3] = (x, y, z)
    return pose


def test_hull_boxes_are_the_runs_of_each_column_merged():
    occ = np.zeros((40, 40, 40), dtype=bool)
    occ[3, 4, 0:2] = True
    occ[3, 4, 5:9] = True
    occ[7, 1, 39] = True
    boxes = hull_boxes(occ, FRAME)
    v = FRAME.voxel_size
    spans = sorted((tuple(b.min(0) / v), tuple(b.max(0) / v)) for b in boxes)
    expected = [((3, 4, 0), (4, 5, 2)), ((3, 4, 5), (4, 5, 9)), ((7, 1, 39), (8, 2, 40))]
    assert len(boxes) == 3 and all(b.shape == (8, 3) for b in boxes)
    np.testing.assert_allclose(np.array(spans, dtype=float), np.array(expected, dtype=float))
    assert hull_boxes(np.zeros((40, 40, 40), bool), FRAME) == []
    # Merged across columns: a block is one box, a step two.
    assert len(hull_boxes(_block((5, 6, 0), (9, 12, 3)), FRAME)) == 1
    assert (
        len(hull_boxes(_block((5, 6, 0), (9, 12, 3)) | _block((5, 6, 0), (7, 12, 5)), FRAME)) == 2
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hull_boxes_cover_exactly_the_occupied_voxels(seed):
    rng = np.random.default_rng(seed)
    occ = rng.random((40, 40, 40)) < (0.2, 0.5, 0.9)[seed]
    occ[:, :, 20:] &= rng.random((40, 40, 20)) < 0.5
    v = FRAME.voxel_size
    count = np.zeros(occ.shape, dtype=int)
    boxes = hull_boxes(occ, FRAME)
    for b in boxes:
        lo = np.round(b.min(0) / v).astype(int)
        hi = np.round(b.max(0) / v).astype(int)
        count[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] += 1
    np.testing.assert_array_equal(count, occ.astype(int))  # every voxel once, no more
    with pytest.raises(ValueError, match="occupied must have shape"):
        hull_boxes(np.zeros((4, 4, 4), bool), FRAME)


def test_hull_check_keeps_a_clear_grasp_and_rejects_collisions_and_empty_closings():
    # A block 3 cm (x) by 12 cm (y), 6 cm tall, centred at (0.15, 0.15).
    occ = _block((18, 12, 0), (22, 28, 8))
    check = HullCheck(occ, FRAME, gripper=PANDA_HAND, pregrasp_distance=0.05)
    assert check.boxes == 1
    top = 8 * FRAME.voxel_size
    tips_2cm_down = top - 0.02 + PANDA_HAND.finger_tip  # the TCP's height for it
    grasps = np.stack(
        [
            # closing across the 3 cm side, fingertips 2 cm below the top: clear
            _top_down(0.15, 0.15, tips_2cm_down, yaw=0.0),
            # closing along the 12 cm side: the fingers land on the block
            _top_down(0.15, 0.15, tips_2cm_down, yaw=np.pi / 2),
            # the palm's face 1 cm into the block
            _top_down(0.15, 0.15, top - 0.01 + PANDA_HAND.palm_front, yaw=0.0),
            # beside the block: the fingers close on nothing
            _top_down(0.05, 0.05, 0.03, yaw=0.0),
        ]
    )
    np.testing.assert_array_equal(check(grasps), [False, True, True, True])
    assert check(np.zeros((0, 4, 4))).shape == (0,)
    with pytest.raises(ValueError, match=r"tcp2world must be \(N, 4, 4\)"):
        check(np.eye(4))
    # An empty hull holds nothing to grasp.
    assert HullCheck(np.zeros((40, 40, 40), bool), FRAME)(grasps).all()


def test_a_grasp_into_the_table_is_rejected():
    occ = _block((18, 18, 0), (22, 22, 8))  # 3 cm square, 6 cm tall
    check = HullCheck(occ, FRAME)
    below = _top_down(0.15, 0.15, -0.005)  # fingertips under the table top
    assert check(below[None])[0]


def _volumes(quality: np.ndarray) -> GraspVolumes:
    quats = np.zeros((*quality.shape, 4), np.float32)
    quats[..., 3] = 1.0
    return GraspVolumes(
        FRAME, quality.astype(np.float32), quats, np.full(quality.shape, 0.05, np.float32)
    )


def test_a_rejected_grasp_suppresses_no_neighbour():
    quality = np.zeros((40, 40, 40), np.float32)
    quality[10, 10, 10] = 1.0
    quality[11, 10, 10] = 0.9  # suppressed by its neighbour
    quality[30, 30, 30] = 0.95
    vols = _volumes(quality)
    plain = select_candidates(vols, epsilon=0.5, sigma=0.0, nms_window=4)
    assert [c.index for c in plain] == [(10, 10, 10), (30, 30, 30)]
    bad = FRAME.centers(np.array([[10, 10, 10]]))[0]

    calls = []

    def reject(poses: np.ndarray) -> np.ndarray:
        calls.append(len(poses))
        return np.linalg.norm(poses[:, :3, 3] - bad, axis=1) < 1e-9

    kept = select_candidates(vols, epsilon=0.5, sigma=0.0, nms_window=4, reject=reject)
    assert [c.index for c in kept] == [(30, 30, 30), (11, 10, 10)]
    assert calls == [3]  # every voxel above ε, once
    everything = select_candidates(
        vols, epsilon=0.5, sigma=0.0, reject=lambda p: np.ones(len(p), bool)
    )
    assert everything == []
    with pytest.raises(ValueError, match="reject returned shape"):
        select_candidates(vols, epsilon=0.5, sigma=0.0, reject=lambda p: np.zeros(1, bool))


def test_the_hand_keeps_half_a_voxel_from_the_hull():
    # Carving keeps a voxel when its centre is inside the silhouettes: an object may
    # reach half a voxel (3.75 mm) beyond the boxes.
    v = FRAME.voxel_size
    target = _block((18, 12, 0), (22, 28, 8))
    grasp = _top_down(0.15, 0.15, 8 * v - 0.02 + PANDA_HAND.finger_tip)[None]
    # the outer face of the fingers' base, which closes along world x
    outer = 0.15 + PANDA_HAND.max_opening / 2 + PANDA_HAND.base_thickness
    for first, gap, rejected in ((29, 29 * v - outer, True), (30, 30 * v - outer, False)):
        # as high as the fingers' base part, 1 cm below the palm
        neighbour = _block((first, 8, 0), (first + 4, 32, 10))
        assert 0.0 < gap < v / 2 if rejected else gap > v / 2
        assert HullCheck(target | neighbour, FRAME)(grasp)[0] == rejected


@pytest.mark.parametrize("seed", range(6))
def test_select_candidates_finds_the_peaks_of_the_whole_grid(seed):
    # select_candidates runs NMS on the cube around the voxels above ε only.
    from heapgrasp import nms3d

    rng = np.random.default_rng(seed)
    quality = np.zeros((40, 40, 40), np.float32)
    lo = rng.integers(0, 36, 3)
    hi = np.minimum(lo + rng.integers(1, 15, 3), 40)
    quality[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] = rng.random(tuple(hi - lo))
    quality[rng.random(quality.shape) < 0.02] = 0.3  # below ε, everywhere
    quality[quality > 0.9] = 0.95  # ties
    window = int(rng.integers(1, 6))
    got = [
        c.index
        for c in select_candidates(_volumes(quality), epsilon=0.6, sigma=0.0, nms_window=window)
    ]
    want = [tuple(int(x) for x in i) for i in nms3d(quality, 0.6, window)]
    assert got == want
