"""The analytic antipodal grasp planner (seed 001 §3.3 on an occupancy grid)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from heapgrasp import OccupancyGrid
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import GripperGeometry
from heapgrasp.planning.antipodal import AntipodalPlanner, grasp_orientations
from heapgrasp.planning.volumes import (
    GraspPlanner,
    GraspVolumes,
    quaternion_to_matrix,
    select_candidates,
)

FRAME = GridFrame((0.0, 0.0, 0.0), 0.30, 40)
CENTRES = (np.arange(40) + 0.5) * FRAME.voxel_size


@pytest.fixture(scope="module")
def planner() -> AntipodalPlanner:
    return AntipodalPlanner()


def box_grid(*boxes: tuple[float, float, float, float, float]) -> np.ndarray:
    """Occupancy of upright boxes ``(cx, cy, sx, sy, height)`` standing on the table."""
    x, y, z = np.meshgrid(CENTRES, CENTRES, CENTRES, indexing="ij")
    occ = np.zeros(x.shape, dtype=bool)
    for cx, cy, sx, sy, h in boxes:
        occ |= (np.abs(x - cx) < sx / 2) & (np.abs(y - cy) < sy / 2) & (z < h)
    return occ.astype(np.float32)


def candidates(planner: AntipodalPlanner, grid: np.ndarray) -> list:
    vol = planner.predict(grid, FRAME)
    return select_candidates(vol, epsilon=planner.epsilon, sigma=planner.sigma)


def test_is_a_grasp_planner(planner: AntipodalPlanner) -> None:
    assert isinstance(planner, GraspPlanner)
    assert planner.name == "antipodal"
    assert 0 < planner.epsilon <= 1 and planner.sigma >= 0


def test_upright_box_is_grasped_top_down_across_its_narrow_side(
    planner: AntipodalPlanner,
) -> None:
    grid = box_grid((0.15, 0.15, 0.05, 0.10, 0.08))
    cands = candidates(planner, grid)
    assert cands, "a 5 cm box must be graspable"
    best = cands[0]
    rot = best.pose[:3, :3]
    assert rot[2, 2] < -math.cos(math.radians(35)), "approach roughly downward"
    assert abs(rot[0, 1]) > 0.9, "fingers close along the box's 5 cm side (world x)"
    assert 0.05 <= best.width <= 0.065
    assert np.linalg.norm(best.position[:2] - 0.15) < 0.012, "centred on the box"
    assert 0.005 < best.position[2] < 0.08, "between the table and the top"
    assert best.score >= planner.epsilon


def test_box_wider_than_the_opening_has_no_grasp(planner: AntipodalPlanner) -> None:
    vol = planner.predict(box_grid((0.15, 0.15, 0.10, 0.10, 0.06)), FRAME)
    assert not vol.quality.any()


def test_empty_grid_gives_zero_quality(planner: AntipodalPlanner) -> None:
    vol = planner.predict(np.zeros((40, 40, 40), dtype=np.float32), FRAME)
    assert isinstance(vol, GraspVolumes)
    assert not vol.quality.any() and not vol.widths.any()
    np.testing.assert_allclose(np.linalg.norm(vol.quaternions, axis=-1), 1.0)


@pytest.mark.parametrize("gap", [0.01, 0.05])
def test_no_finger_between_boxes_closer_than_a_finger(
    planner: AntipodalPlanner, gap: float
) -> None:
    """Two 3.5 cm x 10 cm boxes side by side along x: each can only be grasped across
    x, with one finger in the gap, which needs the gap to hold a finger."""
    half = (0.035 + gap) / 2
    grid = box_grid((0.15 - half, 0.15, 0.035, 0.10, 0.06), (0.15 + half, 0.15, 0.035, 0.10, 0.06))
    vol = planner.predict(grid, FRAME)
    if gap < 0.02:
        # A 1 cm gap cannot take a 1.6 cm finger: at most poor tilted grasps at the
        # boxes' corners, with a finger beyond the end of the gap, remain.
        idx = np.argwhere(vol.quality > 0)
        rot = quaternion_to_matrix(vol.quaternions[tuple(idx.T)])
        assert np.all(rot[:, 2, 2] > -0.95), "no top-down grasp"
        assert vol.quality.max() < planner.epsilon
        assert not select_candidates(vol, epsilon=planner.epsilon, sigma=planner.sigma)
    else:
        cands = select_candidates(vol, epsilon=planner.epsilon, sigma=planner.sigma)
        assert cands
        for cand in cands:
            assert abs(cand.pose[0, 1]) > 0.8, "across one box's narrow side"
            assert cand.width < 0.035 + gap


def test_output_is_valid_and_deterministic(planner: AntipodalPlanner) -> None:
    grid = box_grid((0.09, 0.12, 0.04, 0.06, 0.07), (0.20, 0.18, 0.05, 0.05, 0.05))
    vol = planner.predict(grid, FRAME)
    again = planner.predict(grid.copy(), FRAME)
    for arr, other in (
        (vol.quality, again.quality),
        (vol.quaternions, again.quaternions),
        (vol.widths, again.widths),
    ):
        assert arr.dtype == np.float32
        np.testing.assert_array_equal(arr, other)
    GraspVolumes(vol.frame, vol.quality, vol.quaternions, vol.widths)  # validates
    assert vol.quality.min() >= 0 and vol.quality.max() <= 1 and vol.quality.max() > 0
    assert vol.widths.max() <= planner.max_opening + 1e-6
    np.testing.assert_allclose(np.linalg.norm(vol.quaternions, axis=-1), 1.0, atol=1e-5)
    assert not vol.widths[vol.quality == 0].any()


def test_fingers_stay_above_the_table(planner: AntipodalPlanner) -> None:
    grid = box_grid((0.15, 0.15, 0.03, 0.08, 0.03))
    vol = planner.predict(grid, FRAME)
    idx = np.argwhere(vol.quality > 0)
    assert len(idx)
    rot = quaternion_to_matrix(vol.quaternions[tuple(idx.T)])
    centre = FRAME.centers(idx)
    g = planner.gripper
    half = 0.5 * (vol.widths[tuple(idx.T)] + 0.01) + g.tip_thickness
    for sy in (-1.0, 1.0):
        for sx in (-1.0, 1.0):
            tip = np.stack(
                [
                    np.full(len(idx), sx * g.finger_width / 2),
                    sy * half,
                    np.full(len(idx), g.finger_tip),
                ],
                axis=1,
            )
            low = centre[:, 2] + np.einsum("nj,nj->n", rot[:, 2, :], tip)
            assert low.min() >= planner.table_clearance - 1e-6


def test_floating_blob_is_ignored(planner: AntipodalPlanner) -> None:
    x, y, z = np.meshgrid(CENTRES, CENTRES, CENTRES, indexing="ij")
    blob = (np.abs(x - 0.15) < 0.02) & (np.abs(y - 0.15) < 0.02) & (np.abs(z - 0.25) < 0.02)
    vol = planner.predict(blob.astype(np.float32), FRAME)
    assert not vol.quality.any()
    keep = AntipodalPlanner(support_height=None, tilts=(0.0,))
    assert keep.predict(blob.astype(np.float32), FRAME).quality.any()


def test_object_cut_by_the_grid_side_is_not_grasped_across_the_cut() -> None:
    planner = AntipodalPlanner(tilts=(0.0,))
    # A 4 cm x 4 cm column at the grid's x = 0 face: it may go on outside.
    grid = box_grid((0.005, 0.15, 0.04, 0.04, 0.06))
    vol = planner.predict(grid, FRAME)
    idx = np.argwhere(vol.quality > 0)
    rot = quaternion_to_matrix(vol.quaternions[tuple(idx.T)])
    assert np.all(np.abs(rot[:, 0, 1]) < 0.5), "never closing along x, across the cut"


def test_orientations_cover_top_down_and_tilted() -> None:
    rots, tilt = grasp_orientations((0.0, math.radians(30)), 6, 4)
    assert rots.shape == (4 + 6 * 4, 3, 3)
    eye = np.broadcast_to(np.eye(3), rots.shape)
    np.testing.assert_allclose(rots @ rots.transpose(0, 2, 1), eye, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(rots), 1.0)
    np.testing.assert_allclose(np.arccos(-rots[:, 2, 2]), tilt, atol=1e-7)
    assert np.all(np.abs(rots[tilt == 0][:, :, 1][:, 2]) < 1e-12), "top-down: horizontal y"


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"max_opening": 0.0}, "max_opening"),
        ({"max_opening": math.nan}, "max_opening"),
        ({"tilts": ()}, "tilts"),
        ({"tilts": (0.0, 2.0)}, "tilts"),
        ({"n_azimuth": 0}, "n_azimuth"),
        ({"n_yaw": 2.5}, "n_yaw"),
        ({"n_yaw": True}, "n_yaw"),
        ({"friction_angle": 0.0}, "friction_angle"),
        ({"friction_angle": 2.0}, "friction_angle"),
        ({"table_z": math.inf}, "table_z"),
        ({"table_clearance": -0.01}, "table_clearance"),
        ({"pregrasp_distance": -1.0}, "pregrasp_distance"),
        ({"opening_margin": -1.0}, "opening_margin"),
        ({"clearance": -1e-3}, "clearance"),
        ({"min_depth": -1.0}, "min_depth"),
        ({"target_depth": 0.0}, "target_depth"),
        ({"min_depth": 0.03, "target_depth": 0.02}, "target_depth"),
        ({"min_patch": 0}, "min_patch"),
        ({"min_contact_height": -1.0}, "min_contact_height"),
        ({"support_height": -1.0}, "support_height"),
        ({"ledge_factor": 1.5}, "ledge_factor"),
        ({"ledge_factor": math.nan}, "ledge_factor"),
        ({"epsilon": 1.5}, "epsilon"),
        ({"sigma": -1.0}, "sigma"),
        ({"gripper": "panda"}, "gripper"),
    ],
)
def test_bad_parameters_are_rejected(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        AntipodalPlanner(**kwargs)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"finger_width": 0.0}, "finger_width"),
        ({"tip_thickness": -0.01}, "tip_thickness"),
        ({"finger_split": 0.01}, "finger_split"),
        ({"palm_front": 0.01}, "palm_front"),
        ({"palm_back_half": (0.03,)}, "palm_back_half"),
        ({"palm_front_half": (0.02, -0.1)}, "palm_front_half"),
    ],
)
def test_bad_gripper_geometry_is_rejected(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        GripperGeometry(**kwargs)


def test_bad_grids_are_rejected(planner: AntipodalPlanner) -> None:
    with pytest.raises(ValueError, match="shape"):
        planner.predict(np.zeros((32, 32, 32), dtype=np.float32), FRAME)
    bad = np.zeros((40, 40, 40), dtype=np.float32)
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        planner.predict(bad, FRAME)


def test_a_carved_box_is_grasped_in_simulation(tmp_path: Path) -> None:
    from conftest import box_model
    from heapgrasp.geometry.camera import CameraSpec
    from heapgrasp.geometry.motion import ViewSphere
    from heapgrasp.sim.gripper import Grasp, GraspOutcome, PandaHand, execute_grasp
    from heapgrasp.sim.objects import ObjectLibrary
    from heapgrasp.sim.world import SimWorld

    model = box_model(tmp_path, (0.045, 0.07, 0.08))
    camera = CameraSpec.continuous()
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.33)
    with SimWorld(ObjectLibrary([model])) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=3, models=[model])
        (oid,) = world.objects
        poses = [sphere.pose(0.0, 0.0)] + [
            sphere.pose(phi, math.pi / 5) for phi in np.linspace(0, 2 * math.pi, 8, endpoint=False)
        ]
        masks = np.stack([world.capture(p, camera, depth=False).mask for p in poses])
        grid = OccupancyGrid(origin=(0.0, 0.0, 0.0), size=0.30, resolution=40)
        grid.integrate_many(masks, camera.core(), np.stack(poses))
        planner = AntipodalPlanner()
        cands = candidates(planner, grid.high_confidence(0.9))
        assert cands
        hand = PandaHand(world)
        result = execute_grasp(hand, Grasp(cands[0].pose, cands[0].width))
        assert result.outcome == GraspOutcome.SUCCESS, result
        assert result.object_id == oid


def test_a_grasp_above_a_ledge_costs_the_ledge_factor() -> None:
    # A 4 cm roof on a 7 cm wide box: the fingers closing on the roof have the box's
    # wider body just below their tips (a ledge); grasps of the body do not.
    grid = np.maximum(
        box_grid((0.15, 0.15, 0.07, 0.07, 0.06)), box_grid((0.15, 0.15, 0.03, 0.07, 0.10))
    )
    full = AntipodalPlanner(tilts=(0.0,), ledge_factor=1.0).predict(grid, FRAME).quality
    half = AntipodalPlanner(tilts=(0.0,), ledge_factor=0.5).predict(grid, FRAME).quality
    changed = np.abs(full - half) > 1e-6
    assert changed.any(), "some grasps close above the ledge"
    assert (half > 0).sum() > changed.sum(), "and some do not"
    np.testing.assert_allclose(half[changed], 0.5 * full[changed], rtol=1e-5)
    top_z = CENTRES[np.nonzero(changed)[2]]
    assert top_z.min() > 0.06 - 0.046, "ledge grasps reach no lower than the body's top"


# --------------------------------------------------------------------------- the core's search


def _pile(seed: int) -> np.ndarray:
    """A seeded pile: upright and lying boxes and cylinders, some stacked, one cut by a
    side face of the grid, as occupancy (float32)."""
    rng = np.random.default_rng(seed)
    x, y, z = np.meshgrid(CENTRES, CENTRES, CENTRES, indexing="ij")
    occ = np.zeros(x.shape, dtype=bool)
    for _ in range(6):
        cx, cy = rng.uniform(0.04, 0.26, size=2)
        yaw = rng.uniform(0, math.pi)
        u = (x - cx) * math.cos(yaw) + (y - cy) * math.sin(yaw)
        w = -(x - cx) * math.sin(yaw) + (y - cy) * math.cos(yaw)
        base = rng.uniform(0.0, 0.03) if rng.random() < 0.3 else 0.0
        kind = rng.integers(3)
        if kind == 0:  # upright box
            a, b, h = rng.uniform(0.02, 0.07, size=3)
            occ |= (np.abs(u) < a / 2) & (np.abs(w) < b / 2) & (z >= base) & (z < base + h)
        elif kind == 1:  # upright cylinder
            rad, h = rng.uniform(0.015, 0.04), rng.uniform(0.03, 0.09)
            occ |= (u**2 + w**2 < rad**2) & (z >= base) & (z < base + h)
        else:  # cylinder lying along u
            rad, length = rng.uniform(0.015, 0.035), rng.uniform(0.05, 0.12)
            occ |= (np.abs(u) < length / 2) & (w**2 + (z - base - rad) ** 2 < rad**2)
    # An object through the grid's side face (+x): no grasp may close across the cut.
    occ |= (x > 0.27) & (np.abs(y - 0.15) < 0.02) & (z < 0.05)
    return occ.astype(np.float32)


@pytest.mark.parametrize("seed", range(4))
def test_the_core_search_equals_the_numpy_reference_bit_for_bit(seed: int) -> None:
    import reference_antipodal

    planner = AntipodalPlanner()
    scene = planner._scene(_pile(seed) > 0, FRAME)
    assert scene is not None
    want = reference_antipodal.search(planner, scene)
    got = planner._search(scene)
    for name, w, g in zip(("quality", "orientation", "width"), want, got, strict=True):
        np.testing.assert_array_equal(g, w, err_msg=name)
    valid = want[0] > 0
    # The comparison covers many grasps, tilted ones among them.
    assert valid.sum() > 50
    assert (planner._tilt[want[1][valid]] > 0).any()


def _core_args(planner: AntipodalPlanner) -> dict:
    scene = planner._scene(box_grid((0.15, 0.15, 0.04, 0.06, 0.05)) > 0, FRAME)
    assert scene is not None
    captured: dict = {}

    def fake(*args: object) -> tuple:
        names = ("occupied", "gradient", "labels", "centroids", "candidates")
        names += ("rotations", "tilts", "params")
        captured.update(zip(names, args, strict=True))
        return (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0))

    import heapgrasp.planning.antipodal as mod

    real = mod.antipodal_grasps
    mod.antipodal_grasps = fake  # type: ignore[assignment]
    try:
        planner._search(scene)
    finally:
        mod.antipodal_grasps = real
    return captured


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda a: a["params"].pop("min_depth"), 'params: missing key "min_depth"'),
        (lambda a: a["params"].update(voxel_size=float("nan")), "voxel_size"),
        (lambda a: a.update(labels=a["labels"].astype(np.int64)), "labels: expected dtype int32"),
        (lambda a: a["labels"].__setitem__((0, 0, 0), 99), "labels"),
        (lambda a: a["candidates"].__setitem__((0, 0), -1), "candidates"),
        (lambda a: a["candidates"].__setitem__((0, 0), 40), "candidates"),
        (lambda a: a.update(tilts=a["tilts"][:3]), "tilts"),
        (lambda a: a["gradient"].__setitem__((0, 1, 2, 3), np.inf), "gradient"),
        (lambda a: a.update(occupied=a["occupied"][:, :, :39]), "occupied"),
    ],
)
def test_bad_core_arguments_raise_naming_the_argument(change, match: str) -> None:
    from heapgrasp import HeapgraspError
    from heapgrasp._core import antipodal_grasps

    args = _core_args(AntipodalPlanner())
    args["labels"] = args["labels"].copy()
    args["candidates"] = args["candidates"].copy()
    args["gradient"] = args["gradient"].copy()
    change(args)
    with pytest.raises(HeapgraspError, match=match):
        antipodal_grasps(**args)
