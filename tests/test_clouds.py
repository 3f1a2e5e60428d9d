"""Seed 001's point-cloud perception (perception.clouds) against plain references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import look_at
from heapgrasp.perception.clouds import (
    UnexploredRegion,
    backproject,
    fit_table,
    voxel_downsample,
)

CAM = CameraSpec(width=64, height=48, fx=55.4, fy=55.4, cx=31.5, cy=23.5)


def _plane_depth(cam2world: np.ndarray, z_plane: float) -> np.ndarray:
    """Depth (along the optical axis) of the horizontal plane ``z = z_plane``."""
    v, u = np.mgrid[0 : CAM.height, 0 : CAM.width]
    rays = np.stack([(u - CAM.cx) / CAM.fx, (v - CAM.cy) / CAM.fy, np.ones(u.shape)], -1)
    world = rays @ cam2world[:3, :3].T  # the ray's direction per unit depth
    t = (z_plane - cam2world[2, 3]) / world[..., 2]
    return np.where(t > 0, t, np.nan)


def test_backprojected_points_lie_where_the_depth_says():
    cam2world = look_at([0.1, -0.3, 0.5], [0.0, 0.0, 0.0])
    depth = _plane_depth(cam2world, 0.02)
    pts = backproject(depth, CAM, cam2world, max_range=10.0)
    assert len(pts) == np.isfinite(depth).sum()
    np.testing.assert_allclose(pts[:, 2], 0.02, atol=1e-12)
    # The principal point's pixel lies on the optical axis.
    on_axis = CameraSpec(width=64, height=48, fx=55.4, fy=55.4, cx=31.0, cy=23.0)
    centre = np.full((48, 64), np.nan)
    centre[23, 31] = 0.5
    (one,) = backproject(centre, on_axis, cam2world)
    np.testing.assert_allclose(one, cam2world[:3, 3] + 0.5 * cam2world[:3, 2], atol=1e-12)
    # The sensor's range.
    near = np.full((CAM.height, CAM.width), 0.05)
    assert len(backproject(near, CAM, cam2world)) == 0
    with pytest.raises(ValueError, match="depth must have the camera's shape"):
        backproject(np.zeros((3, 3)), CAM, cam2world)
    with pytest.raises(ValueError, match="cam2world must be a finite"):
        backproject(depth, CAM, np.eye(3))


def test_voxel_downsample_keeps_each_cells_centroid_in_any_order():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.05, 0.05, (2000, 3))
    got = voxel_downsample(pts, 0.0075)
    cells: dict[tuple[int, ...], list[np.ndarray]] = {}
    for p in pts:
        cells.setdefault(tuple(np.floor(p / 0.0075).astype(int)), []).append(p)
    want = np.array([np.mean(cells[k], axis=0) for k in sorted(cells)])
    np.testing.assert_allclose(got, want, atol=1e-15)
    shuffled = voxel_downsample(pts[rng.permutation(len(pts))], 0.0075)
    np.testing.assert_allclose(shuffled, got, atol=1e-15)  # fusion is order-free
    assert voxel_downsample(np.zeros((0, 3)), 0.01).shape == (0, 3)
    with pytest.raises(ValueError, match="voxel: expected a finite value > 0"):
        voxel_downsample(pts, 0.0)
    with pytest.raises(ValueError, match="points: contains a non-finite value"):
        voxel_downsample([[np.nan, 0, 0]], 0.01)


def test_the_table_is_the_level_plane_under_the_object():
    rng = np.random.default_rng(1)
    table = np.column_stack(
        [rng.uniform(-0.3, 0.3, 3000), rng.uniform(-0.3, 0.3, 3000), np.full(3000, 0.02)]
    )
    table[:, 2] += rng.normal(0.0, 0.001, 3000)
    box = rng.uniform([-0.03, -0.05, 0.03], [0.03, 0.05, 0.15], (1500, 3))
    wall = np.column_stack(  # a vertical plane with more points than the table: not a table
        [np.full(4000, 0.4), rng.uniform(-0.3, 0.3, 4000), rng.uniform(0.05, 0.5, 4000)]
    )
    plane = fit_table(np.vstack([table, box, wall]))
    assert plane.normal[2] > math.cos(math.radians(1.0))
    assert abs(plane.offset - 0.02) < 0.001
    assert plane.inliers[:3000].mean() > 0.99 and not plane.inliers[3000:].any()
    np.testing.assert_allclose(plane.height([[0, 0, 0.12]]), [0.10], atol=0.002)
    with pytest.raises(ValueError, match="no plane within 10° of horizontal"):
        fit_table(wall)
    with pytest.raises(ValueError, match="at least 3 points"):
        fit_table(np.zeros((2, 3)))


def test_the_unexplored_lattice_covers_the_grown_box():
    obj = np.array([[-0.02, -0.05, 0.0], [0.02, 0.05, 0.12]])
    region = UnexploredRegion.around(obj, 0.0, spacing=0.01)
    lo, hi = region.points.min(axis=0), region.points.max(axis=0)
    np.testing.assert_allclose(lo, [-0.32, -0.35, -0.01], atol=1e-12)
    np.testing.assert_allclose(hi, [0.31, 0.34, 0.36], atol=1e-9)  # up to 0.32, 0.35, 0.37
    big = np.array([[-0.2, 0.0, 0.0], [0.2, 0.0, 0.3]])  # extent 0.4 > 0.3: grown by it
    assert UnexploredRegion.around(big, 0.0, spacing=0.05).points[:, 0].min() == pytest.approx(-0.6)
    with pytest.raises(ValueError, match="needs object points"):
        UnexploredRegion.around(np.zeros((0, 3)), 0.0)


def _seen_reference(points, depth, cam2world, table_z):
    """One point at a time, as the original's loop (but keeping off-image points)."""
    world2cam = np.linalg.inv(cam2world)
    out = np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        if p[2] < table_z:
            continue
        x, y, z = world2cam[:3, :3] @ p + world2cam[:3, 3]
        if z <= 0:
            continue
        u = math.floor(CAM.fx * x / z + CAM.cx + 0.5)  # the core's pixel convention
        v = math.floor(CAM.fy * y / z + CAM.cy + 0.5)
        if not (0 <= u < CAM.width and 0 <= v < CAM.height):
            continue
        m = depth[v, u]
        valid = np.isfinite(m) and 0.10 <= m <= 3.0
        out[i] = (not valid) or m > 0.99 * z
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_view_removes_what_it_shows_empty_as_the_reference_does(seed):
    rng = np.random.default_rng(seed)
    cam2world = look_at(rng.uniform([-0.3, -0.3, 0.3], [0.3, 0.3, 0.5]), [0.0, 0.0, 0.05])
    depth = _plane_depth(cam2world, 0.0)
    # a box on the table, as a depth step, and a few pixels with no return
    depth[15:30, 20:40] *= 0.8
    depth[rng.random(depth.shape) < 0.05] = np.nan
    box = np.array([[-0.05, -0.05, 0.0], [0.05, 0.05, 0.1]])
    region = UnexploredRegion.around(box, 0.0, spacing=0.02)  # a coarse lattice: fast
    want = _seen_reference(region.points, depth, cam2world, 0.0)
    got = region.seen(depth, CAM, cam2world)
    np.testing.assert_array_equal(got, want)
    assert 0 < got.sum() < len(got)
    before = len(region)
    assert region.update(depth, CAM, cam2world) == want.sum()
    assert len(region) == before - want.sum()


def test_what_the_camera_never_looked_at_stays_unexplored():
    cam2world = look_at([0.0, -0.4, 0.2], [0.0, 0.0, 0.05])
    region = UnexploredRegion(
        np.array([[0.0, 0.0, 0.05], [5.0, 0.0, 0.05], [0.0, -0.6, 0.05], [0.0, 0.0, -0.005]]),
        0.0,
    )
    empty = np.full((CAM.height, CAM.width), np.nan)  # no return anywhere
    # In view: seen; off the image, behind the camera, below the table: kept.
    np.testing.assert_array_equal(region.seen(empty, CAM, cam2world), [True, False, False, False])
    near_wall = np.full((CAM.height, CAM.width), 0.2)  # a surface in front of the point
    assert not region.seen(near_wall, CAM, cam2world)[0]
