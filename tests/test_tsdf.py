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
