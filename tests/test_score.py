"""score_views against its definition (HEAPGrasp eq. 14)."""

from __future__ import annotations

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from conftest import ring_poses
from heapgrasp.planning.views import target_region

ORIGIN, SIZE = (-0.15, -0.15, 0.0), 0.30


def observed_grid(scene, camera, poses, res=20):
    g = hg.OccupancyGrid(ORIGIN, SIZE, res)
    masks = np.stack([scene.render_mask(camera, p) for p in poses])
    g.integrate_many(masks, camera, poses)
    return g


def score_by_definition(grid, scene, camera, traj, lam):
    before = grid.count_high_confidence(lam)
    g = grid.copy()
    masks = np.stack([scene.render_mask(camera, p) for p in traj])
    g.integrate_many(masks, camera, traj)
    after = g.count_high_confidence(lam)
    # the kernel evaluates eq. 14 in f32 (1 - f32(after) / f32(before))
    return np.float32(1.0) - np.float32(after) / np.float32(before)


def trajectories(k, m, seed):
    g = np.random.default_rng(seed)
    out = []
    for _ in range(k):
        start = g.uniform(0, 2 * np.pi)
        span = g.uniform(0.2, 2.0)
        eyes = []
        for t in np.linspace(0, 1, m):
            a = start + span * t
            eyes.append((0.5 * np.cos(a), 0.5 * np.sin(a), g.uniform(0.15, 0.6)))
        out.append(
            np.ascontiguousarray(
                np.stack(
                    [ref.look_at(e, (g.normal() * 0.02, g.normal() * 0.02, 0.08)) for e in eyes]
                )
            )
        )
    return out


@pytest.mark.parametrize("lam", [0.9, 1.0, 0.6])
def test_scores_equal_definition(box_scene, camera, lam):
    scene, _ = box_scene
    seen = ring_poses(2, radius=0.5, height=0.3, target=(0, 0, 0.08), jitter=0.5, seed=1)
    grid = observed_grid(scene, camera, seen)
    assert grid.count_high_confidence(lam) > 0
    trajs = trajectories(12, 4, seed=int(lam * 10))
    scores = hg.score_views(grid, scene, camera, trajs, lam=lam)
    assert scores.dtype == np.float32 and scores.shape == (12,)
    expected = np.array([score_by_definition(grid, scene, camera, t, lam) for t in trajs])
    np.testing.assert_array_equal(scores, expected)
    # scores can be negative: voxels never seen before can become high-confidence
    assert np.all(scores <= 1)
    assert np.ptp(scores) > 0


def test_default_lambda_is_0_9(box_scene, camera):
    scene, _ = box_scene
    grid = observed_grid(scene, camera, ring_poses(2, jitter=0.5, seed=2))
    trajs = trajectories(4, 3, seed=5)
    np.testing.assert_array_equal(
        hg.score_views(grid, scene, camera, trajs),
        hg.score_views(grid, scene, camera, trajs, lam=0.9),
    )


def test_repeat_view_scores_zero_and_unseen_side_ranks_higher(box_scene, camera):
    scene, _ = box_scene
    seen_pose = ref.look_at((0.45, 0.05, 0.35), (0.0, 0.0, 0.07))
    grid = observed_grid(scene, camera, seen_pose[None])
    other = ref.look_at((-0.45, -0.08, 0.3), (0.0, 0.0, 0.07))
    side = ref.look_at((0.03, 0.47, 0.25), (0.0, 0.0, 0.07))
    trajs = [
        seen_pose[None].copy(),
        np.stack([seen_pose, seen_pose]),
        other[None].copy(),
        side[None].copy(),
    ]
    s = hg.score_views(grid, scene, camera, trajs)
    assert s[0] == 0 and s[1] == 0
    assert s[2] > s[0] and s[3] > s[0]
    # a trajectory ending at a new view scores at least as much as that view alone
    s2 = hg.score_views(grid, scene, camera, [np.stack([seen_pose, side])])
    assert s2[0] >= s[3] - 1e-6


def test_empty_grid_scores_zero(box_scene, camera):
    scene, _ = box_scene
    grid = hg.OccupancyGrid(ORIGIN, SIZE, 10)
    s = hg.score_views(grid, scene, camera, trajectories(5, 2, seed=3))
    assert s.dtype == np.float32 and s.shape == (5,) and not s.any()
    assert hg.score_views(grid, scene, camera, []).shape == (0,)


def test_many_candidates_shape(box_scene, camera):
    scene, _ = box_scene
    grid = observed_grid(scene, camera, ring_poses(3, radius=0.5, jitter=0.5, seed=4))
    g = np.random.default_rng(8)
    base = trajectories(40, 3, seed=9)
    trajs = [base[g.integers(len(base))] for _ in range(800)]
    s = hg.score_views(grid, scene, camera, trajs)
    assert s.shape == (800,) and s.dtype == np.float32
    assert np.all(np.isfinite(s)) and np.all(s <= 1)
    # identical trajectories get identical scores; spot-check against the definition
    for i in g.integers(0, 800, size=3):
        assert s[i] == score_by_definition(grid, scene, camera, trajs[i], 0.9)


def test_score_does_not_modify_grid(box_scene, camera):
    scene, _ = box_scene
    grid = observed_grid(scene, camera, ring_poses(2, jitter=0.5, seed=2))
    before = [a.copy() for a in grid.counts()]
    hg.score_views(grid, scene, camera, trajectories(6, 3, seed=1), lam=0.9)
    for a, b in zip(grid.counts(), before, strict=True):
        np.testing.assert_array_equal(a, b)


def high_confidence_in(grid, region, lam):
    return int(((grid.occupancy() >= lam) & (grid.counts()[0] > 0) & region).sum())


def test_region_restricts_both_counts(box_scene, camera):
    scene, _ = box_scene
    grid = observed_grid(scene, camera, ring_poses(2, radius=0.5, jitter=0.5, seed=1))
    trajs = trajectories(10, 3, seed=11)
    r = grid.resolution
    everywhere = np.ones((r, r, r), dtype=bool)
    np.testing.assert_array_equal(
        hg.score_views(grid, scene, camera, trajs, region=everywhere),
        hg.score_views(grid, scene, camera, trajs),
    )
    # the column over the first box (centred near (0.03, -0.02))
    column = target_region(grid, (0.03, -0.02, 0.0), 0.05)
    assert 0 < column.sum() < column.size
    before = high_confidence_in(grid, column, 0.9)
    assert before > 0
    scores = hg.score_views(grid, scene, camera, trajs, region=column.astype(np.uint8))
    for t, s in zip(trajs, scores, strict=True):
        g = grid.copy()
        g.integrate_many(np.stack([scene.render_mask(camera, p) for p in t]), camera, t)
        expected = np.float32(1) - np.float32(high_confidence_in(g, column, 0.9)) / np.float32(
            before
        )
        assert s == pytest.approx(expected, abs=1e-6)
    assert not np.array_equal(scores, hg.score_views(grid, scene, camera, trajs))


def test_region_without_measured_volume_scores_zero_and_bad_regions_raise(box_scene, camera):
    scene, _ = box_scene
    grid = observed_grid(scene, camera, ring_poses(2, jitter=0.5, seed=2))
    trajs = trajectories(3, 2, seed=4)
    r = grid.resolution
    assert not hg.score_views(grid, scene, camera, trajs, region=np.zeros((r,) * 3, bool)).any()
    with pytest.raises(hg.ShapeError, match="region"):
        hg.score_views(grid, scene, camera, trajs, region=np.ones((r, r, r - 1), bool))
    with pytest.raises(hg.ShapeError, match="region"):
        hg.score_views(grid, scene, camera, trajs, region=np.ones((r, r, r), np.float32))


@pytest.mark.parametrize("big", [1 << 24, 2**32 - 1])
def test_counts_far_beyond_any_trajectory_score_as_their_definition(box_scene, camera, big):
    # A remembered grid (the scene memory) carries visible counts of 2**24; from_counts
    # takes any uint32. Scoring must neither overflow nor build a table of that size,
    # and must equal eq. 14 by its definition (counts saturate at 2**32 - 1).
    scene, _ = box_scene
    seen = ring_poses(2, radius=0.5, height=0.3, target=(0, 0, 0.08), jitter=0.5, seed=1)
    fresh = observed_grid(scene, camera, seen)
    seg, vis = fresh.counts()
    carved = (vis > 0) & (seg == 0)
    vis = np.where(carved, np.uint32(big), vis).astype(np.uint32)
    seg = np.where(seg == vis, np.uint32(big) * (seg > 0), seg).astype(np.uint32)
    grid = hg.OccupancyGrid.from_counts(ORIGIN, SIZE, seg, np.maximum(vis, seg))
    assert grid.count_high_confidence(0.9) > 0
    trajs = trajectories(6, 4, seed=3)
    scores = hg.score_views(grid, scene, camera, trajs, lam=0.9)
    want = [score_by_definition(grid, scene, camera, t, 0.9) for t in trajs]
    np.testing.assert_allclose(scores, want, atol=2e-3)
