"""Every bad input raises a HeapgraspError (a ValueError) naming the bad argument."""

from __future__ import annotations

import re

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from conftest import GRID_ORIGIN, GRID_SIZE
from heapgrasp import _core

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


# ------------------------------------------------------------------ found by fuzzing
# tests/test_fuzz_bindings.py (issue 36) found each of these; every one raised a
# TypeError / PanicException, aborted the process, hung, or returned a wrong result.
NO_VIEWS = ([], np.zeros((0, 4, 4)), [])  # keep_silhouettes' cameras, poses, masks


def _panda_params(voxel_size: float = 0.0075) -> dict:
    from test_fuzz_bindings import panda_params

    return panda_params(voxel_size, 0.0)


def _antipodal_args(r: int = 12):
    occ = np.zeros((r, r, r), bool)
    occ[3:9, 4:8, 0:6] = True
    return [
        occ,
        np.zeros((3, r, r, r)),
        occ.astype(np.int32),
        np.array([[0.0, 0.0, 0.0], [0.045, 0.045, 0.02]]),
        np.array([[6, 6, 3]], np.int64),
        np.array([[[-1.0, 0, 0], [0, 1, 0], [0, 0, -1]]]),
        np.zeros(1),
    ]


@pytest.mark.parametrize(
    "call,name",
    [
        (lambda: hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, True), "resolution"),
        (lambda: hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, np.True_), "resolution"),
        (lambda: hg.TSDFVolume(GRID_ORIGIN, GRID_SIZE, True), "resolution"),
        (lambda: hg.OccupancyGrid(GRID_ORIGIN, True, 8), "size"),
        (
            lambda: hg.OccupancyGrid.from_counts(
                (0, 0, 0), True, *[np.zeros((2,) * 3, np.uint32)] * 2
            ),
            "size",
        ),
        (lambda: hg.TSDFVolume(GRID_ORIGIN, GRID_SIZE, 8, True), "truncation"),
        (lambda: hg.PinholeCamera(True, 30, 45.0, 47.0, 19.3, 14.6), "width"),
        (lambda: hg.PinholeCamera(40, np.True_, 45.0, 47.0, 19.3, 14.6), "height"),
        (lambda: hg.PinholeCamera(40, 30, True, 47.0, 19.3, 14.6), "fx"),
        (lambda: hg.PinholeCamera(40, 30, 45.0, 47.0, 19.3, np.False_), "cy"),
        (lambda: hg.OccupancyGrid(GRID_ORIGIN).high_confidence(True), "lam"),
        (lambda: hg.OccupancyGrid(GRID_ORIGIN).count_high_confidence(False), "lam"),
        (lambda: hg.gaussian_filter3d(np.zeros((3, 3, 3), np.float32), True), "sigma"),
        (lambda: hg.maximum_filter3d(np.zeros((3, 3, 3), np.float32), True), "window"),
        (lambda: hg.nms3d(np.zeros((3, 3, 3), np.float32), 0.5, True), "window"),
        (lambda: hg.nms3d(np.zeros((3, 3, 3), np.float32), True), "threshold"),
        (
            lambda: _core.antipodal_grasps(
                *_antipodal_args(), {**_panda_params(), "min_patch": True}
            ),
            'params["min_patch"]',
        ),
        (
            lambda: _core.antipodal_grasps(
                *_antipodal_args(), {**_panda_params(), "clearance": True}
            ),
            'params["clearance"]',
        ),
    ],
)
def test_bools_are_not_numbers(call, name):
    """Issue 36: `OccupancyGrid(resolution=True)` made a 1-voxel grid. No bool (Python's or
    NumPy's) is taken for a size, a count or any other number."""
    with raises(hg.InvalidValueError, name):
        call()


def test_bools_are_not_threads_coordinates_or_mesh_ids(used_grid, camera):
    grid, before = used_grid
    with raises(hg.InvalidValueError, "threads"):
        grid.integrate_many(np.ones((1, H, W), bool), camera, good_pose()[None], threads=True)
    assert_unchanged(grid, before)
    for origin in [(True, 0.0, 0.0), np.array([True, False, True])]:
        with raises(hg.ShapeError, "origin"):
            hg.OccupancyGrid(origin, 0.3, 4)
    scene = hg.MeshScene()
    v, f = ref.box_mesh((0.1, 0.1, 0.1))
    assert scene.add_mesh(v, f, np.eye(4)) == 1
    for call in (scene.pose, scene.remove, scene.is_closed):
        with raises(hg.UnknownMeshError, "True"):
            call(True)
    assert scene.ids() == [1]


@pytest.mark.parametrize("bad", [None, "0.5", [0.5], np.array([0.5]), 1j, object()])
def test_non_numbers_raise_invalid_value_not_type_error(bad):
    v = np.zeros((3, 3, 3), np.float32)
    for call, name in [
        (lambda: hg.PinholeCamera(40, 30, bad, 47.0, 19.3, 14.6), "fx"),
        (lambda: hg.OccupancyGrid(GRID_ORIGIN, bad, 8), "size"),
        (lambda: hg.TSDFVolume(GRID_ORIGIN, 0.3, 8, bad), "truncation"),
        (lambda: hg.OccupancyGrid(GRID_ORIGIN, 0.3, 4).high_confidence(bad), "lam"),
        (lambda: hg.gaussian_filter3d(v, bad), "sigma"),
        (lambda: hg.nms3d(v, bad), "threshold"),
        (
            lambda: _core.keep_silhouettes(
                v > 0, v > 0, (0, 0, 0), bad, [], np.zeros((0, 4, 4)), []
            ),
            "voxel_size",
        ),
    ]:
        with raises(hg.InvalidValueError, name):
            call()


def test_numpy_scalars_are_numbers():
    cam = hg.PinholeCamera(np.int64(40), np.uint16(30), np.float32(45.0), 47, 19.3, 14.6)
    assert (cam.width, cam.height, cam.fx, cam.fy) == (40, 30, 45.0, 47.0)
    g = hg.OccupancyGrid(np.array([0.0, 0.0, 0.0], np.float32), np.float64(0.3), np.int32(4))
    assert (g.resolution, g.size) == (4, 0.3)
    assert g.high_confidence(np.array(0.5)).shape == (4, 4, 4)  # a 0-d array is a number


@pytest.mark.parametrize("bad", [None, "cam", hg.MeshScene(), (40, 30, 45.0, 47.0, 19.3, 14.6)])
def test_a_camera_argument_must_be_a_camera(used_grid, camera, box_scene, bad):
    """These raised pyo3's TypeError ("'None' is not an instance of 'PinholeCamera'")."""
    grid, before = used_grid
    scene, _ = box_scene
    vol = hg.TSDFVolume(GRID_ORIGIN, GRID_SIZE, 8)
    m = mask()
    calls = [
        lambda: grid.integrate(m, bad, good_pose()),
        lambda: grid.integrate_many(m[None], bad, good_pose()[None]),
        lambda: vol.integrate(np.ones((H, W), np.float32), bad, good_pose()),
        lambda: scene.render_mask(bad, good_pose()),
        lambda: scene.render_depth(bad, good_pose()),
        lambda: scene.render_labels(bad, good_pose()),
        lambda: hg.score_views(grid, scene, bad, [good_pose()[None]]),
    ]
    for call in calls:
        with raises(hg.InvalidValueError, "camera: expected a PinholeCamera"):
            call()
    with raises(hg.InvalidValueError, "cameras[0]: expected a PinholeCamera"):
        _core.keep_silhouettes(
            np.ones((2, 2, 2), bool),
            np.zeros((2, 2, 2), bool),
            (0, 0, 0),
            0.1,
            [bad],
            good_pose()[None],
            [m],
        )
    assert_unchanged(grid, before)
    with raises(hg.InvalidValueError, "grid: expected an OccupancyGrid"):
        hg.score_views(scene, scene, camera, [good_pose()[None]])
    with raises(hg.InvalidValueError, "scene: expected a MeshScene"):
        hg.score_views(grid, grid, camera, [good_pose()[None]])


def _unaligned(a: np.ndarray) -> np.ndarray:
    buf = np.zeros(a.nbytes + 1, np.uint8)
    u = np.frombuffer(buf.data, dtype=a.dtype, count=a.size, offset=1).reshape(a.shape)
    u[...] = a
    assert u.flags.c_contiguous and not u.flags.aligned
    return u


def test_unaligned_arrays_are_refused(used_grid, camera):
    """A C-contiguous array at an odd byte offset: a pose raised PanicException
    ("copy_from_slice: source slice length (0)"), candidates were read as none (no grasp,
    no error), counts as "got 0 values"."""
    grid, before = used_grid
    with raises(hg.ShapeError, "cam2world: array data must be aligned"):
        grid.integrate(mask(), camera, _unaligned(good_pose()))
    with raises(hg.ShapeError, "obj2world: array data must be aligned"):
        hg.MeshScene().add_mesh(*ref.box_mesh((0.1, 0.1, 0.1)), _unaligned(np.eye(4)))
    assert_unchanged(grid, before)
    args = _antipodal_args()
    args[4] = _unaligned(args[4])
    with raises(hg.ShapeError, "candidates: array data must be aligned"):
        _core.antipodal_grasps(*args, _panda_params())
    s = np.ones((3, 3, 3), np.uint32)
    with raises(hg.ShapeError, "segmented: array data must be aligned"):
        hg.OccupancyGrid.from_counts((0, 0, 0), 1.0, _unaligned(s), s)


def test_bool_arrays_holding_other_bytes_read_as_numpy_reads_them(camera):
    """A bool view of uint8 data can hold 2 or 255. Rust read such bytes as `bool`
    (undefined behaviour): the antipodal planner found no grasp and keep_silhouettes kept
    nothing where NumPy sees True."""
    args = _antipodal_args()
    raw = args[0].astype(np.uint8) * 2
    want = _core.antipodal_grasps(*args, _panda_params())
    assert want[0][0] > 0
    got = _core.antipodal_grasps(raw.view(bool), *args[1:], _panda_params())
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    r = args[0].shape[0]
    cam = hg.PinholeCamera(20, 16, 20.0, 20.0, 10.0, 8.0)
    pose = ref.look_at((0.05, 0.05, 0.6), (0.045, 0.045, 0.0))[None].copy()
    m = np.zeros((16, 20), np.uint8)
    m[4:12, 5:15] = 255
    trimmed = np.zeros((r, r, r), bool)
    want = _core.keep_silhouettes(args[0], trimmed, (0, 0, 0), 0.0075, [cam], pose, [m != 0])
    assert want.any()
    got = _core.keep_silhouettes(
        raw.view(bool), trimmed, (0, 0, 0), 0.0075, [cam], pose, [m.view(bool)]
    )
    assert got.view(np.uint8).max() == 1
    np.testing.assert_array_equal(got, want)
    g1, g2 = (hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, 8) for _ in range(2))
    mm = np.zeros((H, W), np.uint8)
    mm[5:25, 10:30] = 2
    g1.integrate(mm.view(bool), camera, good_pose())
    g2.integrate(mm != 0, camera, good_pose())
    for a, b in zip(g1.counts(), g2.counts(), strict=True):
        np.testing.assert_array_equal(a, b)


def test_endless_sequences_are_refused_without_reading_them(camera, box_scene):
    """`range(10**18)` as an origin or a camera list aborted the process (a Vec of 10**18
    floats: "memory allocation of 8000000000000000000 bytes failed"), as a ray origin it
    raised PanicException ("capacity overflow"), and as trajectories it ran until the
    machine was out of memory."""
    import itertools

    with raises(hg.ShapeError, "origin: expected 3 values, got 1000000000000000000"):
        hg.OccupancyGrid(range(10**18))
    with raises(hg.ShapeError, "origin: expected 3 values"):
        hg.MeshScene().cast_ray(range(2**62), (0, 0, 1))
    with raises(hg.ShapeError, "origin: expected 3 values, got more than 3"):
        hg.OccupancyGrid(itertools.count())
    full = np.ones((2, 2, 2), bool)
    for cams, masks, name in [
        (range(10**18), [], "cameras"),
        ([], range(10**18), "masks"),
        (itertools.repeat(camera), [], "cameras"),
    ]:
        with raises(hg.ShapeError, f"{name}: expected one entry per view"):
            _core.keep_silhouettes(full, ~full, (0, 0, 0), 0.1, cams, np.zeros((0, 4, 4)), masks)
    grid = hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, 4)
    scene, _ = box_scene
    traj = good_pose()[None]
    for trajs in (itertools.repeat(traj), range(10**18)):
        with raises(hg.ShapeError, "trajectories: expected at most 65536 trajectories"):
            hg.score_views(grid, scene, camera, trajs)
    assert hg.score_views(grid, scene, camera, itertools.repeat(traj, 3)).shape == (3,)


def test_errors_name_the_argument_given():
    """These named an argument the call does not have ("size", "resolution") or the
    core's field instead of the key of `params`."""
    z = np.zeros((0, 0, 0))
    with raises(hg.InvalidValueError, "voxel_size"):
        _core.keep_silhouettes(*[np.ones((2, 2, 2), bool)] * 2, (0, 0, 0), 1e308, *NO_VIEWS)
    with raises(hg.ShapeError, "full"):
        _core.keep_silhouettes(z.astype(bool), z.astype(bool), (0, 0, 0), 0.1, *NO_VIEWS)
    with raises(hg.InvalidValueError, "segmented, visible"):
        hg.OccupancyGrid.from_counts((0, 0, 0), 1.0, z.astype(np.uint32), z.astype(np.uint32))
    for fn in (hg.gaussian_filter3d, hg.maximum_filter3d):
        with raises(hg.ShapeError, "volume"):
            fn(z.astype(np.float32), 1)
    args = _antipodal_args()
    with raises(hg.ShapeError, "occupied"):
        empty = [z.astype(bool), np.zeros((3, 0, 0, 0)), z.astype(np.int32)]
        _core.antipodal_grasps(*empty, *args[3:], _panda_params())
    with raises(hg.InvalidValueError, 'params["max_opening"]'):
        _core.antipodal_grasps(*args, {**_panda_params(), "max_opening": 0.0})
    with raises(hg.InvalidValueError, 'params["palm_back_half"][1]'):
        _core.antipodal_grasps(*args, {**_panda_params(), "palm_back_half": (0.03, 1e300)})


def test_antipodal_params_any_mapping_but_nothing_else():
    from types import MappingProxyType

    args = _antipodal_args()
    want = _core.antipodal_grasps(*args, _panda_params())
    got = _core.antipodal_grasps(*args, MappingProxyType(_panda_params()))
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)
    pairs = {**_panda_params(), "palm_front_half": [0.022, 0.101]}  # a list is a pair too
    np.testing.assert_array_equal(_core.antipodal_grasps(*args, pairs)[0], want[0])
    for bad in [list(_panda_params().items()), None, "params"]:
        with raises(hg.InvalidValueError, "params: expected a mapping"):
            _core.antipodal_grasps(*args, bad)


@pytest.mark.parametrize(
    "key,factor",
    [
        ("tip_thickness", 1e300),
        ("base_thickness", 1e300),
        ("palm_front", 1e300),
        ("voxel_size", 1e-300),
        ("finger_width", 1e6),
    ],
)
def test_antipodal_extreme_gripper_lengths_are_refused(key, factor):
    """A length of 1e300 m (or a voxel of 1e-300 m) raised PanicException ("index out of
    bounds: the len is 392 but the index is 9223372036854775808"); a palm 1e298 m deep
    never returned."""
    p = _panda_params()
    p[key] *= factor
    with pytest.raises(hg.InvalidValueError, match=r"params\[.*\]: .*at most 65536 voxels"):
        _core.antipodal_grasps(*_antipodal_args(), p)


def test_antipodal_rotations_must_be_rotations_and_tilts_finite():
    args = _antipodal_args()
    for scale in (1e300, 1.01, -1.0):
        bad = list(args)
        bad[5] = args[5] * scale
        with raises(hg.NotRigidError, "rotations[0]"):
            _core.antipodal_grasps(*bad, _panda_params())
    for t in (np.nan, np.inf):
        bad = list(args)
        bad[6] = np.array([t])
        with raises(hg.NonFiniteError, "tilts"):
            _core.antipodal_grasps(*bad, _panda_params())
