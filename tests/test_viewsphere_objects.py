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


@pytest.mark.parametrize(
    "stem, protocol",
    [
        ("003_cracker_box", "003_cracker_box"),  # YCB's id
        ("YcbCrackerBox", "003_cracker_box"),  # pybullet-object-models
        ("ycb_003_cracker_box", "003_cracker_box"),
        ("cracker_box", "003_cracker_box"),
        ("YcbPowerDrill", "035_power_drill"),
        ("072-a_toy_airplane", "072-a_toy_airplane"),
        ("toy_airplane", "072-a_toy_airplane"),
        ("YcbBanana", None),
        ("004_sugar_box", None),
        ("box", None),
    ],
)
def test_protocol_objects_are_known_by_any_common_spelling(stem, protocol):
    from heapgrasp.viewsphere.objects import protocol_name

    assert protocol_name(stem) == protocol


def _one_mesh(name):
    parts = stand_in(name)
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    return (
        np.vstack([v for v, _ in parts]),
        np.vstack([f + o for (_, f), o in zip(parts, offsets, strict=True)]),
    )


def _up(placed, frame):
    """The angle (degrees) between the placed mesh's up and the stand-in's up."""
    up = frame.T @ np.array([0.0, 0.0, 1.0])
    return np.degrees(np.arccos(min(1.0, abs(float(placed.rotation[2] @ up)))))


Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # z up → y up


@pytest.mark.parametrize("name", ["003_cracker_box", "008_pudding_box", "025_mug", "024_bowl"])
def test_a_protocol_object_rests_as_the_protocol_says_whatever_its_frame(name):
    from heapgrasp.viewsphere.objects import _rotation, placement

    v, f = _one_mesh(name)  # at rest, as the protocol puts the object
    rest = REST_POSES[name]
    ycb = _rotation(rest.roll, rest.pitch)  # YCB's frame: the protocol's roll and pitch rest it
    placed = placement(v @ ycb, f, name)
    assert placed.exact and "the protocol's roll and pitch" in placed.note
    assert _up(placed, ycb) < 1.0
    rng = np.random.default_rng(7)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    for frame in (Y_UP, q * np.sign(np.linalg.det(q))):  # Y up, or any frame at all
        placed = placement(v @ frame, f, name)
        assert placed.exact, placed.note
        assert _up(placed, frame) < 1.0, placed.note
        turned = (v @ frame) @ placed.rotation.T
        assert np.ptp(turned[:, 2]) == pytest.approx(np.ptp(v[:, 2]), abs=1e-6)


def test_a_mesh_that_cannot_rest_as_its_namesake_is_said_so():
    from heapgrasp.viewsphere.objects import placement

    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.04)
    placed = placement(np.asarray(ball.vertices), np.asarray(ball.faces), "003_cracker_box")
    assert not placed.exact
    assert "cannot rest it as 003_cracker_box rests (0.210 m tall)" in placed.note
    box = trimesh.creation.box(extents=(0.03, 0.05, 0.06))
    placed = placement(np.asarray(box.vertices), np.asarray(box.faces), None)
    assert not placed.exact and placed.note == "its most stable pose"
    assert np.ptp(np.asarray(box.vertices) @ placed.rotation[2]) == pytest.approx(0.03)


def test_user_objects_in_the_ycb_layouts_rest_as_the_protocol_says(tmp_path):
    from heapgrasp.viewsphere.objects import user_objects

    folder = tmp_path / "ycb"
    v, f = _one_mesh("003_cracker_box")
    box = trimesh.Trimesh(v @ Y_UP, f)  # a Y-up export of the cracker box
    (folder / "003_cracker_box" / "google_16k").mkdir(parents=True)
    box.export(str(folder / "003_cracker_box" / "google_16k" / "textured.obj"))
    (folder / "YcbCrackerBox").mkdir()
    box.export(str(folder / "YcbCrackerBox" / "textured.obj"))
    (folder / "YcbCrackerBox" / "model.urdf").write_text(
        '<robot name="b"><link name="base"><visual><geometry><mesh filename="textured.obj"/>'
        "</geometry></visual></link></robot>"
    )
    bad: list[tuple[str, str]] = []
    objects = user_objects(folder, tmp_path / "cache", on_bad=lambda *a: bad.append(a))
    assert not bad
    assert [o.name for o in objects] == ["003_cracker_box", "YcbCrackerBox"]
    for obj in objects:
        assert obj.protocol == "003_cracker_box" and obj.exact
        assert obj.yaw_range == REST_POSES["003_cracker_box"].yaw_range
        lo, hi = _extents(obj.meshes)
        np.testing.assert_allclose(hi[2] - lo[2], 0.21, atol=1e-6)
        assert "another" not in obj.placement or "frame" in obj.placement


def test_an_open_scan_rests_as_its_closed_mesh_would():
    from heapgrasp.viewsphere.objects import _stable_rotations, placement

    v, f = _one_mesh("003_cracker_box")
    v = v @ Y_UP
    # One face missing: no volume to weigh, and trimesh's centre of mass of what is left
    # sits on the box's top face, which reorders its stable poses.
    closed, scan = _stable_rotations(v, f), _stable_rotations(v, f[:-2])
    np.testing.assert_allclose([r[2] for r in scan], [r[2] for r in closed], atol=1e-6)
    placed = placement(v, f[:-2], "003_cracker_box")
    assert placed.exact and _up(placed, Y_UP) < 1.0
