"""The exact-geometry grasp labeller: argument checks of ``heapgrasp.GraspLabeller``, its
verdicts on a simulated lone box (agreeing with physics), VGN's sampler and reduction."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from conftest import box_model
from heapgrasp import (
    GraspLabeller,
    InvalidValueError,
    MeshError,
    NonFiniteError,
    NotRigidError,
    ShapeError,
)
from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.sim import grasp_labels as gl
from heapgrasp.sim.gripper import Grasp, PandaHand, execute_grasp
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.optics import Category
from heapgrasp.sim.world import SimWorld

TOP_DOWN = np.diag([1.0, -1.0, -1.0])  # TCP z pointing down, fingers along world ±y
BOX = (0.03, 0.05, 0.06)  # x, y (between the fingers), z


def top_down(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = TOP_DOWN
    m[:3, 3] = (x, y, z)
    return m


def cube(half: float) -> np.ndarray:
    return np.array(
        [[sx, sy, sz] for sx in (-half, half) for sy in (-half, half) for sz in (-half, half)]
    )


def make_labeller(**overrides: object) -> GraspLabeller:
    kwargs: dict[str, object] = {
        "table_z": 0.0,
        "friction": 1.0,
        "pregrasp_distance": 0.05,
        "hand_margin": 0.001,
        "object_margin": 0.001,
        "min_width": 0.004,
    }
    kwargs.update(overrides)
    return GraspLabeller(dataclasses.asdict(PANDA_HAND), **kwargs)  # type: ignore[arg-type]


# ----------------------------------------------------------------------- validation


def test_reason_names_are_the_codes() -> None:
    assert gl.REASONS == (
        "success",
        "collision",
        "empty",
        "two-objects",
        "not-antipodal",
        "narrow",
    )


@pytest.mark.parametrize(
    ("poses", "error", "match"),
    [
        (np.zeros((3, 4, 3)), ShapeError, r"tcp2world: expected shape \(N, 4, 4\)"),
        (np.zeros((4, 4)), ShapeError, "tcp2world: expected a 3-D array"),
        (np.tile(np.eye(4, dtype=np.float32), (2, 1, 1)), ShapeError, "tcp2world: expected dtype"),
        ([np.eye(4)], ShapeError, "tcp2world: expected a numpy.ndarray"),
        (np.tile(np.eye(4), (2, 1, 1))[:, :, ::-1], ShapeError, "tcp2world: array must be C-cont"),
    ],
)
def test_label_refuses_bad_pose_arrays(poses: object, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        make_labeller().label(poses)  # type: ignore[arg-type]
    assert issubclass(error, ValueError)


def test_label_names_the_non_finite_or_non_rigid_pose() -> None:
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[2, 1, 3] = np.nan
    with pytest.raises(NonFiniteError, match=r"tcp2world\[2\]"):
        make_labeller().label(poses)
    poses[2, 1, 3] = 0.0
    poses[1, 0, 0] = 2.0
    with pytest.raises(NotRigidError, match=r"tcp2world\[1\]"):
        make_labeller().label(poses)


def test_label_of_no_grasps_is_empty() -> None:
    ok, width, obj, reason = make_labeller().label(np.zeros((0, 4, 4)))
    assert ok.shape == width.shape == obj.shape == reason.shape == (0,)
    assert (ok.dtype, width.dtype, obj.dtype, reason.dtype) == (
        np.bool_,
        np.float32,
        np.int32,
        np.uint8,
    )


def test_bad_threads_and_parameters_are_named() -> None:
    with pytest.raises(InvalidValueError, match="threads"):
        make_labeller().label(np.zeros((0, 4, 4)), threads=-1)
    with pytest.raises(InvalidValueError, match="friction"):
        make_labeller(friction=float("nan"))
    with pytest.raises(InvalidValueError, match="min_width"):
        make_labeller(min_width=True)
    hand = dataclasses.asdict(PANDA_HAND)
    del hand["finger_tip"]
    with pytest.raises(InvalidValueError, match="finger_tip"):
        GraspLabeller(
            hand,
            table_z=0.0,
            friction=1.0,
            pregrasp_distance=0.05,
            hand_margin=0.001,
            object_margin=0.001,
            min_width=0.004,
        )


def test_add_object_checks_its_pieces() -> None:
    labeller = make_labeller()
    with pytest.raises(ShapeError, match=r"pieces\[1\]: expected shape \(V, 3\)"):
        labeller.add_object(1, np.eye(4), [cube(0.01), np.zeros((4, 2))])
    with pytest.raises(ShapeError, match=r"pieces\[0\]: expected dtype float64"):
        labeller.add_object(1, np.eye(4), [cube(0.01).astype(np.float32)])
    bad = cube(0.01)
    bad[3, 2] = np.inf
    with pytest.raises(NonFiniteError, match=r"pieces\[0\].*\[3, 2\]"):
        labeller.add_object(1, np.eye(4), [bad])
    with pytest.raises(MeshError, match=r"pieces\[0\]"):
        labeller.add_object(1, np.eye(4), [np.zeros((5, 3))])
    with pytest.raises(NotRigidError, match="obj2world"):
        labeller.add_object(1, 2 * np.eye(4), [cube(0.01)])
    with pytest.raises(InvalidValueError, match="id"):
        labeller.add_object(-1, np.eye(4), [cube(0.01)])
    labeller.add_object(1, np.eye(4), [cube(0.01)])
    with pytest.raises(InvalidValueError, match="already"):
        labeller.add_object(1, np.eye(4), [cube(0.01)])
    assert (labeller.object_count, labeller.piece_count) == (1, 1)


# ----------------------------------------------------------------------- a simulated box


@pytest.fixture
def lone_box(tmp_path: Path) -> tuple[SimWorld, int]:
    """A 3 x 5 x 6 cm box standing square with the world axes on the table."""
    model = box_model(tmp_path, BOX)
    world = SimWorld(ObjectLibrary([model]))
    world.reset(n_objects=0, seed=0)
    pose = np.eye(4)
    pose[:3, 3] = (0.15, 0.15, BOX[2] / 2 + 0.001)
    obj = world.spawn(model, pose, Category.OPAQUE)
    world.step(0.5)
    return world, obj.id


def test_table_top_is_z_zero(lone_box: tuple[SimWorld, int]) -> None:
    world, _ = lone_box
    with world:
        assert gl.table_top(world) == pytest.approx(0.0, abs=1e-12)


def test_top_down_grasp_on_a_lone_box_and_one_into_the_table(
    lone_box: tuple[SimWorld, int],
) -> None:
    world, oid = lone_box
    with world:
        x, y, _ = world.object_pose(oid)[:3, 3]
        labeller = gl.labeller(world)
        assert labeller.object_count == 1 and labeller.table_z == pytest.approx(0.0)
        grasps = np.stack([top_down(x, y, 0.04), top_down(x + 0.12, y, -0.01)])
        ok, width, obj, reason = labeller.label(grasps)
        assert ok.tolist() == [True, False]
        assert obj.tolist() == [oid, -1]
        assert [gl.REASONS[r] for r in reason] == ["success", "collision"]
        # The fingers stop PyBullet's two 1 mm margins short of each side of the box
        # (the real pads bulge 0.1 mm past y = ±opening / 2).
        assert width[0] == pytest.approx(BOX[1] + 4 * gl.CONVEX_MARGIN, abs=5e-4)
        assert width[1] == pytest.approx(0.08)
        # Physics agrees: the grasp into the table stops on it without touching the box,
        # then the box is held.
        hand = PandaHand(world)
        for pose, held in zip(grasps[::-1], ok[::-1], strict=True):
            result = execute_grasp(hand, Grasp(pose, width=0.08))
            assert result.success == held, result
            assert result.object_id == (oid if held else None)


def test_thread_count_does_not_change_labels(lone_box: tuple[SimWorld, int]) -> None:
    world, _ = lone_box
    with world:
        samples = gl.sample_grasps(world, np.random.default_rng(1), points=60, yaws=6)
        labeller = gl.labeller(world)
        one = labeller.label(samples.flat(), threads=1)
        for threads in (None, 0, 2, 3):
            other = labeller.label(samples.flat(), threads=threads)
            for a, b in zip(one, other, strict=True):
                np.testing.assert_array_equal(a, b)


# ----------------------------------------------------------------------- VGN's sampler


def test_sampled_grasps_follow_vgns_scheme(lone_box: tuple[SimWorld, int]) -> None:
    world, oid = lone_box
    with world:
        s = gl.sample_grasps(world, np.random.default_rng(0), points=200, yaws=6)
        centre_z = world.object_pose(oid)[2, 3]
    assert s.points.shape == s.normals.shape == (200, 3)
    assert s.poses.shape == (200, 6, 4, 4) and s.flat().shape == (1200, 4, 4)
    np.testing.assert_allclose(s.yaws, np.pi * np.arange(6) / 6)
    assert (s.objects == oid).all()
    assert (s.normals[:, 2] > gl.MIN_NORMAL_Z).all()
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=1), 1.0)
    # On the box's surface: its top or one of its sides.
    z = s.points[:, 2] - centre_z
    assert (np.abs(z) < BOX[2] / 2 + 1e-9).all()
    # Area-weighted: the top (15 cm²) against the four sides (96 cm²).
    top = s.normals[:, 2] > 0.9
    assert 0.05 < top.mean() < 0.3
    rot = s.poses[..., :3, :3]
    eye = np.broadcast_to(np.eye(3), rot.shape)
    np.testing.assert_allclose(rot @ rot.transpose(0, 1, 3, 2), eye, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rot), 1.0)
    np.testing.assert_allclose(rot[..., 2], -np.repeat(s.normals[:, None], 6, axis=1), atol=1e-12)
    # Yaws turn the frame about its z.
    cos = np.einsum("pi,pi->p", rot[:, 0, :, 1], rot[:, 1, :, 1])
    np.testing.assert_allclose(cos, np.cos(np.pi / 6))
    # The TCP sits at the depth: u · finger_depth in front of the palm's face.
    offset = np.einsum("pi,pi->p", s.poses[:, 0, :3, 3] - s.points, s.normals)
    np.testing.assert_allclose(offset, s.depths + PANDA_HAND.palm_front)
    u = s.depths / PANDA_HAND.finger_depth
    assert (u >= -0.1).all() and (u <= 1.1).all() and u.min() < 0.05 and u.max() > 0.95


def test_best_yaw_takes_the_middle_of_the_longest_run() -> None:
    success = np.array(
        [
            [0, 1, 1, 1, 0, 1],  # run 1..3: middle 2
            [1, 1, 0, 0, 0, 1],  # run 5, 0, 1 wraps: middle 0
            [0, 0, 0, 0, 0, 0],  # none: yaw 0, label 0
            [1, 1, 1, 1, 1, 1],  # all: middle of the turn
            [1, 0, 1, 1, 0, 0],  # 2..3 beats 0: lower middle 2
            [0, 1, 0, 1, 0, 0],  # tie: the run starting lowest
        ],
        dtype=bool,
    )
    width = np.arange(36, dtype=np.float32).reshape(6, 6) / 100
    index, label, best = gl.best_yaw(success, width)
    assert index.tolist() == [2, 0, 0, 2, 2, 1]
    assert label.tolist() == [1, 1, 0, 1, 1, 1]
    np.testing.assert_allclose(best, width[np.arange(6), index])
    with pytest.raises(ValueError, match="success and width"):
        gl.best_yaw(success, width[:, :3])


def test_label_scene_gives_one_grasp_per_point(lone_box: tuple[SimWorld, int]) -> None:
    world, oid = lone_box
    with world:
        out = gl.label_scene(world, np.random.default_rng(2), points=80, yaws=6)
    assert out["position"].shape == (80, 3) and out["quat"].shape == (80, 4)
    assert out["label"].dtype == np.uint8 and out["width"].dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(out["quat"], axis=1), 1.0)
    np.testing.assert_allclose(out["position"], out["pose"][:, :3, 3])
    positive = out["label"] == 1
    assert positive.any() and not positive.all()
    assert (out["held"][positive] == oid).all() and (out["held"][~positive] == -1).all()
    assert (out["width"][~positive] == np.float32(0.08)).all()
    assert (out["width"][positive] < 0.08).all()
