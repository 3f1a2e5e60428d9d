"""MeshScene rendering against brute-force Moller-Trumbore ray casting."""

from __future__ import annotations

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from conftest import ring_poses


def render_poses():
    close = ring_poses(5, radius=0.3, height=0.25, target=(0.0, 0.0, 0.06), jitter=1.0, seed=3)
    return np.concatenate([close, ring_poses(3, jitter=1.0, seed=11)])


@pytest.mark.parametrize("k", range(8))
def test_render_matches_bruteforce(box_scene, camera, k):
    scene, meshes = box_scene
    pose = render_poses()[k]
    mask = scene.render_mask(camera, pose)
    depth = scene.render_depth(camera, pose)
    labels = scene.render_labels(camera, pose)
    assert mask.dtype == np.bool_ and depth.dtype == np.float32 and labels.dtype == np.uint32
    assert mask.shape == depth.shape == labels.shape == (camera.height, camera.width)
    rmask, rdepth, rlabels, tie = ref.render_bruteforce(meshes, camera, pose)
    assert not tie.any()  # generic poses: no pixel-centre ray grazes an edge
    assert rmask.sum() > 20
    np.testing.assert_array_equal(mask, rmask)
    np.testing.assert_array_equal(labels, rlabels)
    np.testing.assert_array_equal(depth == 0, ~rmask)
    np.testing.assert_allclose(depth, rdepth.astype(np.float32), rtol=2e-6, atol=0)


def test_scene_management(box_scene, camera):
    scene, meshes = box_scene
    ids = [m[0] for m in meshes]
    assert scene.ids() == sorted(ids) and len(scene) == 2 and ids[0] >= 1
    assert scene.triangle_count == 24
    assert all(scene.is_closed(i) for i in ids)
    np.testing.assert_allclose(scene.pose(ids[0]), meshes[0][3], atol=1e-12)
    # moving a mesh changes its render like the reference
    new_pose = ref.pose_from(ref.random_rotation(np.random.default_rng(5)), (0.02, 0.0, 0.05))
    scene.set_pose(ids[0], new_pose)
    np.testing.assert_allclose(scene.pose(ids[0]), new_pose, atol=1e-12)
    pose = render_poses()[0]
    moved = [(ids[0], meshes[0][1], meshes[0][2], new_pose), meshes[1]]
    rmask, _, rlabels, tie = ref.render_bruteforce(moved, camera, pose)
    ok = ~tie
    np.testing.assert_array_equal(scene.render_labels(camera, pose)[ok], rlabels[ok])
    scene.remove(ids[0])
    assert scene.ids() == [ids[1]]
    rmask, _, _, tie = ref.render_bruteforce([meshes[1]], camera, pose)
    np.testing.assert_array_equal(scene.render_mask(camera, pose)[~tie], rmask[~tie])
    new_id = scene.add_mesh(meshes[0][1], meshes[0][2], new_pose)
    assert new_id not in ids  # ids are never reused


def test_open_mesh_not_closed_and_renders():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    scene = hg.MeshScene()
    i = scene.add_mesh(v, np.array([[0, 1, 2]], dtype=np.int32), np.eye(4))
    assert not scene.is_closed(i)
    cam = hg.PinholeCamera(16, 12, 20.0, 20.0, 7.3, 5.4)
    pose = ref.look_at((0.3, 0.3, -1.0), (0.31, 0.29, 0.0), up=(0, 1, 0))
    m = scene.render_mask(cam, pose)
    rmask, _, _, tie = ref.render_bruteforce([(i, v, np.array([[0, 1, 2]]), np.eye(4))], cam, pose)
    np.testing.assert_array_equal(m[~tie], rmask[~tie])
    # seen from the other side too (no back-face culling of open meshes)
    pose = ref.look_at((0.3, 0.3, 1.0), (0.31, 0.29, 0.0), up=(0, 1, 0))
    rmask, _, _, tie = ref.render_bruteforce([(i, v, np.array([[0, 1, 2]]), np.eye(4))], cam, pose)
    np.testing.assert_array_equal(scene.render_mask(cam, pose)[~tie], rmask[~tie])
    assert rmask.any()


def test_cast_ray(box_scene):
    scene, meshes = box_scene
    mid, _, _, pose = meshes[0]
    centre = pose[:3, 3]
    origin = centre + np.array([0.0, 0.0, 1.0])
    hit = scene.cast_ray(origin, [0.0, 0.0, -3.0])  # direction need not be unit
    assert hit is not None
    dist, hid = hit
    assert hid == mid
    _, rd, _, _ = ref.render_bruteforce(
        meshes,
        hg.PinholeCamera(1, 1, 1.0, 1.0, 0.0, 0.0),
        ref.pose_from(np.diag([1.0, -1.0, -1.0]), origin),
    )
    assert dist == pytest.approx(rd[0, 0], abs=1e-5)
    assert scene.cast_ray(origin, [0.0, 0.0, 1.0]) is None
    assert scene.cast_ray((5.0, 5.0, 5.0), (1.0, 0.0, 0.0)) is None


def test_empty_scene_renders_nothing(camera, poses):
    scene = hg.MeshScene()
    assert not scene.render_mask(camera, poses[0]).any()
    assert not scene.render_depth(camera, poses[0]).any()
    assert not scene.render_labels(camera, poses[0]).any()


def test_contour_fill_equals_faces_on_procedural_objects(tmp_path):
    """Masks of closed meshes are filled from their contours (core `raster::contour`).

    The labels are rasterised face by face, so ``labels > 0`` is the reference mask; on
    the simulator's own objects (bottles, cups, bowls, ...) at random poses and views
    the two must agree pixel for pixel.
    """
    from heapgrasp.geometry.motion import look_at
    from heapgrasp.sim.mesh_files import load_mesh
    from heapgrasp.sim.procedural import generate_procedural

    rng = np.random.default_rng(5)
    models = generate_procedural(tmp_path, count_per_kind=1, seed=2)
    scene = hg.MeshScene()
    for k, m in enumerate(models):
        v, f = load_mesh(m.visual_mesh)
        rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        pose = np.eye(4)
        pose[:3, :3] = rot * np.sign(np.linalg.det(rot))
        pose[:3, 3] = [0.08 + 0.07 * (k % 3), 0.08 + 0.07 * (k // 3), 0.04]
        scene.add_mesh(v, f, pose)
    closed = [scene.is_closed(i) for i in scene.ids()]
    assert sum(closed) >= 3, "the procedural objects should be closed meshes"
    camera = hg.PinholeCamera(320, 240, 300.0, 300.0, 159.5, 119.5)
    covered = 0
    for _ in range(40):
        phi, theta, r = rng.uniform(0, 2 * np.pi), rng.uniform(0, 1.1), rng.uniform(0.25, 0.6)
        eye = np.array([0.15, 0.15, 0.0]) + r * np.array(
            [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
        )
        pose = look_at(eye, (0.15, 0.15, 0.05))
        mask = scene.render_mask(camera, pose)
        np.testing.assert_array_equal(mask, scene.render_labels(camera, pose) > 0)
        covered += int(mask.sum())
    assert covered > 40 * 1000
