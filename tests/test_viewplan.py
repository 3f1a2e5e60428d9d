"""View planning: the eq. 14 oracle and the fixed-view baselines."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt
import pytest
from heapgrasp import MeshScene, OccupancyGrid
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.motion import (
    ViewSphere,
    arc_length_samples,
    interpolate,
    interpolate_sampled,
    look_at,
)
from heapgrasp.geometry.motion.interpolation import _arc_eyes
from heapgrasp.geometry.motion.sphere import look_at_many
from heapgrasp.planning.views import (
    OracleViewScorer,
    ViewContext,
    fixed_waypoints,
    subsample_path,
    sweep_waypoints,
    target_region,
)
from reference import box_mesh


@pytest.fixture
def scene() -> MeshScene:
    s = MeshScene()
    v, f = box_mesh((0.03, 0.05, 0.04))
    pose = np.eye(4)
    pose[:3, 3] = (0.15, 0.15, 0.04)
    s.add_mesh(v, f, pose)
    return s


def test_oracle_prefers_the_unseen_side_to_a_repeated_view(scene: MeshScene) -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    camera = CameraSpec.continuous()
    seen = sphere.pose(0.0, math.pi / 5)
    grid = OccupancyGrid((0.0, 0.0, 0.0), 0.30, 40)
    # Everything captured so far: the path from the top to the seen waypoint.
    for pose in interpolate(sphere.pose(0.0, 0.0), seen, sphere, step=0.02):
        grid.integrate(scene.render_mask(camera.core(), pose), camera.core(), pose)
    assert grid.count_high_confidence(0.9) > 0
    candidates = np.stack([seen, sphere.pose(math.pi, math.pi / 5), sphere.pose(0.5, 0.3)])
    ctx = ViewContext(grid, seen, candidates[:, None], sphere, camera, 0.9, scene)
    s = OracleViewScorer(frames_per_candidate=6).scores(ctx)
    assert s.shape == (3, 1)
    # Re-observing the last view only lowers voxels seen inconsistently along the path.
    assert 0.0 <= s[0, 0] < 0.05
    assert s[1, 0] > 0.2, "the far side carves much of the hull away"
    assert s[1, 0] > s[2, 0] >= 0.0


def test_oracle_scores_the_full_candidate_set_with_one_top_column(scene: MeshScene) -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    camera = CameraSpec.continuous()
    start = sphere.pose(0.0, 0.0)
    grid = OccupancyGrid((0.0, 0.0, 0.0), 0.30, 40)
    grid.integrate(scene.render_mask(camera.core(), start), camera.core(), start)
    cands = sphere.candidates(8, 4, math.pi / 5)
    ctx = ViewContext(grid, start, cands, sphere, camera, 0.9, scene)
    s = OracleViewScorer(frames_per_candidate=3).scores(ctx)
    assert s.shape == (8, 4) and s.dtype == np.float32
    assert np.all(s[:, 0] == s[0, 0]), "theta = 0 candidates coincide"
    assert s[0, 0] == pytest.approx(0.0, abs=1e-6), "the top is where the camera is"
    assert s[:, 1:].min() > 0.0
    with pytest.raises(ValueError, match="true meshes"):
        OracleViewScorer().scores(ViewContext(grid, start, cands, sphere, camera, 0.9, None))
    with pytest.raises(ValueError, match="frames_per_candidate"):
        OracleViewScorer(frames_per_candidate=0)


def test_subsample_path_keeps_the_end_and_drops_the_start() -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    path = interpolate(sphere.pose(0.0, 0.0), sphere.pose(1.0, 0.5), sphere, step=0.005)
    sub = subsample_path(path, 5)
    assert len(sub) == 5
    np.testing.assert_array_equal(sub[-1], path[-1])
    assert not np.array_equal(sub[0], path[0])
    assert len(subsample_path(path[:1], 5)) == 1


def test_sampled_paths_are_the_subsampled_interpolations_exactly() -> None:
    # The oracle orients only the poses it keeps; they must be the very poses that
    # interpolating every path and subsampling it gives (bit for bit), for every kind of
    # path: along the sphere, radial, over the top, from off the sphere, none at all.
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    start = dataclasses.replace(sphere, radius=0.5).pose(-math.pi / 2, 0.9)
    goals = np.concatenate(
        [
            sphere.candidates(8, 4, math.pi / 5).reshape(-1, 4, 4),
            dataclasses.replace(sphere, radius=0.5).pose(-math.pi / 2, 0.9)[None],
            sphere.pose(-math.pi / 2, 0.9)[None],
            sphere.pose(math.pi / 2, 0.9)[None],
        ]
    )
    for a in (start, sphere.pose(0.0, 0.0)):
        fast = interpolate_sampled(a, goals, sphere, step=0.01, frames=10)
        for goal, got in zip(goals, fast, strict=True):
            want = subsample_path(interpolate(a, goal, sphere, step=0.01), 10)
            np.testing.assert_array_equal(got, want)
    with pytest.raises(ValueError, match="frames"):
        interpolate_sampled(start, goals, sphere, step=0.01, frames=0)


def _sampled_one_by_one(
    start: npt.NDArray[np.float64],
    goals: npt.NDArray[np.float64],
    sphere: ViewSphere,
    step: float,
    frames: int,
) -> list[npt.NDArray[np.float64]]:
    """The per-goal loop interpolate_sampled was (one path's eyes, samples, poses)."""
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for goal in goals:
        eyes = _arc_eyes(start[:3, 3], goal[:3, 3], sphere.center_array, step)
        idx = arc_length_samples(eyes, frames)
        out.append(look_at_many(np.ascontiguousarray(eyes[idx]), sphere.target_array, up))
    return out


def test_sampled_paths_equal_the_per_goal_loop_bit_for_bit() -> None:
    # All paths at once must give the poses of one path at a time, bit for bit: random
    # goals on and off the sphere, below it, and the degenerate ones (the start itself or
    # within 1e-12 of it, a tiny move, radial moves, antipodal and nearly antipodal
    # goals, pole to pole), for several starts, steps and frame counts.
    rng = np.random.default_rng(11)
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    c, tgt = sphere.center_array, sphere.target_array

    def pose_at(eye: npt.ArrayLike) -> npt.NDArray[np.float64]:
        return look_at(eye, tgt)

    def rotated(d: npt.NDArray[np.float64], angle: float) -> npt.NDArray[np.float64]:
        # d turned by `angle` about an axis perpendicular to it.
        axis = np.cross(d, [0.3, -0.5, 0.8])
        axis /= np.linalg.norm(axis)
        return d * math.cos(angle) + np.cross(axis, d) * math.sin(angle)

    starts = [
        sphere.pose(0.3, 0.5),
        sphere.pose(0.0, 0.0),  # the top pole: the theta = 0 candidates coincide with it
        dataclasses.replace(sphere, radius=0.5).pose(-2.0, 1.2),
        pose_at(c + np.array([0.2, -0.1, -0.15])),  # below the sphere's centre
    ]
    for start in starts:
        ea = start[:3, 3]
        da = ea - c
        dirs = rng.normal(size=(60, 3))
        dirs /= np.linalg.norm(dirs, axis=1)[:, None]
        radii = rng.uniform(0.1, 0.8, size=60)
        radii[:30] = sphere.radius  # half of them on the sphere
        eyes = [c + r * d for r, d in zip(radii, dirs, strict=True)]
        eyes += [
            ea.copy(),  # the start itself
            ea + np.array([1e-13, 0.0, -1e-13]),  # within 1e-12: no motion either
            ea + np.array([1e-9, 2e-9, 0.0]),  # a tiny move
            c + 1.7 * da,  # radial, outward
            c + 0.4 * da,  # radial, inward
            c - da,  # antipodal
            c - 0.6 * da,  # antipodal, at another radius
            c + rotated(-da, 1e-11),  # nearly antipodal: taken as antipodal
            c + rotated(-da, 1e-7),  # nearly antipodal: a plane of its own
            c + rotated(da, 1e-7),  # nearly the same direction
            c + np.array([0.0, 0.0, -sphere.radius]),  # the bottom pole
        ]
        goals = np.stack([pose_at(e) for e in eyes])
        for step, frames in [(0.01, 10), (0.003, 1), (0.02, 3), (0.5, 10), (0.01, 80)]:
            fast = interpolate_sampled(start, goals, sphere, step=step, frames=frames)
            slow = _sampled_one_by_one(start, goals, sphere, step, frames)
            assert len(fast) == len(slow) == len(goals)
            for k, (got, want) in enumerate(zip(fast, slow, strict=True)):
                assert got.shape == want.shape, (k, step, frames)
                np.testing.assert_array_equal(got, want, err_msg=f"goal {k}, {step}, {frames}")
    # Only the start: one pose per goal, the start's eye.
    same = np.stack([starts[0]] * 3)
    fast = interpolate_sampled(starts[0], same, sphere, step=0.01, frames=10)
    for got, want in zip(fast, _sampled_one_by_one(starts[0], same, sphere, 0.01, 10), strict=True):
        assert got.shape == (1, 4, 4)
        np.testing.assert_array_equal(got, want)
    # A goal at the sphere's centre has no direction; one at the target no orientation.
    for bad in (c, tgt):
        goals = np.stack([sphere.pose(1.0, 0.4), pose_at(c + np.array([0.1, 0.0, 0.0]))])
        goals[1, :3, 3] = bad
        with pytest.raises(ValueError, match=r"sphere\.center|target"):
            _sampled_one_by_one(starts[0], goals, sphere, 0.01, 10)
        with pytest.raises(ValueError, match=r"sphere\.center|target"):
            interpolate_sampled(starts[0], goals, sphere, step=0.01, frames=10)


def test_fixed_waypoints() -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    circle = fixed_waypoints("circle", sphere, L=3)
    assert circle.shape == (4, 4, 4)  # once around: back to the first waypoint
    np.testing.assert_allclose(circle[-1], circle[0], atol=1e-12)
    np.testing.assert_allclose(
        np.linalg.norm(circle[:, :3, 3] - sphere.center_array, axis=1), sphere.radius
    )
    h6 = fixed_waypoints("hemisphere6", sphere, rng=np.random.default_rng(1))
    assert h6.shape == (6, 4, 4)
    np.testing.assert_allclose(np.linalg.norm(h6[:, :3, 3] - sphere.target_array, axis=1), 0.5)
    np.testing.assert_allclose(h6[:, 2, 3], sphere.target[2] + 0.5 * math.cos(math.pi / 6))
    with pytest.raises(ValueError, match="kind"):
        fixed_waypoints("spiral", sphere)


def test_target_region_is_the_column_over_the_target() -> None:
    grid = OccupancyGrid((0.0, 0.0, 0.0), 0.30, 20)
    col = target_region(grid, (0.15, 0.15, 0.9), 0.03)
    assert col.shape == (20, 20, 20) and col.dtype == np.bool_
    assert np.all(col == col[:, :, :1]), "a vertical column: the same in every layer"
    centres = (np.arange(20) + 0.5) * 0.015
    d = np.hypot(centres[:, None] - 0.15, centres[None, :] - 0.15)
    np.testing.assert_array_equal(col[:, :, 0], d <= 0.03)
    for bad in ((0.1, 0.1), (0.1, np.nan, 0.0)):
        with pytest.raises(ValueError, match="position"):
            target_region(grid, bad, 0.03)
    with pytest.raises(ValueError, match="radius"):
        target_region(grid, (0.1, 0.1, 0.0), 0.0)
    with pytest.raises(ValueError, match="target_radius"):
        OracleViewScorer(target_radius=-0.1)


def test_target_column_oracle_favours_views_of_the_target() -> None:
    # A small target box beside a big one, seen from the top only. Over the whole grid
    # the views above the big box's side carve the most; on the target's column, the
    # views from the far side, which see the small box obliquely, do.
    scene = MeshScene()
    for half, centre in (
        ((0.02, 0.02, 0.03), (0.06, 0.15, 0.03)),
        ((0.05, 0.05, 0.05), (0.22, 0.15, 0.05)),
    ):
        v, f = box_mesh(half)
        pose = np.eye(4)
        pose[:3, 3] = centre
        scene.add_mesh(v, f, pose)
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30)
    camera = CameraSpec.continuous()
    start = sphere.pose(0.0, 0.0)
    grid = OccupancyGrid((0.0, 0.0, 0.0), 0.30, 40)
    grid.integrate(scene.render_mask(camera.core(), start), camera.core(), start)
    far, near = sphere.pose(0.0, math.pi / 5), sphere.pose(math.pi, math.pi / 5)
    cands = np.stack([far, near])[:, None]
    target = np.eye(4)
    target[:3, 3] = (0.06, 0.15, 0.05)
    oracle = OracleViewScorer(frames_per_candidate=4, target_radius=0.04)
    whole = oracle.scores(ViewContext(grid, start, cands, sphere, camera, 0.9, scene))
    column = oracle.scores(ViewContext(grid, start, cands, sphere, camera, 0.9, scene, target))
    assert whole[1, 0] > whole[0, 0], "globally the near view carves more"
    assert column[0, 0] > column[1, 0] + 0.1, "on the target's column the far view does"
    # the column scores are eq. 14 counted on target_region
    plain = OracleViewScorer(frames_per_candidate=4)
    assert oracle.region(ViewContext(grid, start, cands, sphere, camera, 0.9, scene)) is None
    np.testing.assert_array_equal(
        whole, plain.scores(ViewContext(grid, start, cands, sphere, camera, 0.9, scene))
    )
    region = oracle.region(ViewContext(grid, start, cands, sphere, camera, 0.9, scene, target))
    assert region is not None
    np.testing.assert_array_equal(region, target_region(grid, target[:3, 3], 0.04))


def test_sweep_turns_toward_the_azimuths_not_yet_seen() -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.3, radius=0.33)
    theta = math.pi / 5
    current = sphere.pose(0.0, theta)
    # Views so far lie clockwise of the current one (and one above, without azimuth).
    seen = np.stack([sphere.eye(math.radians(a), theta) for a in (0.0, -30.0, -60.0)])
    seen = np.vstack([seen, sphere.eye(0.0, 0.0)])
    goals = sweep_waypoints(sphere, current, seen, degrees=100.0, step=45.0, theta=theta)
    assert goals.shape == (3, 4, 4)  # 100° in steps of at most 45°: 33.3° each
    phis = [math.degrees(sphere.spherical(g)[0]) for g in goals]
    np.testing.assert_allclose(phis, [100 / 3, 200 / 3, 100.0], atol=1e-9)
    for g in goals:
        assert sphere.spherical(g)[1] == pytest.approx(theta)
        np.testing.assert_allclose(g, sphere.pose(sphere.spherical(g)[0], theta), atol=1e-12)
    # Seen counter-clockwise instead: it turns the other way.
    mirrored = seen * np.array([1.0, -1.0, 1.0]) + np.array([0.0, 0.3, 0.0])
    back = sweep_waypoints(sphere, current, mirrored, degrees=100.0, step=45.0, theta=theta)
    phis = [math.degrees(sphere.spherical(g)[0]) for g in back]
    np.testing.assert_allclose(phis, [360 - 100 / 3, 360 - 200 / 3, 260.0], atol=1e-9)


@pytest.mark.parametrize("degrees", [0.0, -10.0, 400.0, float("nan")])
def test_sweep_rejects_a_bad_extent(degrees: float) -> None:
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.3, radius=0.33)
    with pytest.raises(ValueError, match="degrees"):
        sweep_waypoints(sphere, sphere.pose(0.0, 0.5), np.zeros((0, 3)), degrees=degrees)
