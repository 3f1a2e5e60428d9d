"""Every bad input raises a HeapgraspError (a ValueError) naming the bad argument."""

from __future__ import annotations

import re

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from conftest import GRID_ORIGIN, GRID_SIZE

H, W = 30, 40


def raises(exc, name):
    return pytest.raises(exc, match=re.escape(name))


def test_hierarchy():
    for e in [
        hg.ShapeError,
        hg.InvalidValueError,
        hg.NonFiniteError,
        hg.NotRigidError,
        hg.MeshError,
        hg.UnknownMeshError,
    ]:
        assert issubclass(e, hg.HeapgraspError)
    assert issubclass(hg.HeapgraspError, ValueError)


def good_pose():
    return ref.look_at((0.5, 0.2, 0.4), (0.0, 0.0, 0.1))


def bad_poses():
    p = good_pose()
    scaled = p.copy()
    scaled[:3, :3] *= 1.01
    sheared = p.copy()
    sheared[0, 1] += 0.05
    reflected = p.copy()
    reflected[:3, 0] *= -1
    last = p.copy()
    last[3, 0] = 0.1
    last2 = p.copy()
    last2[3, 3] = 2.0
    nan = p.copy()
    nan[1, 3] = np.nan
    inf = p.copy()
    inf[0, 0] = np.inf
    return [
        ("scaled", scaled, hg.NotRigidError),
        ("sheared", sheared, hg.NotRigidError),
        ("reflected", reflected, hg.NotRigidError),
        ("last_row", last, hg.NotRigidError),
        ("last_row_w", last2, hg.NotRigidError),
        ("nan", nan, hg.NonFiniteError),
        ("inf", inf, hg.NonFiniteError),
        ("float32", p.astype(np.float32), hg.ShapeError),
        ("shape", p[:3], hg.ShapeError),
        ("ndim", p.ravel(), hg.ShapeError),
        ("fortran", np.asfortranarray(p), hg.ShapeError),
        ("list", p.tolist(), hg.ShapeError),
    ]


def mask():
    return np.zeros((H, W), dtype=bool)


def bad_masks():
    m = np.zeros((H, 2 * W), dtype=bool)
    return [
        ("float", np.zeros((H, W), np.float32)),
        ("int64", np.zeros((H, W), np.int64)),
        ("transposed_shape", np.zeros((W, H), bool)),
        ("small", np.zeros((H - 1, W), bool)),
        ("ndim3", np.zeros((1, H, W), bool)),
        ("ndim1", np.zeros(H * W, bool)),
        ("strided", m[:, ::2]),
        ("fortran", np.asfortranarray(np.zeros((H, W), np.uint8))),
        ("list", [[0] * W] * H),
    ]


def assert_unchanged(grid, before):
    for a, b in zip(grid.counts(), before, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.fixture
def used_grid(grid, camera, poses, rng):
    grid.integrate_many(rng.random((len(poses), H, W)) < 0.5, camera, poses)
    return grid, [a.copy() for a in grid.counts()]


@pytest.mark.parametrize("label,pose,exc", bad_poses(), ids=[b[0] for b in bad_poses()])
def test_integrate_bad_pose(used_grid, camera, label, pose, exc):
    grid, before = used_grid
    with raises(exc, "cam2world"):
        grid.integrate(mask(), camera, pose)
    assert_unchanged(grid, before)


@pytest.mark.parametrize("label,m", bad_masks(), ids=[b[0] for b in bad_masks()])
def test_integrate_bad_mask(used_grid, camera, label, m):
    grid, before = used_grid
    with raises(hg.ShapeError, "mask"):
        grid.integrate(m, camera, good_pose())
    assert_unchanged(grid, before)


@pytest.mark.parametrize("label,pose,exc", bad_poses()[:8], ids=[b[0] for b in bad_poses()[:8]])
def test_integrate_many_one_bad_pose_changes_nothing(used_grid, camera, label, pose, exc):
    grid, before = used_grid
    poses = np.stack([good_pose(), pose.astype(np.float64), good_pose()])
    if exc is hg.ShapeError:  # float32 -> whole stack float32
        poses = poses.astype(np.float32)
    with raises(exc, "cam2worlds"):
        grid.integrate_many(np.ones((3, H, W), bool), camera, poses)
    assert_unchanged(grid, before)


def test_integrate_many_shape_errors(used_grid, camera):
    grid, before = used_grid
    poses = np.stack([good_pose()] * 3)
    ones = np.ones((3, H, W), bool)
    with raises(hg.ShapeError, "cam2worlds"):
        grid.integrate_many(ones, camera, poses[:2])  # count mismatch
    with raises(hg.ShapeError, "cam2worlds"):
        grid.integrate_many(ones, camera, poses[0])  # 2-D
    with raises(hg.ShapeError, "cam2worlds"):
        grid.integrate_many(ones, camera, np.asfortranarray(poses))
    with raises(hg.ShapeError, "masks"):
        grid.integrate_many(ones[0], camera, poses)  # 2-D masks
    with raises(hg.ShapeError, "masks"):
        grid.integrate_many(np.ones((3, H, W + 1), bool), camera, poses)
    with raises(hg.ShapeError, "masks"):
        grid.integrate_many(ones.astype(np.float64), camera, poses)
    with raises(hg.ShapeError, "masks"):
        grid.integrate_many(np.ones((3, H, 2 * W), bool)[:, :, ::2], camera, poses)
    assert_unchanged(grid, before)


@pytest.mark.parametrize("dtype", [bool, np.uint8])
def test_strided_masks_are_reported_as_not_contiguous(used_grid, camera, box_scene, dtype):
    """A strided mask of the right dtype is refused for its layout, not its dtype."""
    grid, before = used_grid
    match = r"mask: array must be C-contiguous"
    with pytest.raises(hg.ShapeError, match=match):
        grid.integrate(np.zeros((H, 2 * W), dtype)[:, ::2], camera, good_pose())
    with pytest.raises(hg.ShapeError, match="masks: array must be C-contiguous"):
        grid.integrate_many(
            np.ones((3, H, 2 * W), dtype)[:, :, ::2], camera, np.stack([good_pose()] * 3)
        )
    with pytest.raises(hg.ShapeError, match="mask: array must be C-contiguous"):
        grid.integrate(np.asfortranarray(np.zeros((H, W), dtype)), camera, good_pose())
    r = grid.resolution
    region = np.ones((r, r, 2 * r), dtype)[:, :, ::2]
    scene, _ = box_scene
    with pytest.raises(hg.ShapeError, match="region: array must be C-contiguous"):
        hg.score_views(grid, scene, camera, [good_pose()[None]], region=region)
    # Wrong ndim is reported as such for bool too, not as a dtype mismatch.
    with pytest.raises(hg.ShapeError, match=r"mask: expected a 2-D array"):
        grid.integrate(np.zeros((1, H, W), dtype), camera, good_pose())
    assert_unchanged(grid, before)


@pytest.mark.parametrize("dtype", [np.int64, np.int32])
def test_strided_faces_are_reported_as_not_contiguous(dtype):
    v, f = ref.box_mesh((0.1, 0.1, 0.1))
    strided = np.repeat(f.astype(dtype), 2, axis=0)[::2]
    np.testing.assert_array_equal(strided, f)
    with pytest.raises(hg.ShapeError, match="faces: array must be C-contiguous"):
        hg.MeshScene().add_mesh(v, strided, np.eye(4))


@pytest.mark.parametrize("threads", [0, -1, 257, 2**70, 1.5, "2"])
def test_integrate_many_bad_threads(used_grid, camera, threads):
    grid, before = used_grid
    with raises(hg.InvalidValueError, "threads"):
        grid.integrate_many(np.ones((1, H, W), bool), camera, good_pose()[None], threads=threads)
    assert_unchanged(grid, before)


@pytest.mark.parametrize("size", [0.0, -0.3, np.nan, np.inf])
def test_bad_grid_size(size):
    with raises(hg.InvalidValueError, "size"):
        hg.OccupancyGrid(GRID_ORIGIN, size, 10)
    with raises(hg.InvalidValueError, "size"):
        hg.TSDFVolume(GRID_ORIGIN, size, 10)


@pytest.mark.parametrize("res", [0, -1, 513, 100000])
def test_bad_resolution(res):
    with raises(hg.InvalidValueError, "resolution"):
        hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, res)
    with raises(hg.InvalidValueError, "resolution"):
        hg.TSDFVolume(GRID_ORIGIN, GRID_SIZE, res)


def test_bad_origin():
    with raises(hg.NonFiniteError, "origin"):
        hg.OccupancyGrid((0.0, np.nan, 0.0), 0.3, 4)
    with raises(hg.ShapeError, "origin"):
        hg.OccupancyGrid((0.0, 0.0), 0.3, 4)


@pytest.mark.parametrize("trunc", [0.0, -0.01, np.nan])
def test_bad_truncation(trunc):
    with raises(hg.InvalidValueError, "truncation"):
        hg.TSDFVolume(GRID_ORIGIN, GRID_SIZE, 8, trunc)


def test_tsdf_bad_inputs(camera):
    vol = hg.TSDFVolume(GRID_ORIGIN, GRID_SIZE, 8)
    d = np.ones((H, W), np.float32)
    vol.integrate(d, camera, good_pose())
    before = (vol.values().copy(), vol.weights().copy())
    for bad in [d.astype(np.float64), d[:-1], d[None], np.ones((H, 2 * W), np.float32)[:, ::2]]:
        with raises(hg.ShapeError, "depth_m"):
            vol.integrate(bad, camera, good_pose())
    for _, pose, exc in bad_poses():
        with raises(exc, "cam2world"):
            vol.integrate(d, camera, pose)
    np.testing.assert_array_equal(vol.values(), before[0])
    np.testing.assert_array_equal(vol.weights(), before[1])


@pytest.mark.parametrize("lam", [-0.01, 1.01, np.nan, np.inf])
def test_bad_lambda(grid, box_scene, camera, lam):
    with raises(hg.InvalidValueError, "lam"):
        grid.high_confidence(lam)
    with raises(hg.InvalidValueError, "lam"):
        grid.count_high_confidence(lam)
    scene, _ = box_scene
    with raises(hg.InvalidValueError, "lam"):
        hg.score_views(grid, scene, camera, [good_pose()[None]], lam=lam)


def test_score_views_bad_trajectory(grid, box_scene, camera):
    scene, _ = box_scene
    t = good_pose()[None]
    scaled = t.copy()
    scaled[0, :3, :3] *= 2
    for bad, exc in [
        (good_pose(), hg.ShapeError),
        (t.astype(np.float32), hg.ShapeError),
        (scaled, hg.NotRigidError),
        (np.asfortranarray(np.stack([t[0]] * 2)), hg.ShapeError),
    ]:
        with raises(exc, "trajectories[1]"):
            hg.score_views(grid, scene, camera, [t, bad])


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"width": 0}, "width"),
        ({"width": -5}, "width"),
        ({"height": 0}, "height"),
        ({"width": 20000}, "width"),
        ({"fx": 0.0}, "fx"),
        ({"fx": -1.0}, "fx"),
        ({"fy": np.nan}, "fy"),
        ({"fy": np.inf}, "fy"),
        ({"cx": np.nan}, "cx"),
        ({"cy": np.inf}, "cy"),
    ],
)
def test_bad_camera(kwargs, name):
    args = {"width": 40, "height": 30, "fx": 50.0, "fy": 50.0, "cx": 20.0, "cy": 15.0}
    args.update(kwargs)
    with raises(hg.InvalidValueError, name):
        hg.PinholeCamera(**args)


def test_camera_attributes():
    c = hg.PinholeCamera(40, 30, 50.0, 51.0, 20.5, 15.5)
    assert (c.width, c.height, c.fx, c.fy, c.cx, c.cy) == (40, 30, 50.0, 51.0, 20.5, 15.5)
    assert c == hg.PinholeCamera(40, 30, 50.0, 51.0, 20.5, 15.5)


def test_filter_bad_inputs():
    v = np.zeros((4, 4, 4), np.float32)
    for sigma in [-0.5, np.nan, np.inf]:
        with raises(hg.InvalidValueError, "sigma"):
            hg.gaussian_filter3d(v, sigma)
    for bad in [
        v.astype(np.float64),
        np.zeros((4, 4, 5), np.float32),
        v[0],
        np.zeros((4, 4, 8), np.float32)[:, :, ::2],
        np.zeros((0, 0, 0), np.float32),
    ]:
        with pytest.raises(hg.HeapgraspError, match=r"volume|resolution"):
            hg.gaussian_filter3d(bad, 1.0)
        with pytest.raises(hg.HeapgraspError, match=r"volume|resolution"):
            hg.maximum_filter3d(bad, 3)
        with pytest.raises(hg.HeapgraspError, match=r"volume|resolution"):
            hg.nms3d(bad, 0.5)
    with raises(hg.InvalidValueError, "window"):
        hg.maximum_filter3d(v, 0)
    with raises(hg.InvalidValueError, "window"):
        hg.nms3d(v, 0.5, 0)
    with raises(hg.InvalidValueError, "threshold"):
        hg.nms3d(v, np.nan)


def test_mesh_bad_inputs():
    scene = hg.MeshScene()
    v, f = ref.box_mesh((0.1, 0.1, 0.1))
    for bad in [f + 8, np.array([[0, 1, -1]]), np.array([[0, 1, 2**40]])]:
        with raises(hg.MeshError, "faces"):
            scene.add_mesh(v, bad, np.eye(4))
    with raises(hg.MeshError, "faces"):
        scene.add_mesh(v, np.zeros((0, 3), np.int64), np.eye(4))
    with raises(hg.ShapeError, "faces"):
        scene.add_mesh(v, f.astype(np.float64), np.eye(4))
    with raises(hg.ShapeError, "faces"):
        scene.add_mesh(v, f.reshape(-1, 4), np.eye(4))
    with raises(hg.ShapeError, "vertices"):
        scene.add_mesh(v[:, :2].copy(), f, np.eye(4))
    with raises(hg.ShapeError, "vertices"):
        scene.add_mesh(v.astype(np.float32), f, np.eye(4))
    vn = v.copy()
    vn[2, 1] = np.nan
    with raises(hg.NonFiniteError, "vertices"):
        scene.add_mesh(vn, f, np.eye(4))
    for _, pose, exc in bad_poses():
        with raises(exc, "obj2world"):
            scene.add_mesh(v, f, pose)
    assert scene.ids() == [] and len(scene) == 0
    i = scene.add_mesh(v, f.astype(np.uint32), np.eye(4))
    with raises(hg.UnknownMeshError, "id"):
        scene.set_pose(i + 1, np.eye(4))
    with raises(hg.UnknownMeshError, "id"):
        scene.pose(i + 5)
    with raises(hg.UnknownMeshError, "id"):
        scene.remove(0)
    with raises(hg.UnknownMeshError, "id"):
        scene.is_closed(77)
    for _, pose, exc in bad_poses():
        with raises(exc, "obj2world"):
            scene.set_pose(i, pose)
    np.testing.assert_array_equal(scene.pose(i), np.eye(4))
    with raises(hg.InvalidValueError, "direction"):
        scene.cast_ray((0, 0, 0), (0, 0, 0))
    with raises(hg.NonFiniteError, "direction"):
        scene.cast_ray((0, 0, 0), (0, np.nan, 1))
    with raises(hg.NonFiniteError, "origin"):
        scene.cast_ray((np.inf, 0, 0), (0, 0, 1))
    with raises(hg.ShapeError, "origin"):
        scene.cast_ray((0, 0), (0, 0, 1))
    cam = hg.PinholeCamera(8, 6, 10.0, 10.0, 4.0, 3.0)
    for _, pose, exc in bad_poses():
        for fn in (scene.render_mask, scene.render_depth, scene.render_labels):
            with raises(exc, "cam2world"):
                fn(cam, pose)


def test_from_counts_bad_inputs():
    s = np.zeros((3, 3, 3), np.uint32)
    with raises(hg.ShapeError, "segmented"):
        hg.OccupancyGrid.from_counts((0, 0, 0), 1.0, s.astype(np.int64), s)
    with raises(hg.ShapeError, "visible"):
        hg.OccupancyGrid.from_counts((0, 0, 0), 1.0, s, s.astype(np.float32))
    with pytest.raises(hg.ShapeError, match="segmented, visible"):
        hg.OccupancyGrid.from_counts((0, 0, 0), 1.0, s, np.zeros((3, 3, 4), np.uint32))
    with pytest.raises(hg.HeapgraspError, match=r"segmented|visible"):
        hg.OccupancyGrid.from_counts((0, 0, 0), 1.0, s + 2, s + 1)  # seg > vis
    with raises(hg.InvalidValueError, "size"):
        hg.OccupancyGrid.from_counts((0, 0, 0), -1.0, s, s)


# Integer arguments outside their range (negative, beyond any C integer) must raise a
# HeapgraspError naming the argument, not pyo3's OverflowError.
@pytest.mark.parametrize(
    "call",
    [
        lambda: hg.maximum_filter3d(np.zeros((3, 3, 3), np.float32), -1),
        lambda: hg.nms3d(np.zeros((3, 3, 3), np.float32), 0.5, -2),
        lambda: hg.OccupancyGrid((0, 0, 0), 0.3, 2**70),
        lambda: hg.PinholeCamera(2**70, 3, 1.0, 1.0, 0.0, 0.0),
        lambda: hg.MeshScene().pose(-1),
        lambda: hg.score_views(
            hg.OccupancyGrid((0, 0, 0)), hg.MeshScene(), hg.PinholeCamera(4, 4, 1, 1, 1, 1), 5
        ),
    ],
    ids=[
        "max_window_-1",
        "nms_window_-2",
        "resolution_2**70",
        "width_2**70",
        "mesh_id_-1",
        "trajectories_int",
    ],
)
def test_out_of_range_integers_raise_heapgrasp_error(call):
    with pytest.raises(hg.HeapgraspError):
        call()
