"""Roof trimming of the silhouette hull (heapgrasp.perception.roofs)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from box_scenes import box_scene
from fake_robot import FrameMasks, MaskedFrame
from heapgrasp import OccupancyGrid, PinholeCamera
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.motion import look_at
from heapgrasp.perception.roofs import SilhouetteView, column_heights, keep_silhouettes, trim_roofs
from heapgrasp.perception.segmenters import IdealSegmenter
from heapgrasp.perception.silhouette import SilhouettePerception

MASKS = IdealSegmenter(FrameMasks())


V = 0.0075  # voxel size of Table I's grid (0.30 m / 40)


def box_with_tent(r: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """A 6 × 6 × 6 box with a tent roof along x, as carved from two opposite sides; and
    the box alone."""
    box = np.zeros((r, r, r), dtype=np.float32)
    box[5:11, 5:11, :6] = 1.0
    hull = box.copy()
    for i in range(5, 11):
        ridge = min(i - 5, 10 - i)  # 0 at the eaves, 2 at the ridge
        hull[i, 5:11, 6 : 6 + 2 * ridge] = 1.0
    return hull, box


def test_column_heights() -> None:
    occ = np.zeros((4, 4, 5), dtype=bool)
    occ[1, 2, :3] = True
    occ[3, 0, 4] = True  # a floating voxel counts up to its layer
    h = column_heights(occ)
    assert h.shape == (4, 4)
    assert h[1, 2] == 3 and h[3, 0] == 5 and h.sum() == 8
    with pytest.raises(ValueError, match="3-D"):
        column_heights(np.zeros((4, 4), dtype=bool))


def test_a_tent_roof_is_trimmed_to_the_box_below() -> None:
    hull, box = box_with_tent()
    assert hull.sum() > box.sum()
    np.testing.assert_array_equal(trim_roofs(hull, V, 0.0225), box)


def test_flat_tops_and_narrow_objects_keep_their_height() -> None:
    hull, box = box_with_tent()
    tall = np.zeros_like(box)
    tall[15:17, 15:17, :14] = 1.0  # 1.5 cm wide, 10.5 cm tall, narrower than the disc
    wide = np.zeros_like(box)
    wide[2:22, 14:22, :4] = 1.0
    for grid in (box, tall, wide, np.maximum(box, tall)):
        np.testing.assert_array_equal(trim_roofs(grid, V, 0.0225), grid)
    # Everything at once: only the roof goes.
    scene = np.maximum(hull, tall)
    np.testing.assert_array_equal(trim_roofs(scene, V, 0.0225), np.maximum(box, tall))


def test_what_it_can_cut_a_narrow_tower_on_a_wider_base() -> None:
    # A neck narrower than the disc on a wider body is cut to the body's height: the
    # documented cost of the prior (a grasp beside it may touch it).
    bottle = np.zeros((24, 24, 24), dtype=np.float32)
    bottle[6:14, 6:14, :8] = 1.0
    bottle[9:11, 9:11, 8:14] = 1.0
    trimmed = trim_roofs(bottle, V, 0.0225)
    assert column_heights(trimmed > 0).max() == 8


def test_values_are_kept_and_small_discs_change_nothing() -> None:
    hull, _ = box_with_tent()
    graded = hull * np.float32(0.95)
    out = trim_roofs(graded, V, 0.0225)
    assert out.dtype == np.float32
    assert set(np.unique(out)) <= {0.0, np.float32(0.95)}
    np.testing.assert_array_equal(trim_roofs(hull, V, 0.003), hull)
    np.testing.assert_array_equal(trim_roofs(hull, V, 0.0), hull)
    assert trim_roofs(hull, V, 0.0) is not hull


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.zeros((4, 4, 5)), V, 0.02), "cubic"),
        ((np.full((4, 4, 4), np.nan), V, 0.02), "NaN"),
        ((np.zeros((4, 4, 4)), 0.0, 0.02), "voxel_size"),
        ((np.zeros((4, 4, 4)), V, -0.01), "radius"),
        ((np.zeros((4, 4, 4)), V, float("inf")), "radius"),
    ],
)
def test_bad_input_names_the_value(args: tuple[object, ...], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        trim_roofs(*args)  # type: ignore[arg-type]


def test_perception_trims_the_grasp_input_only_when_asked() -> None:
    frame = GridFrame((0.0, 0.0, 0.0), 0.18, 24)
    with pytest.raises(ValueError, match="roof_radius"):
        SilhouettePerception(frame, MASKS, roof_radius=-1.0)
    hull, box = box_with_tent()
    # Counts as if every frame had seen every voxel and segmented the hull.
    visible = np.full(hull.shape, 10, dtype=np.uint32)
    segmented = (hull * 10).astype(np.uint32)
    grid = OccupancyGrid.from_counts(frame.origin, frame.size, segmented, visible)
    plain = SilhouettePerception(frame, MASKS)
    trimmed = SilhouettePerception(frame, MASKS, roof_radius=0.0225)
    plain.grid = grid
    trimmed.grid = grid.copy()
    np.testing.assert_array_equal(plain.grasp_input(), hull)
    np.testing.assert_array_equal(trimmed.grasp_input(), box)
    # the grid itself (what the view scorer counts) keeps the roof
    assert trimmed.grid.count_high_confidence(0.9) == int(hull.sum())


# --------------------------------------------------------------- keep_silhouettes
R_GRID = 40
FRAME = GridFrame((-0.15, -0.15, 0.0), 0.30, R_GRID)


def _carve(
    boxes: list[tuple[tuple[float, float, float], tuple[float, float, float]]],
) -> tuple[np.ndarray, list[SilhouetteView]]:
    """Carves axis-aligned boxes ``(centre, extents)`` standing in the grid from 8 views
    around them at θ_max = 36° (Table I); returns ``Ŝ≥0.9`` and the views."""
    scene = box_scene(boxes)
    camera = PinholeCamera(320, 240, 270.0, 270.0, 159.5, 119.5)
    grid = OccupancyGrid(FRAME.origin, FRAME.size, FRAME.resolution)
    views = []
    for k in range(8):
        phi, theta = 2 * math.pi * k / 8, math.radians(36.0)
        eye = 0.33 * np.array(
            [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
        )
        pose = look_at(eye, (0.0, 0.0, 0.0))
        mask = scene.render_mask(camera, pose)
        grid.integrate(mask, camera, pose)
        views.append(SilhouetteView(camera, pose, mask))
    return grid.high_confidence(0.9), views


def _top(grid: np.ndarray, lo: tuple[int, int], hi: tuple[int, int]) -> int:
    """Highest column height (layers) over the cells ``lo .. hi`` (exclusive)."""
    return int(column_heights(grid[lo[0] : hi[0], lo[1] : hi[1]] > 0).max())


def test_a_roof_stays_trimmed_since_the_object_below_explains_it() -> None:
    # A 6 x 6 x 4.5 cm box (6 layers, columns 16-23): 8 views at 36° leave a roof on it.
    full, views = _carve([((0.0, 0.0, 0.0225), (0.06, 0.06, 0.045))])
    near = ((12, 12), (28, 28))
    assert _top(full, *near) >= 9
    trimmed = trim_roofs(full, V, 0.0225)
    assert _top(trimmed, *near) == 6
    assert (column_heights(trimmed[16:24, 16:24] > 0) < 6).any()  # and its edges cut
    kept = keep_silhouettes(full, trimmed, FRAME.origin, V, views)
    assert set(np.unique(kept)) <= set(np.unique(full))
    assert ((kept > 0) >= (trimmed > 0)).all() and ((kept > 0) <= (full > 0)).all()
    # The edges are back, the roof stays off.
    np.testing.assert_array_equal(column_heights(kept[16:24, 16:24] > 0), 6)
    assert _top(kept, *near) == 6


def test_a_real_part_that_trimming_cut_is_put_back() -> None:
    # A 1.5 cm post, 12 cm tall, against the side of a 6 x 6 x 4.5 cm box: in the merged
    # hull the post is narrower than the disc and higher than what is around it.
    full, views = _carve(
        [((0.0, 0.0, 0.0225), (0.06, 0.06, 0.045)), ((0.0375, 0.0, 0.06), (0.015, 0.015, 0.12))]
    )
    post = ((23, 18), (27, 22))  # the post's columns
    assert _top(full, *post) >= 16
    trimmed = trim_roofs(full, V, 0.0225)
    assert _top(trimmed, *post) <= 8  # cut down to the box
    kept = keep_silhouettes(full, trimmed, FRAME.origin, V, views)
    assert _top(kept, *post) >= 15  # the post is back, to within a voxel of 12 cm
    # ... and the box's roof stays off: a lip of a voxel or two at some of its eaves.
    box = column_heights(kept[16:22, 16:24] > 0)
    assert box.max() <= 8 and box.mean() <= 6.5


def test_keep_silhouettes_without_views_or_cuts_returns_the_trimmed_grid() -> None:
    full, views = _carve([((0.0, 0.0, 0.0225), (0.06, 0.06, 0.045))])
    trimmed = trim_roofs(full, V, 0.0225)
    np.testing.assert_array_equal(keep_silhouettes(full, trimmed, FRAME.origin, V, []), trimmed)
    np.testing.assert_array_equal(keep_silhouettes(full, full, FRAME.origin, V, views), full)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"full": np.zeros((4, 4, 4))}, "full and trimmed"),
        ({"origin": (0.0, 0.0)}, "origin"),
        ({"voxel_size": -1.0}, "voxel_size"),
    ],
)
def test_keep_silhouettes_bad_input_names_the_value(kwargs: dict[str, object], match: str) -> None:
    grid = np.zeros((R_GRID,) * 3, dtype=np.float32)
    args: dict[str, object] = {
        "full": grid,
        "trimmed": grid,
        "origin": FRAME.origin,
        "voxel_size": V,
        "views": [],
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        keep_silhouettes(**args)  # type: ignore[arg-type]


def test_a_view_with_a_mask_of_the_wrong_size_is_refused() -> None:
    camera = PinholeCamera(32, 24, 27.0, 27.0, 15.5, 11.5)
    with pytest.raises(ValueError, match="mask must have shape"):
        SilhouetteView(camera, np.eye(4), np.zeros((32, 24), dtype=bool))
    with pytest.raises(ValueError, match="cam2world"):
        SilhouetteView(camera, np.eye(3), np.zeros((24, 32), dtype=bool))


def test_perception_keeps_what_the_silhouettes_show() -> None:
    with pytest.raises(ValueError, match="silhouette_views"):
        SilhouettePerception(FRAME, MASKS, roof_radius=0.0225, silhouette_views=-2)
    boxes = [((0.0, 0.0, 0.0225), (0.06, 0.06, 0.045)), ((0.0375, 0.0, 0.06), (0.015, 0.015, 0.12))]
    full, views = _carve(boxes)
    spec = CameraSpec()
    frames = [MaskedFrame(cam2world=v.cam2world, camera=spec, mask=v.mask) for v in views]
    checked = SilhouettePerception(FRAME, MASKS, roof_radius=0.0225)
    unchecked = SilhouettePerception(FRAME, MASKS, roof_radius=0.0225, silhouette_views=0)
    for perception in (checked, unchecked):
        perception.update(frames)
        np.testing.assert_array_equal(perception.grid.high_confidence(0.9), full)
    trimmed = trim_roofs(full, V, 0.0225)
    np.testing.assert_array_equal(unchecked.grasp_input(), trimmed)
    assert unchecked.views == []  # nothing stored when nothing is checked
    np.testing.assert_array_equal(
        checked.grasp_input(), keep_silhouettes(full, trimmed, FRAME.origin, V, views)
    )
    post = ((23, 18), (27, 22))
    assert _top(checked.grasp_input(), *post) >= 15
    # a subset of the frames still sees the post; a new phase forgets them all
    few = SilhouettePerception(FRAME, MASKS, roof_radius=0.0225, silhouette_views=3)
    few.update(frames)
    assert len(few.views) == 8
    assert _top(few.grasp_input(), *post) > _top(trimmed, *post)
    few.reset()
    assert few.views == [] and few.frames_seen == 0


def test_painting_boxes_equals_painting_them_one_by_one() -> None:
    from reference_roofs import _paint

    rng = np.random.default_rng(7)
    h, w = 24, 32
    n = 60
    u0 = rng.integers(-2, w + 2, n)
    v0 = rng.integers(-2, h + 2, n)
    u1 = np.minimum(u0 + rng.integers(-2, 8, n), w - 1)  # some empty boxes
    v1 = np.minimum(v0 + rng.integers(-2, 8, n), h - 1)
    u0, v0 = np.maximum(u0, 0), np.maximum(v0, 0)
    ok = rng.random(n) < 0.8
    for value in (True, False):
        start = rng.random((h, w)) < 0.5
        want = start.copy()
        for i in np.flatnonzero(ok):
            if u1[i] >= u0[i] and v1[i] >= v0[i]:
                want[v0[i] : v1[i] + 1, u0[i] : u1[i] + 1] = value
        got = _paint(start.copy(), (u0, u1, v0, v1, ok), value=value)
        np.testing.assert_array_equal(got, want)
        assert (got != start).any()


def _random_hull_case(
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, list[SilhouetteView]]:
    """A random pile of boxes carved from views around it, its hull and the hull with
    roofs trimmed."""
    boxes = []
    for _ in range(int(rng.integers(1, 5))):
        ext = rng.uniform(0.01, 0.07, 3)
        centre = (*rng.uniform(-0.06, 0.06, 2), ext[2] / 2 + rng.uniform(0.0, 0.03))
        boxes.append((tuple(centre), tuple(ext)))
    scene = box_scene(boxes, rng.uniform(0.0, math.pi, len(boxes)))
    camera = PinholeCamera(160, 120, 135.0, 140.0, 79.5, 59.5)
    grid = OccupancyGrid(FRAME.origin, FRAME.size, FRAME.resolution)
    views = []
    for _ in range(int(rng.integers(2, 9))):
        phi, theta = rng.uniform(0, 2 * math.pi), rng.uniform(0.0, math.radians(36.0))
        r = rng.uniform(0.3, 0.6)
        eye = r * np.array(
            [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
        )
        pose = look_at(eye, (*rng.uniform(-0.03, 0.03, 2), 0.0))
        mask = scene.render_mask(camera, pose)
        grid.integrate(mask, camera, pose)
        views.append(SilhouetteView(camera, pose, mask))
    full = grid.high_confidence(0.9)
    return full, trim_roofs(full, V, float(rng.uniform(0.01, 0.04))), views


def test_the_core_check_equals_the_numpy_reference() -> None:
    # The check moved to the Rust core; its NumPy original is the oracle, voxel for
    # voxel, on random piles (roofs trimmed with random discs, views in random order).
    import reference_roofs

    rng = np.random.default_rng(2026)
    restored = 0
    for case in range(24):
        full, trimmed, views = _random_hull_case(rng)
        if case % 3 == 0:
            views = views[::-1]
        got = keep_silhouettes(full, trimmed, FRAME.origin, V, views)
        want = reference_roofs.keep_silhouettes(full, trimmed, FRAME.origin, V, views)
        np.testing.assert_array_equal(got, want, err_msg=f"case {case}")
        restored += int(((got > 0) & ~(trimmed > 0)).sum())
    assert restored > 0  # the cases do restore voxels, not only keep the trimmed grid


def test_the_core_check_refuses_a_bad_view() -> None:
    full, views = _carve([((0.0, 0.0, 0.0225), (0.06, 0.06, 0.045))])
    trimmed = trim_roofs(full, V, 0.0225)
    sheared = views[0].cam2world.copy()
    sheared[0, 1] += 0.1
    bad = SilhouetteView(views[0].camera, sheared, views[0].mask)
    with pytest.raises(ValueError, match="poses"):
        keep_silhouettes(full, trimmed, FRAME.origin, V, [views[1], bad])


def test_the_native_check_names_the_bad_argument() -> None:
    from heapgrasp import ShapeError, _core

    camera = PinholeCamera(8, 6, 5.0, 5.0, 3.5, 2.5)
    grid = np.zeros((4, 4, 4), dtype=bool)
    args: dict[str, object] = {
        "full": grid,
        "trimmed": grid,
        "origin": (0.0, 0.0, 0.0),
        "voxel_size": 0.01,
        "cameras": [camera],
        "poses": np.eye(4)[None].copy(),
        "masks": [np.zeros((6, 8), dtype=bool)],
    }
    assert not _core.keep_silhouettes(**args).any()  # type: ignore[arg-type]
    for bad, match in [
        ({"masks": [np.zeros((8, 6), dtype=bool)]}, r"masks\[0\]: expected shape \(6, 8\)"),
        ({"masks": []}, "one entry per view"),
        ({"trimmed": np.zeros((4, 4, 5), dtype=bool)}, r"trimmed: expected shape \(4, 4, 4\)"),
        ({"full": np.zeros((4, 4, 4), dtype=np.float32)}, "full: expected dtype bool"),
    ]:
        with pytest.raises(ShapeError, match=match):
            _core.keep_silhouettes(**{**args, **bad})  # type: ignore[arg-type]


def _inside_every_silhouette(points: np.ndarray, views: list[SilhouetteView]) -> np.ndarray:
    """``(N,)`` True for the world points that project inside every view's mask."""
    inside = np.ones(len(points), dtype=bool)
    for view in views:
        world2cam = np.linalg.inv(view.cam2world)
        p = points @ world2cam[:3, :3].T + world2cam[:3, 3]
        cam = view.camera
        u = np.rint(cam.fx * p[:, 0] / p[:, 2] + cam.cx).astype(int)
        v = np.rint(cam.fy * p[:, 1] / p[:, 2] + cam.cy).astype(int)
        seen = (p[:, 2] > 0) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
        hit = np.zeros(len(points), dtype=bool)
        hit[seen] = view.mask[v[seen], u[seen]]
        inside &= hit
    return inside


def test_the_silhouettes_carved_finer_around_a_point_measure_the_hull_closer() -> None:
    # A 5.5 cm box: carved again three times finer from the same silhouettes
    # (local_input), the hull's width is measured within a fine voxel of the visual
    # hull's own (points tested against every silhouette), where the grid's 7.5 mm
    # voxels are off by up to one of theirs; the fine hull still holds the box.
    width = 0.055
    _, views = _carve([((0.0, 0.0, 0.025), (width, 0.10, 0.05))])
    spec = CameraSpec()
    frames = [MaskedFrame(cam2world=v.cam2world, camera=spec, mask=v.mask) for v in views]
    perception = SilhouettePerception(FRAME, MASKS, roof_radius=0.0225)
    perception.update(frames)
    fine, frame = perception.local_input((0.0, 0.0, 0.06), 0.16, 63)
    assert frame.resolution == 63 and frame.origin[2] == 0.0  # kept above the table
    occ = fine > 0
    vf = frame.voxel_size
    k = int(0.02 / vf)
    z = frame.origin[2] + (k + 0.5) * vf
    xs = np.flatnonzero(occ[:, :, k].any(axis=1))
    measured = (xs.max() - xs.min() + 1) * vf
    # the visual hull's own width at that height, on a 0.25 mm lattice
    gx, gy = np.meshgrid(np.arange(-0.05, 0.05, 0.00025), np.arange(-0.06, 0.06, 0.0025))
    pts = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])
    hull_x = pts[_inside_every_silhouette(pts, views), 0]
    exact = hull_x.max() - hull_x.min()
    assert abs(measured - exact) <= vf
    assert exact >= width
    # the box is inside, but for what the roof trimming rounds off its corners (a disc
    # cannot reach into them) and the silhouettes do not put back: within 3 fine voxels
    c = (np.arange(63) + 0.5) * vf
    cx = c + frame.origin[0]
    cy = c + frame.origin[1]
    cz = c + frame.origin[2]
    m = 3 * vf
    inner = (
        (np.abs(cx)[:, None, None] <= width / 2 - m)
        & (np.abs(cy)[None, :, None] <= 0.05 - m)
        & ((cz > m) & (cz < 0.05 - m))[None, None, :]
    )
    assert occ[inner].all()
    with pytest.raises(ValueError, match="centre"):
        perception.local_input((0.0, float("nan"), 0.0))
    # no silhouettes kept: nothing to carve
    bare = SilhouettePerception(FRAME, MASKS)
    bare.update(frames)
    assert not bare.local_input((0.0, 0.0, 0.06))[0].any()


def test_the_silhouettes_carved_again_reach_beyond_the_grid() -> None:
    # A box reaching 4 cm out of the grid's +x side: the grid holds what lies inside;
    # the same frames carved into a cube grown by 8 voxels hold the rest too.
    _, views = _carve([((0.14, 0.0, 0.025), (0.10, 0.05, 0.05))])
    spec = CameraSpec()
    frames = [MaskedFrame(cam2world=v.cam2world, camera=spec, mask=v.mask) for v in views]
    perception = SilhouettePerception(FRAME, MASKS, roof_radius=0.0225)
    perception.update(frames)
    grown = FRAME.size + 16 * V
    grid, frame = perception.local_grid((0.0, 0.0, grown / 2), grown, R_GRID + 16)
    assert frame.origin == pytest.approx((-0.15 - 8 * V, -0.15 - 8 * V, 0.0))
    high = grid.high_confidence(0.9) > 0
    x = frame.origin[0] + (np.argwhere(high)[:, 0] + 0.5) * V
    assert x.max() > 0.18  # the box ends at 0.19
    # inside the grid the two agree voxel for voxel
    inner = high[8:-8, 8:-8, :R_GRID]
    np.testing.assert_array_equal(inner, perception.grid.high_confidence(0.9) > 0)
    planned = perception.planner_input(grid.high_confidence(0.9), frame)
    assert planned.shape == high.shape and ((planned > 0) <= high).all()
