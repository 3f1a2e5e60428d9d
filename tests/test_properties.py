"""Hypothesis property tests of carving on random cameras, poses, masks and grids."""

from __future__ import annotations

import heapgrasp as hg
import numpy as np
import reference as ref
from hypothesis import given, settings
from hypothesis import strategies as st


@st.composite
def setups(draw, max_frames=4):
    seed = draw(st.integers(0, 2**32 - 1))
    g = np.random.default_rng(seed)
    w = draw(st.integers(8, 64))
    h = draw(st.integers(8, 64))
    fx = draw(st.floats(20, 200))
    fy = draw(st.floats(20, 200))
    cx = draw(st.floats(-0.5 * w, 1.5 * w))
    cy = draw(st.floats(-0.5 * h, 1.5 * h))
    cam = hg.PinholeCamera(w, h, fx, fy, cx, cy)
    res = draw(st.integers(1, 12))
    size = draw(st.floats(0.05, 1.0))
    origin = tuple(g.uniform(-1, 1, size=3))
    n = draw(st.integers(1, max_frames))
    centre = np.asarray(origin) + size / 2
    poses = []
    for _ in range(n):
        rot = ref.random_rotation(g)
        if g.random() < 0.7:  # aimed at the grid from a random distance
            eye = centre - rot[:, 2] * size * g.uniform(0.3, 4.0) + g.normal(size=3) * 0.2 * size
        else:  # anywhere, possibly inside the grid
            eye = centre + g.normal(size=3) * size
        poses.append(ref.pose_from(rot, eye))
    poses = np.ascontiguousarray(np.stack(poses))
    density = draw(st.floats(0, 1))
    masks = g.random((n, h, w)) < density
    return cam, origin, size, res, poses, masks


@settings(max_examples=50, deadline=None)
@given(setups())
def test_counts_match_reference(setup):
    cam, origin, size, res, poses, masks = setup
    grid = hg.OccupancyGrid(origin, size, res)
    grid.integrate_many(masks, cam, poses)
    seg, vis = grid.counts()
    assert np.all(seg <= vis)
    rseg, rvis, tie = ref.sfs_counts(origin, size, res, masks, cam, poses)
    bad = (seg != rseg) | (vis != rvis)
    assert not np.any(bad & ~tie)
    assert np.all(np.abs(vis.astype(np.int64) - rvis) <= len(poses))


@settings(max_examples=40, deadline=None)
@given(setups(max_frames=5), st.booleans())
def test_integrate_many_equals_successive_and_counts_grow(setup, as_uint8):
    cam, origin, size, res, poses, masks = setup
    if as_uint8:
        masks = masks.astype(np.uint8) * 255
    many = hg.OccupancyGrid(origin, size, res)
    many.integrate_many(masks, cam, poses)
    one = hg.OccupancyGrid(origin, size, res)
    prev_s, prev_v = (a.astype(np.int64) for a in one.counts())
    for m, p in zip(masks, poses, strict=True):
        one.integrate(m, cam, p)
        s, v = (a.astype(np.int64) for a in one.counts())
        ds, dv = s - prev_s, v - prev_v
        assert np.all((dv == 0) | (dv == 1))  # visible grows by at most 1 per frame
        assert np.all((ds >= 0) & (ds <= dv))  # segmented only where visible
        prev_s, prev_v = s, v
    for a, b in zip(many.counts(), one.counts(), strict=True):
        np.testing.assert_array_equal(a, b)


@settings(max_examples=30, deadline=None)
@given(setups(max_frames=3), st.floats(0, 1))
def test_high_confidence_definition(setup, lam):
    cam, origin, size, res, poses, masks = setup
    grid = hg.OccupancyGrid(origin, size, res)
    grid.integrate_many(masks, cam, poses)
    seg, vis = grid.counts()
    expected = ref.high_confidence(seg, vis, lam)
    np.testing.assert_array_equal(grid.occupancy(), ref.occupancy(seg, vis))
    np.testing.assert_array_equal(grid.high_confidence(lam), expected)
    assert grid.count_high_confidence(lam) == np.count_nonzero(expected)
    # the empty and full masks bracket every mask
    lo = hg.OccupancyGrid(origin, size, res)
    lo.integrate_many(np.zeros_like(masks), cam, poses)
    hi = hg.OccupancyGrid(origin, size, res)
    hi.integrate_many(np.ones_like(masks), cam, poses)
    assert not lo.counts()[0].any()
    np.testing.assert_array_equal(lo.counts()[1], vis)
    np.testing.assert_array_equal(hi.counts()[0], vis)
