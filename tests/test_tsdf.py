"""TSDF fusion against the NumPy reference of the tsdf.rs contract."""

from __future__ import annotations

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref

ORIGIN, SIZE, RES, TRUNC = (-0.15, -0.15, 0.0), 0.30, 14, 0.04


def assert_tsdf_match(vol, r):
    vals, wts = vol.values(), vol.weights()
    assert vals.dtype == np.float32 and wts.dtype == np.float32
    assert vals.shape == wts.shape == (RES,) * 3
    ok = ~r.tie
    np.testing.assert_array_equal(wts[ok], r.weights[ok])
    np.testing.assert_allclose(vals[ok], r.values[ok], rtol=0, atol=1e-5)
    assert np.all(np.abs(vals) <= 1.0)


def test_tsdf_properties():
    vol = hg.TSDFVolume(ORIGIN, SIZE, RES, TRUNC)
    assert vol.resolution == RES
    assert vol.truncation == pytest.approx(TRUNC)
    assert vol.size == pytest.approx(SIZE)
    assert vol.origin == pytest.approx(ORIGIN)
    assert not vol.values().any() and not vol.weights().any()


def test_tsdf_rendered_depth_matches_reference(box_scene, camera, poses):
    scene, _ = box_scene
    vol = hg.TSDFVolume(ORIGIN, SIZE, RES, TRUNC)
    r = ref.TsdfRef(ORIGIN, SIZE, RES, TRUNC)
    for p in poses:
        depth = scene.render_depth(camera, p)
        vol.integrate(depth, camera, p)
        r.integrate(depth, camera, p)
    assert r.weights.max() >= 2 and (r.values < 0).any() and (r.values == 1).any()
    assert_tsdf_match(vol, r)


def test_tsdf_random_depth_with_missing_values(camera, poses, rng):
    vol = hg.TSDFVolume(ORIGIN, SIZE, RES, TRUNC)
    r = ref.TsdfRef(ORIGIN, SIZE, RES, TRUNC)
    for p in poses[:4]:
        depth = rng.uniform(0.4, 1.0, size=(camera.height, camera.width)).astype(np.float32)
        depth[rng.random(depth.shape) < 0.1] = 0.0
        depth[rng.random(depth.shape) < 0.05] = np.nan
        depth[rng.random(depth.shape) < 0.05] = -1.0
        depth[rng.random(depth.shape) < 0.02] = np.inf
        vol.integrate(depth, camera, p)
        r.integrate(depth, camera, p)
    assert_tsdf_match(vol, r)


def test_tsdf_copy_and_reset(box_scene, camera, poses):
    scene, _ = box_scene
    vol = hg.TSDFVolume(ORIGIN, SIZE, RES, TRUNC)
    vol.integrate(scene.render_depth(camera, poses[0]), camera, poses[0])
    c = vol.copy()
    c.integrate(scene.render_depth(camera, poses[1]), camera, poses[1])
    assert c.weights().sum() > vol.weights().sum()
    c.reset()
    assert not c.weights().any() and not c.values().any()
    assert vol.weights().any()


def test_tsdf_random_poses(rng):
    cam = hg.PinholeCamera(23, 17, 30.0, 35.0, 9.7, 8.2)
    vol = hg.TSDFVolume(ORIGIN, SIZE, RES, TRUNC)
    r = ref.TsdfRef(ORIGIN, SIZE, RES, TRUNC)
    centre = np.array(ORIGIN) + SIZE / 2
    for _ in range(5):
        rot = ref.random_rotation(rng)
        pose = ref.pose_from(rot, centre - rot[:, 2] * rng.uniform(0.1, 0.8))
        depth = rng.uniform(0.05, 0.9, size=(cam.height, cam.width)).astype(np.float32)
        vol.integrate(depth, cam, pose)
        r.integrate(depth, cam, pose)
    assert r.weights.sum() > 0
    assert_tsdf_match(vol, r)


def _sphere_tsdf(res=40, size=0.30, radius=0.06, trunc=0.03):
    """A sphere's TSDF as a depth camera leaves it: values in front and up to one
    truncation behind the surface, deeper voxels unobserved (0, weight 0)."""
    from heapgrasp.geometry.grid import GridFrame

    frame = GridFrame((-size / 2, -size / 2, 0.0), size, res)
    centre = np.array([0.01, -0.02, 0.12])
    sdf = np.linalg.norm(frame.centers(np.argwhere(np.ones((res,) * 3))) - centre, axis=1)
    sdf = (sdf - radius).reshape((res,) * 3)
    weights = (sdf >= -trunc).astype(np.float32)
    values = np.where(weights > 0, np.minimum(1.0, sdf / trunc), 0.0).astype(np.float32)
    return frame, centre, radius, values, weights


def test_tsdf_surface_lies_on_the_surface_with_outward_normals():
    from heapgrasp.perception.depth import tsdf_surface

    frame, centre, radius, values, weights = _sphere_tsdf()
    points, normals = tsdf_surface(values, frame, weights)
    assert len(points) > 500
    rel = points - centre
    dist = np.linalg.norm(rel, axis=1)
    np.testing.assert_allclose(dist, radius, atol=5e-4)  # linear interpolation of a sphere
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9)
    cos = np.einsum("ij,ij->i", normals, rel / dist[:, None])
    assert cos.min() > np.cos(np.radians(6))  # outward, along the radius
    # without weights, 0 (the TSDF's initial value) marks what was never observed
    same, _ = tsdf_surface(values, frame)
    np.testing.assert_allclose(same, points)


def test_tsdf_surface_skips_crossings_into_unobserved_voxels():
    from heapgrasp.perception.depth import tsdf_surface

    frame, _, _, values, weights = _sphere_tsdf()
    # the value behind the surface unobserved: a sign change into it is no surface
    behind = values < 0
    values[behind], weights[behind] = -1.0, 0.0
    points, normals = tsdf_surface(values, frame, weights)
    assert points.shape == normals.shape == (0, 3)
    with pytest.raises(ValueError, match="values must be"):
        tsdf_surface(values[:-1], frame)
    with pytest.raises(ValueError, match="weights must be"):
        tsdf_surface(values, frame, weights[:-1])
