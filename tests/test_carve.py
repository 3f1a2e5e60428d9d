"""Shape-from-Silhouette carving and occupancy against the NumPy reference."""

from __future__ import annotations

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from conftest import GRID_ORIGIN, GRID_SIZE


def random_masks(rng, n, cam, p=0.5):
    return rng.random((n, cam.height, cam.width)) < p


def assert_counts_match(grid, masks, cam, poses):
    seg, vis = grid.counts()
    assert seg.dtype == np.uint32 and vis.dtype == np.uint32
    r = grid.resolution
    assert seg.shape == vis.shape == (r, r, r)
    rseg, rvis, tie = ref.sfs_counts(grid.origin, grid.size, r, masks, cam, poses)
    bad = (seg != rseg) | (vis != rvis)
    assert not np.any(bad & ~tie), f"{np.count_nonzero(bad & ~tie)} non-tie voxels differ"
    # a tie can move a voxel by at most one pixel per frame
    assert np.all(np.abs(vis.astype(np.int64) - rvis) <= len(masks))
    return rseg, rvis, tie


def test_grid_properties():
    g = hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, 12)
    assert g.origin == pytest.approx(GRID_ORIGIN)
    assert g.size == pytest.approx(GRID_SIZE)
    assert g.resolution == 12
    assert g.voxel_size == pytest.approx(GRID_SIZE / 12)
    seg, vis = g.counts()
    assert not seg.any() and not vis.any()
    assert g.count_high_confidence() == 0


@pytest.mark.parametrize("dtype", ["bool", "uint8"])
def test_single_frame_matches_reference(grid, camera, poses, rng, dtype):
    masks = random_masks(rng, 1, camera)
    m = masks[0] if dtype == "bool" else masks[0].astype(np.uint8) * 255
    grid.integrate(m, camera, poses[0])
    _, rvis, tie = assert_counts_match(grid, masks, camera, poses[:1])
    assert rvis.sum() > 100  # the view actually sees the grid
    assert tie.sum() < 0.01 * tie.size


@pytest.mark.parametrize("dtype", ["bool", "uint8"])
def test_many_frames_matches_reference(grid, camera, poses, rng, dtype):
    masks = random_masks(rng, len(poses), camera)
    m = masks if dtype == "bool" else masks.astype(np.uint8) * 255
    grid.integrate_many(m, camera, poses)
    assert_counts_match(grid, masks, camera, poses)


def test_uint8_any_nonzero_is_set(grid, camera, poses, rng):
    masks = rng.integers(0, 4, size=(len(poses), camera.height, camera.width), dtype=np.uint8)
    grid.integrate_many(masks, camera, poses)
    g2 = hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, grid.resolution)
    g2.integrate_many(masks != 0, camera, poses)
    for a, b in zip(grid.counts(), g2.counts(), strict=True):
        np.testing.assert_array_equal(a, b)


def test_integrate_many_equals_successive_integrate(grid, camera, poses, rng):
    masks = random_masks(rng, len(poses), camera)
    g2 = grid.copy()
    grid.integrate_many(masks, camera, poses)
    for m, p in zip(masks, poses, strict=True):
        g2.integrate(m, camera, p)
    for a, b in zip(grid.counts(), g2.counts(), strict=True):
        np.testing.assert_array_equal(a, b)


def test_occupancy_and_high_confidence(grid, camera, poses, rng):
    masks = random_masks(rng, len(poses), camera, p=0.8)
    grid.integrate_many(masks, camera, poses)
    seg, vis = grid.counts()
    occ = grid.occupancy()
    assert occ.dtype == np.float32 and occ.shape == seg.shape
    np.testing.assert_array_equal(occ, ref.occupancy(seg, vis))
    for lam in [0.0, 0.5, 0.8, 0.9, 1.0, 1 / 3]:
        hc = grid.high_confidence(lam)
        assert hc.dtype == np.float32
        expected = ref.high_confidence(seg, vis, lam)
        np.testing.assert_array_equal(hc, expected)
        assert grid.count_high_confidence(lam) == np.count_nonzero(expected)
    assert grid.count_high_confidence() == np.count_nonzero(ref.high_confidence(seg, vis, 0.9))


def test_from_counts_roundtrip(rng):
    r = 7
    vis = rng.integers(0, 20, size=(r, r, r), dtype=np.uint32)
    seg = (vis * rng.random((r, r, r))).astype(np.uint32)
    g = hg.OccupancyGrid.from_counts((0.1, -0.2, 0.3), 0.5, seg, vis)
    assert g.resolution == r
    s2, v2 = g.counts()
    np.testing.assert_array_equal(s2, seg)
    np.testing.assert_array_equal(v2, vis)
    np.testing.assert_array_equal(g.occupancy(), ref.occupancy(seg, vis))
    # lambda compared in f32: occupancy exactly 2/3 is high-confidence for lam = 2/3
    g = hg.OccupancyGrid.from_counts(
        (0, 0, 0), 1.0, np.full((1, 1, 1), 2, np.uint32), np.full((1, 1, 1), 3, np.uint32)
    )
    assert g.count_high_confidence(2 / 3) == 1
    assert g.count_high_confidence(np.nextafter(np.float32(2 / 3), np.float32(1))) == 0


def test_copy_is_independent_and_reset(grid, camera, poses, rng):
    masks = random_masks(rng, 2, camera)
    grid.integrate_many(masks, camera, poses[:2])
    before = [a.copy() for a in grid.counts()]
    c = grid.copy()
    c.integrate(masks[0], camera, poses[0])
    for a, b in zip(grid.counts(), before, strict=True):
        np.testing.assert_array_equal(a, b)
    assert c.counts()[1].sum() > before[1].sum()
    c.reset()
    assert not c.counts()[0].any() and not c.counts()[1].any()


def test_camera_facing_away_sees_nothing(grid, camera):
    pose = ref.look_at((0, 0, 1.0), (0, 0, 2.0))
    grid.integrate(np.ones((camera.height, camera.width), bool), camera, pose)
    assert not grid.counts()[1].any()


def test_full_mask_full_view_occupancy_one(camera):
    g = hg.OccupancyGrid((-0.05, -0.05, -0.05), 0.1, 6)
    pose = ref.look_at((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0))
    g.integrate(np.ones((camera.height, camera.width), np.uint8), camera, pose)
    seg, vis = g.counts()
    assert (vis == 1).all() and (seg == 1).all()
    assert g.count_high_confidence(1.0) == 6**3


# (resolution, threads) for 3 frames: 66^3 > 2^18 voxels takes the slab path (one x slab
# per thread) whatever the frame count; 48^3 does with more threads than frames, and is
# frame-parallel (private counts per thread, summed) with at most as many.
@pytest.mark.parametrize(
    "res,threads",
    [(66, 2), (66, 4), (48, 4), (48, 3), (48, 1), (66, None)],
    ids=["slabs2", "slabs4", "slabs4-small", "frames3", "one", "auto"],
)
def test_large_grid_matches_reference(camera, poses, rng, res, threads):
    """A grid big enough for the multi-threaded slab path, on explicit thread counts."""
    g = hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, res)
    masks = random_masks(rng, 3, camera)
    g.integrate_many(masks, camera, poses[:3], threads=threads)
    _, rvis, _ = assert_counts_match(g, masks, camera, poses[:3])
    assert np.count_nonzero(rvis) > rvis.size // 10


def test_thread_count_does_not_change_the_counts(camera, poses, rng):
    masks = random_masks(rng, len(poses), camera)
    counts = []
    for threads in [1, 2, 3, 5, 6, 7, 16]:
        g = hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, 20)
        g.integrate_many(masks, camera, poses, threads=threads)
        counts.append(g.counts())
    for seg, vis in counts[1:]:
        np.testing.assert_array_equal(seg, counts[0][0])
        np.testing.assert_array_equal(vis, counts[0][1])


U32_MAX = np.iinfo(np.uint32).max


@pytest.mark.parametrize("threads", [None, 1, 2, 4])
@pytest.mark.parametrize("start", [U32_MAX, U32_MAX - 1, U32_MAX - 4])
def test_counts_saturate_at_the_u32_limit(camera, poses, start, threads):
    """Counts near 2**32 - 1 stop there: occupancy 1 stays 1 rather than wrapping to 0."""
    # Twice the usual cube: the ring of views leaves part of it unseen.
    res, size = 12, 2 * GRID_SIZE
    full = np.full((res, res, res), start, np.uint32)
    g = hg.OccupancyGrid.from_counts(GRID_ORIGIN, size, full, full)
    fresh = hg.OccupancyGrid(GRID_ORIGIN, size, res)
    ones = np.ones((len(poses), camera.height, camera.width), bool)
    for grid in (g, fresh):
        grid.integrate_many(ones, camera, poses, threads=threads)
        grid.integrate(ones[0], camera, poses[0])
    added = fresh.counts()[1].astype(np.int64)
    expected = np.minimum(start + added, U32_MAX)
    assert (added == 0).any() and (expected == U32_MAX).any()
    seg, vis = g.counts()
    np.testing.assert_array_equal(vis, expected)
    np.testing.assert_array_equal(seg, expected)
    np.testing.assert_array_equal(g.occupancy(), np.ones_like(g.occupancy()))
    assert g.count_high_confidence(1.0) == res**3
    # A frame that sees without segmenting: visible stays at the top, segmented never
    # passes it.
    g.integrate(np.zeros((camera.height, camera.width), bool), camera, poses[1])
    seg, vis = g.counts()
    np.testing.assert_array_equal(vis[expected == U32_MAX], U32_MAX)
    assert (seg <= vis).all()
