"""Seed 001's stand-in objects (viewsphere.objects): sizes, closed meshes, rest."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from heapgrasp.viewsphere.objects import TEST_OBJECTS, TRAIN_OBJECTS, stand_in
from heapgrasp.viewsphere.protocol import REST_POSES

#: Published sizes (m), sorted; the drill and the airplane are composites (not listed).
SIZES = {
    "003_cracker_box": (0.06, 0.158, 0.21),
    "005_tomato_soup_can": (0.066, 0.066, 0.101),
    "006_mustard_bottle": (0.05, 0.085, 0.175),
    "008_pudding_box": (0.035, 0.089, 0.11),  # standing on its end (110 mm tall)
    "010_potted_meat_can": (0.05, 0.082, 0.097),
    "013_apple": (0.075, 0.075, 0.075),
    "021_bleach_cleanser": (0.065, 0.098, 0.25),
    "024_bowl": (0.053, 0.159, 0.159),
    "055_baseball": (0.075, 0.075, 0.075),
}


def _extents(meshes):
    pts = np.vstack([v for v, _ in meshes])
    return pts.min(axis=0), pts.max(axis=0)


@pytest.mark.parametrize("name", [*TEST_OBJECTS, *TRAIN_OBJECTS])
def test_each_stand_in_is_closed_and_rests_centred_on_the_table(name):
    meshes = stand_in(name)
    lo, hi = _extents(meshes)
    assert lo[2] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9)
    assert (hi - lo).max() < 0.30  # fits the benchmark's object box
    for v, f in meshes:
        mesh = trimesh.Trimesh(v, f, process=False)
        assert mesh.is_watertight and mesh.volume > 0


@pytest.mark.parametrize("name", sorted(SIZES))
def test_the_stand_ins_have_the_published_sizes(name):
    lo, hi = _extents(stand_in(name))
    np.testing.assert_allclose(np.sort(hi - lo), SIZES[name], atol=0.002)


def test_the_test_objects_are_the_protocols_and_unknown_names_are_refused():
    assert set(TEST_OBJECTS) == set(REST_POSES)
    lo, hi = _extents(stand_in("025_mug"))
    assert hi[2] - lo[2] == pytest.approx(0.082, abs=0.002)
    assert (hi - lo)[:2].max() > 0.09  # the handle sticks out of the 8 cm body
    with pytest.raises(ValueError, match="unknown object 'teapot'; known: 003_cracker_box"):
        stand_in("teapot")


def test_the_pudding_box_stands_on_its_end_as_the_protocols_height_says():
    lo, hi = _extents(stand_in("008_pudding_box"))
    # The protocol's origin height, 0.06 m, is about half of 110 mm, not of 35 mm.
    assert hi[2] - lo[2] == pytest.approx(0.11, abs=1e-6)
    assert abs(REST_POSES["008_pudding_box"].z - (hi[2] - lo[2]) / 2) < 0.01


def test_benchmark_objects_turn_about_the_vertical_and_check_their_size():
    from heapgrasp.viewsphere.objects import stand_ins

    (can,) = stand_ins(["005_tomato_soup_can"])
    assert can.yaw_range == REST_POSES["005_tomato_soup_can"].yaw_range
    (box,) = stand_ins(["003_cracker_box"])
    turned = box.posed(np.pi / 2)
    lo, hi = _extents(turned)
    np.testing.assert_allclose(hi - lo, [0.158, 0.06, 0.21], atol=1e-9)
    box.check_size(0.15, 0.30)
    with pytest.raises(ValueError, match=r"'003_cracker_box'.*larger than the workspace"):
        box.check_size(0.05, 0.30)
