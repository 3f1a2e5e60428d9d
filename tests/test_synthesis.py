"""Seed 001's grasp synthesis (planning.synthesis) on analytic shapes, and the core's
kernels against their NumPy reference (tests/reference_synthesis.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import reference_synthesis as ref
from heapgrasp import contact_patches
from heapgrasp.planning.synthesis import (
    estimate_normals,
    grasp_pairs,
    rank_grasps,
    usable_contacts,
)

S = 0.0075  # the benchmark's voxel


def _box(size: tuple[float, float, float]) -> np.ndarray:
    """Surface points of a box standing on the table (z = 0), centred on the z axis, on
    a 7.5 mm lattice of each face but the bottom."""
    sx, sy, sz = size
    xs = np.arange(-sx / 2, sx / 2 + 1e-9, S)
    ys = np.arange(-sy / 2, sy / 2 + 1e-9, S)
    zs = np.arange(0.0, sz + 1e-9, S)
    faces = []
    for x in (xs[0], xs[-1]):
        faces.append(np.stack(np.meshgrid([x], ys, zs, indexing="ij"), -1).reshape(-1, 3))
    for y in (ys[0], ys[-1]):
        faces.append(np.stack(np.meshgrid(xs, [y], zs, indexing="ij"), -1).reshape(-1, 3))
    faces.append(np.stack(np.meshgrid(xs, ys, [zs[-1]], indexing="ij"), -1).reshape(-1, 3))
    return np.unique(np.round(np.vstack(faces), 9), axis=0)


def _cylinder(radius: float, height: float) -> np.ndarray:
    n = max(8, round(2 * math.pi * radius / S))
    a = np.arange(n) * 2 * math.pi / n
    zs = np.arange(0.0, height + 1e-9, S)
    side = np.stack(
        [
            np.repeat(radius * np.cos(a), len(zs)),
            np.repeat(radius * np.sin(a), len(zs)),
            np.tile(zs, n),
        ],
        -1,
    )
    g = np.arange(-radius, radius + 1e-9, S)
    xx, yy = np.meshgrid(g, g)
    top = np.column_stack([xx.ravel(), yy.ravel(), np.full(xx.size, zs[-1])])
    return np.vstack([side, top[np.hypot(top[:, 0], top[:, 1]) < radius - S / 2]])


def _sphere(radius: float) -> np.ndarray:
    n = round(4 * math.pi * radius**2 / S**2)
    k = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * k / n)
    azimuth = math.pi * (1 + 5**0.5) * k
    unit = np.column_stack(
        [np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)]
    )
    return unit * radius + [0.0, 0.0, radius]


def _synthesise(points: np.ndarray):
    normals, curvature = estimate_normals(points)
    usable = usable_contacts(points, normals, curvature)
    return normals, usable, grasp_pairs(points, normals, usable)


def test_normals_point_out_of_a_sphere_with_low_curvature():
    pts = _sphere(0.05)
    normals, curvature = estimate_normals(pts)
    radial = (pts - [0, 0, 0.05]) / 0.05
    assert np.einsum("ij,ij->i", normals, radial).min() > 0.98
    assert curvature.max() < 0.05
    with pytest.raises(ValueError, match="need at least 10 points"):
        estimate_normals(pts[:5])
    with pytest.raises(ValueError, match=r"points must be \(N, 3\)"):
        estimate_normals(pts[:, :2])


def test_a_box_is_grasped_across_its_narrow_faces_only():
    pts = _box((0.04, 0.09, 0.10))
    _, usable, pairs = _synthesise(pts)
    assert len(pairs) > 20
    line = pts[pairs.second] - pts[pairs.first]
    line /= np.linalg.norm(line, axis=1)[:, None]
    assert np.abs(line[:, 0]).min() > math.cos(math.radians(15.0))  # across x, 4 cm
    assert pairs.quality.min() >= 150.0 and pairs.width.max() <= 0.08
    np.testing.assert_allclose(np.median(pairs.width), 0.04 + S, atol=0.004)
    # Not within 1 cm of the bottom, nor on the edges (curvature).
    assert pts[pairs.first, 2].min() >= 0.01 and pts[pairs.second, 2].min() >= 0.01
    edge = (np.abs(np.abs(pts[:, 0]) - 0.02) < 1e-6) & (np.abs(np.abs(pts[:, 1]) - 0.045) < 1e-6)
    assert not usable[edge].any()


def test_a_sphere_wider_than_the_hand_gets_no_grasp():
    _, usable, pairs = _synthesise(_sphere(0.05))
    assert usable.sum() > 100 and len(pairs) == 0


def test_a_cylinder_is_grasped_across_its_diameter():
    pts = _cylinder(0.03, 0.10)
    _, _, pairs = _synthesise(pts)
    assert len(pairs) > 20
    mid = (pts[pairs.first] + pts[pairs.second]) / 2
    assert np.hypot(mid[:, 0], mid[:, 1]).max() < 0.01  # through the axis
    line = pts[pairs.second] - pts[pairs.first]
    tilt = np.degrees(np.arcsin(np.abs(line[:, 2]) / np.linalg.norm(line, axis=1)))
    assert tilt.max() <= 15.0  # the 150° quality allows 15° on each contact
    assert (tilt == 0.0).mean() > 0.3
    np.testing.assert_allclose(pairs.width, 0.06 + S, atol=0.003)


def test_a_finger_pad_needs_a_patch():
    plane = np.stack(np.meshgrid(np.arange(-0.05, 0.05, S), np.arange(-0.05, 0.05, S)), -1)
    flat = np.column_stack([plane.reshape(-1, 2), np.zeros(plane.size // 2)])
    normals = np.tile([0.0, 0.0, 1.0], (len(flat), 1))
    centre = np.linalg.norm(flat, axis=1) == np.linalg.norm(flat, axis=1).min()
    assert contact_patches(flat, normals, centre)[centre].all()
    strip = flat[np.abs(flat[:, 0]) < 0.01]  # 2 cm wide: too narrow for the 26 mm pad
    assert not contact_patches(strip, normals[: len(strip)], np.ones(len(strip), bool)).any()


def test_grasps_near_the_centre_line_come_first():
    pts = _box((0.04, 0.09, 0.10))
    _, _, pairs = _synthesise(pts)
    order = rank_grasps(pts, pairs, [0.0, 0.0, 0.05])
    mid = (pts[pairs.first] + pts[pairs.second]) / 2
    line = np.hypot(mid[order, 0], mid[order, 1])
    assert np.all(np.diff(np.floor(line / 0.01)) >= 0)
    assert sorted(order.tolist()) == list(range(len(pairs)))


def test_a_grasp_pose_closes_along_the_contact_line_and_pitch_turns_the_approach():
    from heapgrasp.planning.synthesis import grasp_pose

    p1, p2 = np.array([0.02, 0.0, 0.05]), np.array([-0.02, 0.0, 0.05])
    above = grasp_pose(p1, p2, math.pi / 2)
    np.testing.assert_allclose(above[:3, 1], [1.0, 0.0, 0.0], atol=1e-12)  # closing
    np.testing.assert_allclose(above[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)  # from above
    np.testing.assert_allclose(above[:3, 3], [0.0, 0.0, 0.05])
    side = grasp_pose(p1, p2, 0.0)
    assert abs(side[2, 2]) < 1e-12  # level approach
    for pose in (above, side, grasp_pose([0, 0, 0.1], [0, 0, 0.05], 0.3)):
        r = pose[:3, :3]
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        assert np.linalg.det(r) > 0.999


def test_the_first_free_grasp_avoids_the_unexplored_region():
    from heapgrasp.planning.synthesis import first_free_grasp

    pts = _box((0.04, 0.09, 0.10))
    _, _, pairs = _synthesise(pts)
    order = rank_grasps(pts, pairs, [0.0, 0.0, 0.05])
    below = np.stack(np.meshgrid(*(np.arange(-0.2, 0.2, 0.02),) * 2, [-0.005]), -1).reshape(-1, 3)
    found = first_free_grasp(pts, below, pairs, order)
    assert found is not None
    k, pose = found
    np.testing.assert_allclose(pose[:3, 3], (pts[pairs.first[k]] + pts[pairs.second[k]]) / 2)
    np.testing.assert_allclose(pose[:3, 2], [0.0, 0.0, -1.0], atol=1e-9)  # from above first
    assert abs(pose[0, 1]) > 0.99  # closing across the 4 cm side
    # Unexplored space above the box: no approach from above, another one is found.
    g = np.arange(-0.15, 0.15, 0.01)
    roof = np.stack(np.meshgrid(g, g, np.arange(0.11, 0.3, 0.01)), -1).reshape(-1, 3)
    found = first_free_grasp(pts, np.vstack([below, roof]), pairs, order)
    assert found is not None and found[1][2, 2] > -0.99
    # Unexplored all around: nothing is free.
    shell = np.stack(np.meshgrid(g, g, np.arange(0.0, 0.3, 0.01)), -1).reshape(-1, 3)
    outside = (np.abs(shell[:, 0]) > 0.03) | (np.abs(shell[:, 1]) > 0.055) | (shell[:, 2] > 0.11)
    assert first_free_grasp(pts, shell[outside], pairs, order) is None


def _clouds() -> list[np.ndarray]:
    """Measured-looking clouds: the analytic shapes, jittered and turned (no lattice
    ties), and a rendered view of a stand-in object."""
    rng = np.random.default_rng(5)
    shapes = [_box((0.04, 0.09, 0.10)), _cylinder(0.03, 0.10), _sphere(0.035)]
    out = []
    for pts in shapes:
        a = rng.uniform(0, 2 * math.pi)
        turn = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        out.append(pts @ turn.T + rng.normal(0.0, 0.0008, pts.shape))
    from heapgrasp.viewsphere.objects import stand_in
    from heapgrasp.viewsphere.sphere import START
    from heapgrasp.viewsphere.world import ViewsphereWorld

    world = ViewsphereWorld(stand_in("005_tomato_soup_can"))
    views = [START] + [world.sphere.move(START, d)[1] for d in range(0, 8, 2)]
    out.append(world.object_points(views)[0])
    return out


@pytest.mark.parametrize("case", range(4))
def test_the_core_agrees_with_the_numpy_reference(case):
    pts = _clouds()[case]
    normals, curvature = estimate_normals(pts)
    want_n, want_c = ref.estimate_normals(pts)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", normals, want_n)), 1.0, atol=1e-6)
    np.testing.assert_allclose(normals, want_n, atol=1e-6)
    np.testing.assert_allclose(curvature, want_c, atol=1e-9)
    usable = usable_contacts(pts, want_n, want_c)
    want_u = ref.usable_contacts(pts, want_n, want_c)
    # Rounding may move a projected point across a pixel edge: at most a few disagree.
    assert usable.sum() > 0 and (usable != want_u).sum() <= max(2, usable.sum() // 100)
    pairs = grasp_pairs(pts, want_n, want_u)
    want = ref.grasp_pairs(pts, want_n, want_u)
    got = {(int(i), int(j)): (q, w) for i, j, q, w in zip(*dataclasses.astuple(pairs), strict=True)}
    exp = {(int(i), int(j)): (q, w) for i, j, q, w in zip(*dataclasses.astuple(want), strict=True)}
    # Pairs on the quality threshold may go either way.
    edge = {k for k, (q, _) in (got | exp).items() if abs(q - 150.0) < 1e-9}
    assert set(got) - edge == set(exp) - edge and len(exp) > 0
    for k in set(got) & set(exp):
        np.testing.assert_allclose(got[k], exp[k], rtol=0, atol=1e-9)
    assert list(got) == sorted(got)
