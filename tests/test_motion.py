"""Camera motion planning: look_at, view sphere (eq. 12), interpolation (eq. 8), timing."""

from __future__ import annotations

import math

import heapgrasp as hg
import numpy as np
import pytest
from heapgrasp.geometry.motion import (
    MotionLimits,
    TimedPath,
    ViewSphere,
    circle_waypoints,
    concatenate,
    hemisphere_waypoints,
    interpolate,
    look_at,
    path_length,
    plan_waypoints,
    time_path,
)
from ruckig import InputParameter, Ruckig, Trajectory

FX, FY, CX, CY = 270.0, 270.0, 159.5, 119.5


def sphere() -> ViewSphere:
    # 0.30 m scene cube with minimum corner (-0.15, -0.15, 0.0), Table I radius.
    return ViewSphere.for_cube((-0.15, -0.15, 0.0), 0.30, radius=0.33)


def project(cam2world: np.ndarray, point: np.ndarray) -> tuple[float, float, float]:
    p = np.linalg.inv(cam2world) @ np.append(point, 1.0)
    return FX * p[0] / p[2] + CX, FY * p[1] / p[2] + CY, p[2]


def assert_rigid(pose: np.ndarray) -> None:
    r = pose[:3, :3]
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_array_equal(pose[3], [0.0, 0.0, 0.0, 1.0])


def distance_to_polyline(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    a, b = vertices[:-1], vertices[1:]
    ab = b - a
    t = np.einsum("kij,ij->ki", points[:, None, :] - a[None], ab) / np.sum(ab * ab, axis=1)
    t = np.clip(t, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.min(np.linalg.norm(points[:, None, :] - closest, axis=2), axis=1)


# ----------------------------------------------------------------------------- look_at


@pytest.mark.parametrize(
    ("eye", "target"),
    [((0.4, 0.1, 0.5), (0.0, 0.0, 0.1)), ((-0.3, 0.2, 0.05), (0.1, -0.1, 0.2))],
)
def test_look_at_is_rigid_and_centres_the_target(eye, target):
    pose = look_at(eye, target)
    assert pose.shape == (4, 4) and pose.dtype == np.float64
    assert_rigid(pose)
    np.testing.assert_array_equal(pose[:3, 3], eye)
    u, v, z = project(pose, np.asarray(target))
    assert z == pytest.approx(np.linalg.norm(np.subtract(target, eye)))
    assert (u, v) == (pytest.approx(CX), pytest.approx(CY))
    # x (image right) is horizontal for up = +z, and y (image down) points downward.
    assert pose[2, 0] == pytest.approx(0.0, abs=1e-15)
    assert pose[2, 1] < 0.0


def test_look_at_straight_down_sees_world_y_at_the_top():
    pose = look_at((0.0, 0.0, 0.5), (0.0, 0.0, 0.0))
    np.testing.assert_allclose(pose[:3, :3], [[1, 0, 0], [0, -1, 0], [0, 0, -1]], atol=0)
    _, v, _ = project(pose, np.array([0.0, 0.05, 0.0]))
    assert v < CY
    # Looking straight up: still rigid, +y fallback.
    assert_rigid(look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)))


def test_look_at_matches_the_rust_core_in_a_render():
    """The core's rasteriser agrees with where the Python pose projects a marker."""
    cam = hg.PinholeCamera(320, 240, FX, FY, CX, CY)
    scene = hg.MeshScene()
    marker = np.array([0.04, 0.06, 0.0])
    h = 0.01
    verts = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
    faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int64)
    obj2world = np.eye(4)
    obj2world[:3, 3] = marker
    scene.add_mesh(verts, faces, obj2world)
    for eye in [(0.0, 0.0, 0.5), (0.3, -0.2, 0.4)]:
        pose = look_at(eye, (0.0, 0.0, 0.0))
        mask = scene.render_mask(cam, np.ascontiguousarray(pose))
        u, v, _ = project(pose, marker)
        assert mask[round(v), round(u)]
        vs, us = np.nonzero(mask)
        assert abs(vs.mean() - v) < 2.0 and abs(us.mean() - u) < 2.0
        if eye == (0.0, 0.0, 0.5):  # straight down: world +y is toward the image top
            assert vs.max() < CY


def test_look_at_rejects_eye_equal_target():
    with pytest.raises(ValueError, match="target"):
        look_at((0.1, 0.2, 0.3), (0.1, 0.2, 0.3))
    with pytest.raises(hg.NonFiniteError):
        look_at((np.nan, 0.0, 0.0), (0.0, 0.0, 0.0))


# ----------------------------------------------------------------------------- view sphere


def test_view_sphere_for_cube():
    s = sphere()
    assert s.center == (0.0, 0.0, 0.0)
    assert s.target == (0.0, 0.0, 0.15)
    assert s.radius == 0.33
    with pytest.raises(ValueError, match="radius"):
        ViewSphere((0.0, 0.0, 0.0), (0.0, 0.0, 0.1), -1.0)


def test_candidates_follow_eq_12():
    s = sphere()
    cands = s.candidates()
    assert cands.shape == (40, 20, 4, 4)
    eyes = cands[..., :3, 3]
    np.testing.assert_allclose(np.linalg.norm(eyes - s.center_array, axis=-1), 0.33, atol=1e-12)
    # theta = 0 row: all at the top of the sphere.
    np.testing.assert_allclose(eyes[:, 0], np.tile([0.0, 0.0, 0.33], (40, 1)), atol=1e-15)
    # Index [u-1, v-1] has phi = 2 pi (u-1)/U, theta = theta_max (v-1)/V.
    for u, v in [(1, 2), (7, 5), (40, 20), (23, 11)]:
        phi, theta = 2 * math.pi * (u - 1) / 40, (math.pi / 5) * (v - 1) / 20
        np.testing.assert_allclose(cands[u - 1, v - 1], s.pose(phi, theta), atol=1e-14)
        p, t, r = s.spherical(cands[u - 1, v - 1])
        assert (p, t, r) == (pytest.approx(phi), pytest.approx(theta), pytest.approx(0.33))
    assert s.spherical(eyes[0, 0]) == (0.0, pytest.approx(0.0, abs=1e-12), pytest.approx(0.33))
    # Every candidate looks at the scene centre.
    for pose in cands.reshape(-1, 4, 4):
        assert_rigid(pose)
        u_px, v_px, z = project(pose, s.target_array)
        assert z > 0.0
        assert u_px == pytest.approx(CX, abs=1e-9)
        assert v_px == pytest.approx(CY, abs=1e-9)
    phi, theta = ViewSphere.candidate_angles(4, 2, 1.0)
    np.testing.assert_allclose(phi[:, 0], [0, math.pi / 2, math.pi, 3 * math.pi / 2])
    np.testing.assert_allclose(theta[0], [0.0, 0.5])


# ----------------------------------------------------------------------------- interpolate


@pytest.mark.parametrize(
    ("a", "b"),
    [((0.0, 0.5), (2.0, 0.3)), ((0.3, 0.1), (0.31, 0.6)), ((1.0, 0.0), (4.0, 0.6))],
)
def test_interpolation_stays_on_the_sphere(a, b):
    s = sphere()
    pa, pb = s.pose(*a), s.pose(*b)
    path = interpolate(pa, pb, s, step=0.005)
    eyes = path[:, :3, 3]
    np.testing.assert_allclose(np.linalg.norm(eyes - s.center_array, axis=1), 0.33, atol=1e-9)
    np.testing.assert_array_equal(path[0], pa)
    np.testing.assert_array_equal(path[-1], pb)
    steps = np.linalg.norm(np.diff(eyes, axis=0), axis=1)
    assert steps.max() <= 0.005 + 1e-15
    ua, ub = pa[:3, 3] / 0.33, pb[:3, 3] / 0.33
    arc = 0.33 * math.acos(np.clip(ua @ ub, -1.0, 1.0))
    assert path_length(path) == pytest.approx(arc, rel=0.01)
    assert len(path) >= math.ceil(arc / 0.005) + 1
    for pose in path:
        assert_rigid(pose)
        u_px, v_px, _ = project(pose, s.target_array)
        assert (u_px, v_px) == (pytest.approx(CX, abs=1e-9), pytest.approx(CY, abs=1e-9))


def test_interpolation_special_cases():
    s = sphere()
    p = s.pose(1.0, 0.4)
    single = interpolate(p, p, s)
    assert single.shape == (1, 4, 4)
    np.testing.assert_array_equal(single[0], p)
    # Antipodal eyes (equator): deterministic, over the top of the sphere.
    a, b = s.pose(0.0, math.pi / 2), s.pose(math.pi, math.pi / 2)
    path = interpolate(a, b, s, step=0.01)
    np.testing.assert_array_equal(path, interpolate(a, b, s, step=0.01))
    assert path[:, 2, 3].max() == pytest.approx(0.33, abs=1e-4)
    assert path_length(path) == pytest.approx(0.33 * math.pi, rel=1e-3)
    # Different radii: radius interpolated linearly along the same direction.
    far = look_at(2.0 * s.eye(0.5, 0.3), s.target_array)
    radial = interpolate(s.pose(0.5, 0.3), far, s, step=0.01)
    r = np.linalg.norm(radial[:, :3, 3], axis=1)
    np.testing.assert_allclose(r, np.linspace(0.33, 0.66, len(r)), atol=1e-12)
    assert path_length(radial) == pytest.approx(0.33)
    assert path_length(radial[:1]) == 0.0


# ----------------------------------------------------------------------------- timing


def straight_path(length: float, n: int = 101) -> np.ndarray:
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = np.linspace(0.0, length, n)
    return poses


def test_duration_matches_ruckig_and_the_closed_form():
    timed = time_path(straight_path(1.0), MotionLimits())
    assert timed.length == pytest.approx(1.0)
    # Closed form: t_j = a/j = 0.2, constant-acceleration phase (v - a^2/j)/a = 0.05, the
    # two ramps cover 2 * v * 0.45 / 2 = 0.1125 m, cruise (1 - 0.1125) / v = 3.55 s.
    assert timed.duration == pytest.approx(4.45, abs=1e-9)
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [timed.length]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [0.25], [1.0], [5.0]
    traj = Trajectory(1)
    Ruckig(1).calculate(inp, traj)
    assert timed.duration == traj.duration


@pytest.mark.parametrize("limits", [MotionLimits(), MotionLimits(0.1, 0.5, 2.0)])
def test_time_path_respects_the_limits(limits):
    s = sphere()
    timed = time_path(interpolate(s.pose(0.0, 0.6), s.pose(2.5, 0.2), s), limits)
    dt = 1e-3
    t = np.arange(0.0, timed.duration + dt, dt)
    eyes = np.array([timed.at(float(ti))[:3, 3] for ti in t])
    speed = np.linalg.norm(np.diff(eyes, axis=0), axis=1) / dt
    assert speed.max() <= limits.max_velocity * (1 + 1e-3)
    assert speed.max() >= 0.95 * limits.max_velocity
    states = np.array([timed.state(float(ti)) for ti in t])
    assert np.all(np.abs(states[:, 1]) <= limits.max_velocity * (1 + 1e-9))
    assert np.all(np.abs(states[:, 2]) <= limits.max_acceleration * (1 + 1e-9))
    # Starts and ends at rest.
    assert timed.state(0.0)[1:] == (0.0, 0.0)
    assert timed.state(timed.duration)[1:] == (0.0, 0.0)
    assert speed[0] < 1e-3 and speed[-1] < 1e-3
    np.testing.assert_array_equal(timed.at(0.0), timed.poses[0])
    np.testing.assert_array_equal(timed.at(timed.duration), timed.poses[-1])
    np.testing.assert_array_equal(timed.at(timed.duration + 1.0), timed.poses[-1])


def test_sample_at_camera_rate_on_the_geometric_path():
    s = sphere()
    geo = interpolate(s.pose(0.0, 0.6), s.pose(2.0, 0.3), s)
    timed = time_path(geo)
    times, poses = timed.sample(30.0)
    assert poses.shape == (len(times), 4, 4)
    assert times[0] == 0.0 and times[-1] == timed.duration
    gaps = np.diff(times)
    np.testing.assert_allclose(gaps[:-1], 1 / 30, rtol=0, atol=1e-12)
    assert 0.0 < gaps[-1] <= 1 / 30 + 1e-12
    assert len(times) == math.floor(timed.duration * 30 - 1e-9) + 2
    np.testing.assert_array_equal(poses[0], geo[0])
    np.testing.assert_array_equal(poses[-1], geo[-1])
    # On the geometric path: on the polyline through the samples, hence within the chord
    # sag step^2 / (8 r) of the sphere, and still looking at the target.
    eyes = poses[:, :3, 3]
    assert distance_to_polyline(eyes, geo[:, :3, 3]).max() < 1e-12
    r = np.linalg.norm(eyes - s.center_array, axis=1)
    assert np.all(r <= 0.33 + 1e-12) and np.all(r >= 0.33 - 0.005**2 / (8 * 0.33) - 1e-12)
    arc = np.array([timed.state(float(t))[0] for t in times])
    assert np.all(np.diff(arc) > 0.0)
    # Orientations are slerped between samples: the optical axis stays within
    # (step / distance)^2 rad of the target direction (exact at the samples).
    for pose in poses:
        assert_rigid(pose)
        to_target = s.target_array - pose[:3, 3]
        d = np.linalg.norm(to_target)
        angle = math.acos(min(1.0, float(pose[:3, 2] @ to_target) / d))
        assert angle <= (0.005 / d) ** 2
    # Default frame rate.
    np.testing.assert_array_equal(timed.sample()[0], times)


def test_zero_length_path():
    p = sphere().pose(0.0, 0.2)
    timed = time_path(p[None])
    assert (timed.length, timed.duration) == (0.0, 0.0)
    times, poses = timed.sample()
    np.testing.assert_array_equal(times, [0.0])
    np.testing.assert_array_equal(poses, p[None])


def test_motion_limits_are_validated():
    with pytest.raises(ValueError, match="max_velocity"):
        MotionLimits(max_velocity=0.0)
    with pytest.raises(ValueError, match="max_jerk"):
        MotionLimits(max_jerk=math.inf)


def test_plan_waypoints_follows_eq_8():
    s = sphere()
    start = s.pose(0.0, 0.0)
    wps = circle_waypoints(s, L=3, theta=math.pi / 5, phi0=0.3)
    paths = plan_waypoints(start, list(wps), s, MotionLimits(), 30.0)
    assert len(paths) == 3 and all(isinstance(p, TimedPath) for p in paths)
    prev = start
    for path, wp in zip(paths, wps, strict=True):
        np.testing.assert_array_equal(path.poses[0, :3, 3], prev[:3, 3])
        np.testing.assert_array_equal(path.poses[-1], wp)
        assert path.state(0.0)[1] == 0.0 and path.state(path.duration)[1] == 0.0
        assert path.fps == 30.0
        prev = wp
    times, poses = concatenate(paths)
    assert times[-1] == pytest.approx(sum(p.duration for p in paths))
    assert np.all(np.diff(times) > 0.0)
    np.testing.assert_array_equal(poses[0], start)
    np.testing.assert_array_equal(poses[-1], wps[-1])
    assert path_length(poses) <= sum(p.length for p in paths) + 1e-12
    assert plan_waypoints(start, [], s) == []


# ----------------------------------------------------------------------------- baselines


def test_hemisphere_waypoints_are_reproducible():
    center = np.array([0.0, 0.0, 0.15])
    a = hemisphere_waypoints(np.random.default_rng(7), center)
    b = hemisphere_waypoints(np.random.default_rng(7), center)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (6, 4, 4)
    assert not np.array_equal(a, hemisphere_waypoints(np.random.default_rng(8), center))
    d = a[:, :3, 3] - center
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 0.5, atol=1e-12)
    np.testing.assert_allclose(d[:, 2], 0.5 * math.cos(math.pi / 6), atol=1e-12)
    phi = np.arctan2(d[:, 1], d[:, 0]) % (2 * math.pi)
    assert np.all(np.diff(phi) > 0.0)  # visited in increasing azimuth
    expected = np.sort(np.random.default_rng(7).uniform(0.0, 2 * math.pi, 6))
    np.testing.assert_allclose(phi, expected, atol=1e-12)
    for pose in a:
        u_px, v_px, _ = project(pose, center)
        assert (u_px, v_px) == (pytest.approx(CX, abs=1e-9), pytest.approx(CY, abs=1e-9))


def test_circle_waypoints_are_evenly_spaced():
    s = sphere()
    wps = circle_waypoints(s, L=5, theta=math.pi / 5, phi0=0.4)
    assert wps.shape == (5, 4, 4)
    eyes = wps[:, :3, 3]
    ring = np.roll(eyes, -1, axis=0) - eyes
    chords = np.linalg.norm(ring, axis=1)
    np.testing.assert_allclose(chords, chords[0], rtol=1e-12)
    expected = 2 * 0.33 * math.sin(math.pi / 5) * math.sin(math.pi / 5)
    assert chords[0] == pytest.approx(expected)
    for k, pose in enumerate(wps):
        phi, theta, r = s.spherical(pose)
        assert phi == pytest.approx((0.4 + 2 * math.pi * k / 5) % (2 * math.pi))
        assert theta == pytest.approx(math.pi / 5)
        assert r == pytest.approx(0.33)
        np.testing.assert_allclose(pose, s.pose(phi, theta), atol=1e-14)


def test_a_closed_circle_goes_once_around_and_back_to_its_first_waypoint():
    s = sphere()
    open_ = circle_waypoints(s, L=3, theta=math.pi / 5, phi0=-0.7)
    closed = circle_waypoints(s, L=3, theta=math.pi / 5, phi0=-0.7, closed=True)
    assert closed.shape == (4, 4, 4)
    np.testing.assert_array_equal(closed[:3], open_)
    np.testing.assert_allclose(closed[3], closed[0], atol=1e-12)
    # three equal legs: the whole circle, not two thirds of it
    legs = np.linalg.norm(np.diff(closed[:, :3, 3], axis=0), axis=1)
    np.testing.assert_allclose(legs, legs[0], rtol=1e-12)
    assert len(circle_waypoints(s, L=1, closed=True)) == 1  # no circle to close
    with pytest.raises(ValueError, match="L"):
        circle_waypoints(s, L=0, closed=True)
