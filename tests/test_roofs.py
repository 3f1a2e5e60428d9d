"""Roof trimming of the silhouette hull (heapgrasp.roofs)."""

from __future__ import annotations

import numpy as np
import pytest
from heapgrasp import OccupancyGrid
from heapgrasp.grasping.volumes import GridFrame
from heapgrasp.perception import SilhouettePerception
from heapgrasp.roofs import column_heights, trim_roofs

V = 0.0075  # voxel size of Table I's grid (0.30 m / 40)


def box_with_tent(r: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A 6 × 6 × 6 box with a tent roof along x, as carved from two opposite sides; and
    the box alone."""
    box = np.zeros((r, r, r), dtype=np.float32)
    box[5:11, 5:11, :6] = 1.0
    hull = box.copy()
    for i in range(5, 11):
        ridge = min(i - 5, 10 - i)  # 0 at the eaves, 2 at the ridge
        hull[i, 5:11, 6 : 6 + 2 * ridge] = 1.0
    return hull, box


def test_column_heights() -> None:
    occ = np.zeros((4, 4, 5), dtype=bool)
    occ[1, 2, :3] = True
    occ[3, 0, 4] = True  # a floating voxel counts up to its layer
    h = column_heights(occ)
    assert h.shape == (4, 4)
    assert h[1, 2] == 3 and h[3, 0] == 5 and h.sum() == 8
    with pytest.raises(ValueError, match="3-D"):
        column_heights(np.zeros((4, 4), dtype=bool))


def test_a_tent_roof_is_trimmed_to_the_box_below() -> None:
    hull, box = box_with_tent()
    assert hull.sum() > box.sum()
    np.testing.assert_array_equal(trim_roofs(hull, V, 0.0225), box)


def test_flat_tops_and_narrow_objects_keep_their_height() -> None:
    hull, box = box_with_tent()
    tall = np.zeros_like(box)
    tall[15:17, 15:17, :14] = 1.0  # 1.5 cm wide, 10.5 cm tall, narrower than the disc
    wide = np.zeros_like(box)
    wide[2:22, 14:22, :4] = 1.0
    for grid in (box, tall, wide, np.maximum(box, tall)):
        np.testing.assert_array_equal(trim_roofs(grid, V, 0.0225), grid)
    # Everything at once: only the roof goes.
    scene = np.maximum(hull, tall)
    np.testing.assert_array_equal(trim_roofs(scene, V, 0.0225), np.maximum(box, tall))


def test_what_it_can_cut_a_narrow_tower_on_a_wider_base() -> None:
    # A neck narrower than the disc on a wider body is cut to the body's height: the
    # documented cost of the prior (a grasp beside it may touch it).
    bottle = np.zeros((24, 24, 24), dtype=np.float32)
    bottle[6:14, 6:14, :8] = 1.0
    bottle[9:11, 9:11, 8:14] = 1.0
    trimmed = trim_roofs(bottle, V, 0.0225)
    assert column_heights(trimmed > 0).max() == 8


def test_values_are_kept_and_small_discs_change_nothing() -> None:
    hull, _ = box_with_tent()
    graded = hull * np.float32(0.95)
    out = trim_roofs(graded, V, 0.0225)
    assert out.dtype == np.float32
    assert set(np.unique(out)) <= {0.0, np.float32(0.95)}
    np.testing.assert_array_equal(trim_roofs(hull, V, 0.003), hull)
    np.testing.assert_array_equal(trim_roofs(hull, V, 0.0), hull)
    assert trim_roofs(hull, V, 0.0) is not hull


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.zeros((4, 4, 5)), V, 0.02), "cubic"),
        ((np.full((4, 4, 4), np.nan), V, 0.02), "NaN"),
        ((np.zeros((4, 4, 4)), 0.0, 0.02), "voxel_size"),
        ((np.zeros((4, 4, 4)), V, -0.01), "radius"),
        ((np.zeros((4, 4, 4)), V, float("inf")), "radius"),
    ],
)
def test_bad_input_names_the_value(args: tuple[object, ...], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        trim_roofs(*args)  # type: ignore[arg-type]


def test_perception_trims_the_grasp_input_only_when_asked() -> None:
    frame = GridFrame((0.0, 0.0, 0.0), 0.18, 24)
    with pytest.raises(ValueError, match="roof_radius"):
        SilhouettePerception(frame, roof_radius=-1.0)
    hull, box = box_with_tent()
    # Counts as if every frame had seen every voxel and segmented the hull.
    visible = np.full(hull.shape, 10, dtype=np.uint32)
    segmented = (hull * 10).astype(np.uint32)
    grid = OccupancyGrid.from_counts(frame.origin, frame.size, segmented, visible)
    plain = SilhouettePerception(frame)
    trimmed = SilhouettePerception(frame, roof_radius=0.0225)
    plain.grid = grid
    trimmed.grid = grid.copy()
    np.testing.assert_array_equal(plain.grasp_input(), hull)
    np.testing.assert_array_equal(trimmed.grasp_input(), box)
    # the grid itself (what the view scorer counts) keeps the roof
    assert trimmed.grid.count_high_confidence(0.9) == int(hull.sum())
