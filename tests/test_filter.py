"""Gaussian smoothing, maximum filter and NMS against NumPy and SciPy."""

from __future__ import annotations

import heapgrasp as hg
import numpy as np
import pytest
import reference as ref
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage


@pytest.mark.parametrize("sigma", [0.0, 0.3, 0.5, 1.0, 1.7, 3.0])
@pytest.mark.parametrize("r", [1, 5, 11])
def test_gaussian_matches_reference_and_scipy(rng, sigma, r):
    vol = rng.normal(size=(r, r, r)).astype(np.float32)
    out = hg.gaussian_filter3d(vol, sigma)
    assert out.dtype == np.float32 and out.shape == vol.shape
    np.testing.assert_allclose(out, ref.gaussian_filter3d(vol, sigma), rtol=1e-5, atol=1e-6)
    sp = ndimage.gaussian_filter(vol, sigma, mode="nearest", truncate=4.0)
    np.testing.assert_allclose(out, sp, rtol=1e-5, atol=1e-6)


def test_gaussian_zero_sigma_is_copy(rng):
    vol = rng.normal(size=(4, 4, 4)).astype(np.float32)
    out = hg.gaussian_filter3d(vol, 0.0)
    np.testing.assert_array_equal(out, vol)
    out[0, 0, 0] = 99
    assert vol[0, 0, 0] != 99


def test_gaussian_preserves_constant():
    vol = np.full((6, 6, 6), 0.25, np.float32)
    np.testing.assert_allclose(hg.gaussian_filter3d(vol, 2.0), vol, rtol=1e-6)


@pytest.mark.parametrize("window", [1, 2, 3, 4, 5, 7, 20])
def test_maximum_filter_matches_reference_and_scipy(rng, window):
    r = 9
    vol = rng.normal(size=(r, r, r)).astype(np.float32)
    out = hg.maximum_filter3d(vol, window)
    assert out.dtype == np.float32 and out.shape == vol.shape
    np.testing.assert_array_equal(out, ref.maximum_filter3d(vol, window))
    np.testing.assert_array_equal(out, ndimage.maximum_filter(vol, size=window, mode="reflect"))


def test_maximum_filter_default_window_is_4(rng):
    vol = rng.normal(size=(6, 6, 6)).astype(np.float32)
    np.testing.assert_array_equal(hg.maximum_filter3d(vol), ref.maximum_filter3d(vol, 4))


def test_maximum_filter_ignores_nan(rng):
    vol = rng.normal(size=(5, 5, 5)).astype(np.float32)
    vol[rng.random(vol.shape) < 0.3] = np.nan
    vol[0:2, 0:2, 0:2] = np.nan  # window of [0,0,0] (offsets -1..1 at w=3) has [2,*] etc.
    out = hg.maximum_filter3d(vol, 3)
    np.testing.assert_array_equal(out, ref.maximum_filter3d(vol, 3))
    allnan = np.full((3, 3, 3), np.nan, np.float32)
    assert np.isnan(hg.maximum_filter3d(allnan, 2)).all()


def test_nms_docs_example():
    v = np.zeros((4, 4, 4), np.float32)
    v[1, 2, 3] = 0.9
    v[3, 0, 0] = 0.7
    out = hg.nms3d(v, 0.5, 3)
    assert out.dtype == np.int64
    np.testing.assert_array_equal(out, [[1, 2, 3], [3, 0, 0]])


@pytest.mark.parametrize("window", [1, 2, 3, 4, 6])
def test_nms_matches_bruteforce(rng, window):
    r = 10
    vol = hg.gaussian_filter3d(rng.random((r, r, r)).astype(np.float32), 1.0)
    out = hg.nms3d(vol, 0.45, window)
    expected = ref.nms3d(vol, 0.45, window)
    assert len(expected) > 0
    np.testing.assert_array_equal(out, expected)


def test_nms_plateaus_ties_and_nan():
    vol = np.zeros((6, 6, 6), np.float32)
    vol[1:3, 1:3, 1] = 0.5  # plateau: all kept, in flat order
    vol[5, 5, 5] = 0.8
    vol[4, 0, 0] = np.nan
    vol[0, 5, 0] = -0.0
    out = hg.nms3d(vol, -1.0, 2)
    np.testing.assert_array_equal(out, ref.nms3d(vol, -1.0, 2))
    assert tuple(out[0]) == (5, 5, 5)
    assert not any(tuple(p) == (4, 0, 0) for p in out)
    empty = hg.nms3d(vol, 2.0)
    assert empty.shape == (0, 3) and empty.dtype == np.int64


@settings(max_examples=40, deadline=None)
@given(
    r=st.integers(1, 7),
    window=st.integers(1, 9),
    seed=st.integers(0, 2**32 - 1),
    levels=st.integers(2, 6),
    thr=st.floats(-1, 1),
)
def test_nms_and_max_filter_property(r, window, seed, levels, thr):
    g = np.random.default_rng(seed)
    # few distinct values -> many ties and plateaus
    vol = (g.integers(0, levels, size=(r, r, r)) / levels).astype(np.float32)
    np.testing.assert_array_equal(
        hg.maximum_filter3d(vol, window), ndimage.maximum_filter(vol, size=window, mode="reflect")
    )
    np.testing.assert_array_equal(hg.nms3d(vol, thr, window), ref.nms3d(vol, thr, window))


@settings(max_examples=30, deadline=None)
@given(r=st.integers(1, 8), sigma=st.floats(0.05, 4.0), seed=st.integers(0, 2**32 - 1))
def test_gaussian_property(r, sigma, seed):
    vol = np.random.default_rng(seed).normal(size=(r, r, r)).astype(np.float32)
    out = hg.gaussian_filter3d(vol, sigma)
    sp = ndimage.gaussian_filter(vol, sigma, mode="nearest", truncate=4.0)
    np.testing.assert_allclose(out, sp, rtol=1e-5, atol=1e-6)


def test_large_volume_filters(rng):
    """Volumes big enough for the multi-threaded slab path."""
    vol = rng.random((40, 40, 40)).astype(np.float32)
    np.testing.assert_allclose(
        hg.gaussian_filter3d(vol, 1.5),
        ndimage.gaussian_filter(vol, 1.5, mode="nearest"),
        rtol=1e-5,
        atol=1e-6,
    )
    for w in (3, 4, 9):
        np.testing.assert_array_equal(
            hg.maximum_filter3d(vol, w), ndimage.maximum_filter(vol, size=w, mode="reflect")
        )
    sm = hg.gaussian_filter3d(vol, 1.0)
    mx = ndimage.maximum_filter(sm, size=4, mode="reflect")
    keep = np.flatnonzero((sm == mx).ravel() & (sm.ravel() >= 0.5))
    keep = keep[np.lexsort((keep, -sm.ravel()[keep]))]
    np.testing.assert_array_equal(hg.nms3d(sm, 0.5), np.stack(np.unravel_index(keep, sm.shape), -1))
