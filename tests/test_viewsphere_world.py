"""Seed 001's world on the renderer (viewsphere.world): views, fusion, a grasp."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from heapgrasp.viewsphere.policies import BrickPolicy, breadth_first, run_episode
from heapgrasp.viewsphere.sphere import START
from heapgrasp.viewsphere.world import VIEWSPHERE_CAMERA, ViewsphereWorld


def _on_table(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(mesh.vertices, dtype=np.float64).copy()
    v[:, 2] -= v[:, 2].min()
    return v, np.asarray(mesh.faces, dtype=np.int64)


def test_the_camera_is_seed_001s():
    assert (VIEWSPHERE_CAMERA.width, VIEWSPHERE_CAMERA.height) == (640, 480)
    fov = 2 * np.arctan(VIEWSPHERE_CAMERA.width / 2 / VIEWSPHERE_CAMERA.fx)
    assert fov == pytest.approx(1.047198, abs=1e-5)


def test_a_box_is_seen_fused_and_grasped_across_its_narrow_side():
    world = ViewsphereWorld([_on_table(trimesh.creation.box(extents=(0.04, 0.09, 0.10)))])
    depth = world.depth(START)
    assert depth.shape == (480, 640) and depth.max() > 0.3
    obj, table_z = world.object_points([START])
    assert abs(table_z) < 0.002 and len(obj) > 50
    assert obj[:, 2].max() == pytest.approx(0.10, abs=0.005)
    episode = breadth_first(world.grasp_found, max_steps=2)
    assert episode.found
    grasp = world.grasp(list(episode.poses))
    assert grasp is not None and grasp.quality >= 150.0
    line = grasp.contacts[0] - grasp.contacts[1]
    assert abs(line[0]) / np.linalg.norm(line) > 0.9  # across the 4 cm side
    # The brick policy's episode runs on the same world.
    brick = run_episode(BrickPolicy(), world.grasp_found, max_steps=2)
    assert len(brick.poses) == brick.steps + 1


def test_a_sphere_wider_than_the_hand_yields_nothing():
    world = ViewsphereWorld([_on_table(trimesh.creation.icosphere(subdivisions=3, radius=0.05))])
    assert world.grasp([START]) is None
    with pytest.raises(ValueError, match="at least one view"):
        world.grasp([])
    with pytest.raises(ValueError, match="at least one mesh"):
        ViewsphereWorld([])


def test_the_config_checks_its_values_and_round_trips():
    from heapgrasp.viewsphere.grasps import ViewsphereConfig

    config = ViewsphereConfig(voxel=0.01, max_steps=4)
    assert ViewsphereConfig.from_dict(config.to_dict()) == config
    assert config.sphere().radius == 0.40 and abs(config.start.polar - np.pi / 7) < 1e-12
    with pytest.raises(ValueError, match=r"unknown viewsphere setting.*voxels"):
        ViewsphereConfig.from_dict({"voxels": 0.01})
    for bad in ({"voxel": 0.0}, {"max_steps": -1}, {"min_range": 4.0}, {"radius": float("nan")}):
        with pytest.raises(ValueError, match="ViewsphereConfig"):
            ViewsphereConfig(**bad)


def test_each_set_of_views_is_synthesised_once():
    world = ViewsphereWorld([_on_table(trimesh.creation.box(extents=(0.04, 0.09, 0.10)))])
    sphere = world.sphere
    one = sphere.move(START, 4)[1]
    first = world.grasp([START, one])
    assert world.grasps.sets_evaluated == 1
    assert world.grasp([START, one, START]) is first  # the same set: cached
    assert world.grasps.sets_evaluated == 1
    world.grasp([START])
    assert world.grasps.sets_evaluated == 2


def test_the_fused_state_is_the_object_and_the_unexplored_points():
    world = ViewsphereWorld([_on_table(trimesh.creation.box(extents=(0.04, 0.09, 0.10)))])
    one = world.sphere.move(START, 4)[1]
    obj, unexplored = world.grasps.fused([START])
    obj2, unexplored2 = world.grasps.fused([START, one])
    assert len(obj2) >= len(obj) > 0  # a second view shows no less of the box
    assert 0 < len(unexplored2) < len(unexplored)  # and explores more
