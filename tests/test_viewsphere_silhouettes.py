"""The viewsphere benchmark on silhouettes (``--perception silhouette|fused``): the hull
carved from the views bounds the object, a finger touches it only at frontier points,
fused depth is kept inside the hull, and the bench records what held."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from heapgrasp.sim.optics import Category
from heapgrasp.viewsphere.grasps import ViewsphereConfig, ViewsphereGrasps
from heapgrasp.viewsphere.objects import stand_in
from heapgrasp.viewsphere.report import summarize
from heapgrasp.viewsphere.sphere import SpherePose
from heapgrasp.viewsphere.world import ViewsphereWorld

#: Views around the object, as a policy reaches them: from the start, then lower.
AROUND = [(180.0, 180.0 / 7.0), (60.0, 45.0), (300.0, 45.0), (180.0, 65.0), (0.0, 65.0)]


def _poses(angles):
    return [SpherePose(math.radians(a), math.radians(p)) for a, p in angles]


def _inside_box(points, half, shrink=0.0):
    """Which points are in the box of half extents ``half`` on the table, ``shrink``
    in from each face."""
    return (
        np.all(np.abs(points[:, :2]) <= half[:2] - shrink + 1e-9, axis=1)
        & (points[:, 2] >= shrink - 1e-9)
        & (points[:, 2] <= 2 * half[2] - shrink + 1e-9)
    )


@pytest.fixture(scope="module")
def box_world() -> ViewsphereWorld:
    return ViewsphereWorld(stand_in("010_potted_meat_can"), perception="silhouette")


def test_the_hull_holds_the_object_and_shrinks_as_views_are_added(box_world):
    (v, _), *_ = stand_in("010_potted_meat_can")
    half = (v.max(axis=0) - v.min(axis=0)) / 2
    grasps = box_world.grasps
    cells = [grasps.hull(_poses(AROUND[:k])).cells for k in (1, 3, 5)]
    # Every cell whose centre is inside the box is in every hull (silhouettes carve
    # only what some view sees empty).
    res = cells[0].shape[0]
    voxel = grasps.config.voxel
    idx = np.argwhere(np.ones_like(cells[0]))
    corner = np.array([-res * voxel / 2, -res * voxel / 2, 0.0])
    centres = corner + (idx + 0.5) * voxel
    solid = _inside_box(centres, half, voxel)
    for c in cells:
        assert c[tuple(idx[solid].T)].all()
    # More views carve more: each hull holds the next, where the first view sees
    # (eq. 10 counts a cell no view sees as empty: the cube's far corners, the space
    # near a camera outside another's field of view).
    near = (np.all(np.abs(centres[:, :2]) <= 0.09, axis=1) & (centres[:, 2] <= 0.12)).reshape(
        cells[0].shape
    )
    assert (cells[1] <= cells[0])[near].all() and (cells[2] <= cells[1])[near].all()
    assert cells[2][near].sum() < 0.6 * cells[0][near].sum()
    # The surface points lie on the hull's cell faces, outside the object's interior.
    hull = grasps.hull(_poses(AROUND))
    assert len(hull.surface) and not _inside_box(hull.surface, half, 1.01 * voxel).any()


def test_one_silhouette_bounds_nothing_so_no_grasp_is_taken_from_it(box_world):
    grasps = box_world.grasps
    one = _poses(AROUND[:1])
    assert not grasps.hull(one).touchable(views=2, agree_deg=20.0, apart_deg=40.0).any()
    assert grasps.grasp(one) is None


def test_frontier_points_need_two_views_whose_cones_touch_and_rays_cross(box_world):
    hull = box_world.grasps.hull(_poses(AROUND))
    c = box_world.grasps.config
    strict = hull.touchable(views=2, agree_deg=c.rim_agree_deg, apart_deg=c.rim_apart_deg)
    any_rim = hull.touchable(views=1, agree_deg=180.0, apart_deg=0.0)
    loose = hull.touchable(views=2, agree_deg=90.0, apart_deg=0.0)
    assert strict.any()
    assert (strict <= loose).all() and (loose <= any_rim).all()
    assert strict.sum() < loose.sum() < any_rim.sum()


def test_perception_is_checked_and_silhouettes_are_required():
    world = ViewsphereWorld(stand_in("005_tomato_soup_can"))
    with pytest.raises(ValueError, match="perception must be one of depth, silhouette, fused"):
        ViewsphereGrasps(world.render, sphere=world.sphere, perception="lidar")
    with pytest.raises(ValueError, match="needs the views' silhouettes"):
        ViewsphereGrasps(world.render, sphere=world.sphere, perception="fused")
    with pytest.raises(ValueError, match="hull_lambda must be in"):
        ViewsphereConfig(hull_lambda=0.0)
    with pytest.raises(ValueError, match="rim_views must be an int >= 1"):
        ViewsphereConfig(rim_views=0)


def test_fused_keeps_the_depth_inside_the_hull_only():
    meshes = stand_in("005_tomato_soup_can")
    poses = _poses(AROUND[:3])
    fused = ViewsphereWorld(meshes, sensor=Category("transparent"), perception="fused")
    depth = ViewsphereWorld(meshes, sensor=Category("transparent"))
    hull = fused.grasps.hull(poses)
    points, _ = fused.grasps.object_points(poses)
    assert len(points) >= len(hull.surface)
    extra = points[len(hull.surface) :]
    raw, _ = depth.grasps.object_points(poses)
    assert len(extra) <= len(raw)
    # The unexplored region is the depth's, less what the silhouettes carved.
    assert len(fused.grasps.unexplored(poses)) <= len(depth.grasps.unexplored(poses))


def test_held_at_step_counts_the_grasps_that_held_by_each_step():
    settings = {"policies": ["brick"], "config": {"max_steps": 2}, "poses": 3}

    def rec(pose, steps, outcome):
        entry = {"found": outcome is not None, "steps": steps, "seconds": 0.1}
        return {"pose": pose, "yaw_deg": 0.0, "policies": {"brick": {**entry, "executed": outcome}}}

    records = {"box": [rec(0, 0, "success"), rec(1, 1, "empty"), rec(2, 2, None)]}
    summary = summarize(settings, records, {})["policies"]["brick"]["objects"]["box"]
    assert summary["success_at_step"] == pytest.approx([1 / 3, 2 / 3, 2 / 3])
    assert summary["held_at_step"] == pytest.approx([1 / 3, 1 / 3, 1 / 3])
    unexecuted = {
        "box": [
            {
                **rec(0, 0, None),
                "policies": {
                    "brick": {"found": True, "steps": 0, "seconds": 0.1, "executed": None}
                },
            }
        ]
    }
    assert (
        summarize(settings, unexecuted, {})["policies"]["brick"]["objects"]["box"]["held_at_step"]
        is None
    )


def test_the_bench_runs_on_silhouettes_and_records_it(tmp_path: Path, monkeypatch) -> None:
    from heapgrasp.cli import main

    monkeypatch.setenv("HEAPGRASP_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "run"
    args = ["viewsphere", "bench", "--out", str(out), "--workers", "1", "--quiet"]
    args += ["--no-figures", "--objects", "005_tomato_soup_can", "--poses", "1"]
    args += ["--policies", "brick", "--sensor", "transparent", "--perception", "silhouette"]
    assert main(args) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["settings"]["perception"] == "silhouette"
    can = results["policies"]["brick"]["objects"]["005_tomato_soup_can"]
    assert can["held_at_step"] is not None and len(can["held_at_step"]) == 7
    assert main([*args[:-1], "depth"]) == 2  # another perception in the same folder
