"""The grasp network's dataset (VGN's scheme on the loop's grids, :mod:`heapgrasp.data.grasps`)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pybullet")

from heapgrasp.cli import main
from heapgrasp.data.grasps import GraspDataConfig, draw_scene, generate, read_manifest
from heapgrasp.data.scenes import capture_random_views
from heapgrasp.data.shards import shard_path
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.loop.config import RunConfig
from heapgrasp.planning.volumes import GraspVolumes
from heapgrasp.sim.build import object_library, sim_pipeline

CONFIG = GraspDataConfig(scenes=2, root_seed=0, shard_size=1, max_objects=2)
TSDF = GraspDataConfig(scenes=1, root_seed=0, shard_size=1, max_objects=2, input="tsdf")
R = 40


def _load(path: Path) -> dict[str, Any]:
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[dict[str, Any]]]:
    out = tmp_path_factory.mktemp("grasps")
    manifest = generate(CONFIG, out, progress=False)
    assert manifest["complete"] and manifest["samples"] == 2 and manifest["dropped"] == 0
    shards = [_load(shard_path(out, s)) for s in range(2)]
    assert manifest["grasps"] == sum(len(d["grasp_label"]) for d in shards) > 0
    library = object_library(RunConfig())
    ks = {draw_scene(CONFIG, i, library)[0].k for i in range(2)}
    assert -1 in ks and len(ks) == 2  # seed 0: no-vp's circle and Algorithm 1's waypoints
    return out, shards


@pytest.fixture(scope="module")
def tsdf_dataset(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("grasps-tsdf")
    manifest = generate(TSDF, out, progress=False)
    assert manifest["complete"] and manifest["samples"] == 1
    return _load(shard_path(out, 0))


def test_shards_hold_the_contract(
    dataset: tuple[Path, list[dict[str, Any]]], tsdf_dataset: dict[str, Any]
) -> None:
    _, shards = dataset
    per_scene = {
        "origin": (np.float64, (3,)),
        "voxel_size": (np.float64, ()),
        "scene_seed": (np.int64, ()),
        "scene_index": (np.int64, ()),
        "k": (np.int64, ()),
    }
    per_grasp = {
        "grasp_scene": (np.int64, ()),
        "grasp_voxel": (np.int64, (3,)),
        "grasp_position": (np.float32, (3,)),
        "grasp_quat": (np.float32, (4,)),
        "grasp_width": (np.float32, ()),
        "grasp_label": (np.uint8, ()),
    }
    library = object_library(RunConfig())
    samples = [(d, "occupancy", draw_scene(CONFIG, i, library)[0].k) for i, d in enumerate(shards)]
    for d, grid, k in [*samples, (tsdf_dataset, "tsdf", -1)]:
        assert set(d) == {grid, *per_scene, *per_grasp, "scenes", "dropped"}
        assert d["scenes"].dtype == d["dropped"].dtype == np.int64 and d["scenes"].shape == ()
        s, g = len(d["k"]), len(d["grasp_label"])
        assert d[grid].dtype == np.float32 and d[grid].shape == (s, R, R, R)
        for key, (dtype, shape) in per_scene.items():
            assert d[key].dtype == dtype and d[key].shape == (s, *shape), key
        for key, (dtype, shape) in per_grasp.items():
            assert d[key].dtype == dtype and d[key].shape == (g, *shape), key
        assert d["k"].tolist() == [k]
        assert (d["grasp_scene"] == 0).all()
        np.testing.assert_allclose(np.linalg.norm(d["grasp_quat"], axis=1), 1.0, atol=1e-5)
    for d, _, _ in samples:  # Ŝ≥λ: the occupancy where it reaches λ = 0.9, else 0
        occupied = d["occupancy"][d["occupancy"] > 0]
        assert occupied.size and ((occupied >= 0.9) & (occupied <= 1)).all()
    # the TSDF, truncated and normalised (transparent objects may leave no surface in it:
    # the depth camera sees through them)
    tsdf = tsdf_dataset["tsdf"]
    assert (np.abs(tsdf) <= 1.0).all() and (tsdf > 0).any()


def test_labels_are_balanced_and_voxels_hold_their_grasps(
    dataset: tuple[Path, list[dict[str, Any]]],
) -> None:
    _, shards = dataset
    opening = 0.08
    for d in shards:
        label = d["grasp_label"]
        positives, negatives = int((label == 1).sum()), int((label == 0).sum())
        assert positives > 0 and set(np.unique(label)) <= {0, 1}
        assert negatives <= positives  # all positives, as many negatives where there are
        width = d["grasp_width"]
        assert ((width >= 0) & (width <= opening + 1e-6)).all()
        np.testing.assert_allclose(width[label == 0], opening, atol=1e-6)
        frame = GridFrame(tuple(d["origin"][0]), float(d["voxel_size"][0]) * R, R)
        voxel = d["grasp_voxel"]
        assert ((voxel >= 0) & (voxel < R)).all()
        np.testing.assert_array_equal(voxel, frame.index(d["grasp_position"]))
        lo = frame.centers(voxel) - frame.voxel_size / 2
        assert (
            (d["grasp_position"] >= lo - 1e-6)
            & (d["grasp_position"] < lo + frame.voxel_size + 1e-6)
        ).all()


def test_grasps_are_sampled_on_the_surface_the_grid_shows(
    dataset: tuple[Path, list[dict[str, Any]]], tsdf_dataset: dict[str, Any]
) -> None:
    """VGN's sampling: each grasp's approach passes through a point of the surface the
    network's input shows (the TSDF's zero crossings, the hull's boundary), whose
    outward normal does not point down, at a depth in VGN's range."""
    from heapgrasp.data.grasps import MIN_HEIGHT, grid_surface
    from heapgrasp.geometry.gripper import PANDA_HAND
    from scipy.spatial.transform import Rotation

    _, shards = dataset
    for d, kind in [*((d, "occupancy") for d in shards), (tsdf_dataset, "tsdf")]:
        frame = GridFrame(tuple(d["origin"][0]), float(d["voxel_size"][0]) * R, R)
        points, normals = grid_surface(d[kind][0], kind, frame)
        approach = Rotation.from_quat(d["grasp_quat"]).as_matrix()[:, :, 2]
        grasp = d["grasp_position"].astype(np.float64)
        # the surface point ahead of the grasp's origin (the palm's face): origin +
        # approach * depth
        rel = points[None, :, :] - grasp[:, None, :]
        s = np.einsum("gpk,gk->gp", rel, approach)
        off_line = np.linalg.norm(rel - s[:, :, None] * approach[:, None, :], axis=2)
        nearest = np.argmin(off_line, axis=1)
        rows = np.arange(len(grasp))
        assert off_line[rows, nearest].max() < 1e-5, kind
        fd = PANDA_HAND.finger_depth
        depth = s[rows, nearest]
        assert (depth >= -0.1 * fd - 1e-5).all() and (depth <= 1.1 * fd + 1e-5).all()
        np.testing.assert_allclose(normals[nearest], -approach, atol=1e-4)
        assert (points[nearest, 2] >= frame.origin[2] + MIN_HEIGHT).all()
        assert (approach[:, 2] < 0.1).all()


class _Spy:
    """A grasp planner that keeps what the loop feeds it."""

    name = "spy"
    sigma = 1.0
    epsilon = 0.8
    opens_fully = False
    needs_hull_check = False

    def __init__(self, input_kind: str) -> None:
        self.input_kind = input_kind
        self.grids: list[np.ndarray] = []

    def predict(self, grid: np.ndarray, frame: GridFrame) -> GraspVolumes:
        self.grids.append(grid.copy())
        z = np.zeros((R, R, R), np.float32)
        return GraspVolumes(frame, z, np.zeros((R, R, R, 4), np.float32), z)


def test_inputs_are_what_the_loop_feeds_the_network(
    dataset: tuple[Path, list[dict[str, Any]]], tsdf_dataset: dict[str, Any]
) -> None:
    _, shards = dataset
    library = object_library(RunConfig())
    # the VGN baseline's phase in a fresh world of the scene: its TSDF
    scene, _ = draw_scene(TSDF, 0, library)
    # one look: a spy plans nothing, and the dataset's phases do not look again
    net = {"grasp_planner": "network", "start": scene.start, "split": "train", "look_again": 0}
    spy = _Spy("tsdf")
    with scene.world(library, TSDF) as world:
        run = RunConfig(method="vgn", **net)
        sim_pipeline(run, world, seed=scene.world_seed, grasp_planner=spy).plan()
    (tsdf,) = spy.grids
    assert tsdf.dtype == np.float32
    np.testing.assert_array_equal(tsdf_dataset["tsdf"][0], tsdf)
    for index, d in enumerate(shards):
        scene, rng = draw_scene(CONFIG, index, library)
        assert int(d["scene_seed"][0]) == scene.world_seed
        seed = scene.world_seed
        net = {"grasp_planner": "network", "start": scene.start, "split": "train"}
        net["look_again"] = 0
        # the silhouette method's grid where it plans grasps
        spy = _Spy("occupancy")
        with scene.world(library, CONFIG) as world:
            if scene.k < 0:  # no-vp's phase
                run = RunConfig(method="no-vp", **net)
                sim_pipeline(run, world, seed=seed, grasp_planner=spy).plan()
            else:  # HEAPGrasp's at a view waypoint, after k of them
                run = RunConfig(method="heapgrasp", view_planner="oracle", **net)
                pipeline = sim_pipeline(run, world, seed=seed, grasp_planner=spy)
                capture_random_views(pipeline, rng, scene.k)
                pipeline.grasp_candidates()
                high = pipeline.perception.grid.high_confidence(run.lam)
                assert (spy.grids[0] <= high).all()  # Ŝ≥λ, its roofs trimmed
        (occupancy,) = spy.grids
        assert occupancy.dtype == np.float32
        np.testing.assert_array_equal(d["occupancy"][0], occupancy)


def test_a_shard_run_again_has_the_same_bytes_and_resume_skips(
    dataset: tuple[Path, list[dict[str, Any]]],
) -> None:
    out, _ = dataset
    first = shard_path(out, 0).read_bytes()
    os.remove(shard_path(out, 0))
    kept = shard_path(out, 1).stat().st_mtime_ns
    manifest = generate(CONFIG, out, progress=False)
    assert shard_path(out, 0).read_bytes() == first
    assert shard_path(out, 1).stat().st_mtime_ns == kept  # kept, not redone
    assert manifest["complete"] and read_manifest(out)["config"]["scenes"] == 2
    # a damaged shard (bytes flipped in a member, cut short, emptied) is written again
    # on the rerun, named, and the dataset is whole again: the same bytes
    good = shard_path(out, 0).read_bytes()
    middle = len(good) // 2
    for damaged in (
        good[:middle] + bytes(b ^ 0xFF for b in good[middle : middle + 64]) + good[middle + 64 :],
        good[: len(good) // 3],
        b"",
    ):
        shard_path(out, 0).write_bytes(damaged)
        manifest = generate(CONFIG, out, progress=False)
        assert shard_path(out, 0).read_bytes() == good
        assert manifest["complete"]
        assert shard_path(out, 1).stat().st_mtime_ns == kept
    with pytest.raises(ValueError, match="max_objects: 2 there, 3 asked"):
        generate(GraspDataConfig(**{**CONFIG.identity(), "scenes": 2, "max_objects": 3}), out)
    # nor do shards made with other loop settings, or by another labeller
    path = out / "manifest.json"
    text = path.read_text()
    manifest = json.loads(text)
    manifest["config"]["roof_radius"] = 0.0
    manifest["config"]["labeller"] = "0123"
    path.write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match=r"roof_radius: 0.0 there, 0.0225 asked.*labeller: '0123'"):
        generate(CONFIG, out)
    path.write_text(text)


def test_bad_settings_are_named() -> None:
    with pytest.raises(ValueError, match="split must be one of"):
        GraspDataConfig(split="holdout")
    with pytest.raises(ValueError, match="points must be an integer >= 1, got 0"):
        GraspDataConfig(points=0)
    with pytest.raises(ValueError, match=r"input must be one of .*got 'depth'"):
        GraspDataConfig(input="depth")
    with pytest.raises(ValueError, match="unknown gripper 'robotiq'; choose among panda"):
        GraspDataConfig(gripper="robotiq")


def test_grasps_for_the_2f140_are_labelled_with_its_geometry() -> None:
    """``--gripper robotiq-2f140``: failures carry its 14 cm opening, the grasp origin is
    its palm's face, and its samples differ from the Panda's on the same scene."""
    from heapgrasp.data.grasps import scene_sample
    from heapgrasp.geometry.gripper import ROBOTIQ_2F140

    config = GraspDataConfig(scenes=1, root_seed=3, shard_size=1, max_objects=2)
    robotiq = GraspDataConfig(**{**config.identity(), "scenes": 1, "gripper": "robotiq-2f140"})
    panda_sample = scene_sample(config, 0)
    ours = scene_sample(robotiq, 0)
    assert panda_sample is not None and ours is not None
    label, width = ours["grasp_label"], ours["grasp_width"]
    np.testing.assert_allclose(width[label == 0], ROBOTIQ_2F140.max_opening, atol=1e-6)
    assert (width <= ROBOTIQ_2F140.max_opening + 1e-6).all()
    np.testing.assert_array_equal(ours["occupancy"], panda_sample["occupancy"])  # same capture
    assert not np.array_equal(ours["grasp_position"], panda_sample["grasp_position"])


def test_cli(
    dataset: tuple[Path, list[dict[str, Any]]], capsys: pytest.CaptureFixture[str]
) -> None:
    out, _ = dataset
    args = ["grasps", "data", str(out), "--scenes", "2", "--seed", "0", "--quiet"]
    args += ["--max-objects", "2", "--workers", "1"]
    assert main([*args, "--shard-size", "1"]) == 0  # every shard there: nothing to run
    summary = json.loads(capsys.readouterr().out)
    assert summary["samples"] == 2 and summary["grasps"] > 0 and summary["complete"]
    # the same with a pool: nothing to run starts no pool (it was "max_workers must be
    # greater than 0", exit 2, for a complete dataset run again with --workers 2)
    assert main([*args[:-2], "--workers", "2", "--shard-size", "1"]) == 0
    assert json.loads(capsys.readouterr().out)["complete"]
    assert main([*args, "--shard-size", "2"]) == 2  # refused
    assert "shard_size: 1 there, 2 asked" in capsys.readouterr().err
    assert main(["grasps", "data", str(out), "--scenes", "0"]) == 2
    assert "--scenes" in capsys.readouterr().err
    assert main(["grasps", "data", str(out), "--split", "holdout"]) == 2
