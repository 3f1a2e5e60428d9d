"""On-policy grasp data (:mod:`heapgrasp.data.loop_grasps`, ``heapgrasp grasps
loop-data``): the loop's own grids, the network's top grasps labelled on the true
meshes, in the grasp data's format."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pybullet")

from heapgrasp.cli import main
from heapgrasp.data.loop_grasps import (
    LOOP_PHASE,
    LoopGraspDataConfig,
    phase_sample,
    top_precision,
)
from heapgrasp.data.shards import generate, shard_path
from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.loop.stages import make_grasp_planner
from heapgrasp.sim.build import scene_world, sim_pipeline
from heapgrasp.sim.grasp_labels import labeller

CONFIG = LoopGraspDataConfig(scenes=2, shard_size=1, objects=2, points=40, top=4, root_seed=3)


def _load(path: Path) -> dict[str, Any]:
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[dict[str, Any]]]:
    out = tmp_path_factory.mktemp("loop-grasps")
    manifest = generate(CONFIG, out, progress=False)
    assert manifest["complete"] and manifest["samples"] >= 2
    shards = [_load(shard_path(out, s)) for s in range(2)]
    return out, shards


def test_shards_are_grasp_data_that_training_reads(
    dataset: tuple[Path, list[dict[str, Any]]],
) -> None:
    """The grasp data's arrays (``heapgrasp grasps train`` loads them), every sample a
    loop phase, and the top candidates indexed, ranked best first, scores falling."""
    from heapgrasp.training.grasp_data import load_grasp_dataset

    torch = pytest.importorskip("torch")
    del torch
    out, shards = dataset
    data = load_grasp_dataset(out)
    assert data.input_kind == "occupancy" and data.split == "train"
    assert len(data) == sum(len(s["k"]) for s in shards)
    for s in shards:
        n = len(s["k"])
        assert (s["k"] == LOOP_PHASE).all()
        assert s["occupancy"].shape == (n, 40, 40, 40)
        assert s["occupancy"].min() >= 0.0 and s["occupancy"].max() <= 1.0
        assert len(s["top_scene"]) == len(s["top_rank"]) == len(s["top_label"])
        for i in range(n):
            ranks = s["top_rank"][s["top_scene"] == i]
            scores = s["top_score"][s["top_scene"] == i]
            np.testing.assert_array_equal(ranks, np.arange(len(ranks)))
            assert len(ranks) <= CONFIG.top
            assert (np.diff(scores) <= 1e-6).all()
        # both labels among the grasps (the top ones unbalanced, VGN's balanced)
        assert set(np.unique(s["grasp_label"])) == {0, 1}
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["config"]["driver"] == "network" and manifest["config"]["input"] == "occupancy"
    assert manifest["top_grasps"] == sum(len(s["top_label"]) for s in shards)


def test_a_phase_holds_the_networks_grid_and_its_labelled_top_grasps() -> None:
    """On a phase of a scene: the grid is the one the network reads, the top grasps are
    the loop's candidates of the network, each labelled as the labeller labels it, and
    all of them are among the sample's grasps, held at the palm's face."""
    base = CONFIG.run_config("opaque", "pile")
    rank = CONFIG.ranker_config(base)
    planner = make_grasp_planner(rank, PANDA_HAND)
    rng = np.random.default_rng(0)
    with scene_world(base, 11, "opaque") as world:
        pipeline = sim_pipeline(rank, world, seed=11, grasp_planner=planner)
        pipeline.plan()
        sample = phase_sample(pipeline, world, (rank, planner), CONFIG, rng)
        assert sample is not None
        np.testing.assert_array_equal(sample["occupancy"], pipeline.perception.grasp_input())
        cands = pipeline.grasp_candidates()[: CONFIG.top]
        assert cands, "the network proposes grasps on this pile"
        np.testing.assert_allclose(sample["top_score"], [c.score for c in cands], rtol=1e-6)
        poses = np.stack([c.pose for c in cands])
        ok, _, _, _ = labeller(world).label(poses, threads=1)
        np.testing.assert_array_equal(sample["top_label"], ok.astype(np.uint8))
    palm = poses[:, :3, 3] + poses[:, :3, 2] * PANDA_HAND.palm_front
    held = sample["grasp_position"]
    for p in palm:
        assert np.min(np.linalg.norm(held - p, axis=1)) < 1e-5


def test_a_shard_run_again_has_the_same_bytes(
    dataset: tuple[Path, list[dict[str, Any]]], tmp_path: Path
) -> None:
    out, _ = dataset
    from heapgrasp.data.shards import write_shard

    write_shard(CONFIG, 1, str(tmp_path))
    assert shard_path(tmp_path, 1).read_bytes() == shard_path(out, 1).read_bytes()


def test_precision_of_the_top_grasps_is_counted(
    dataset: tuple[Path, list[dict[str, Any]]],
) -> None:
    out, shards = dataset
    summary = top_precision(out, ks=(1, 4))
    rank = np.concatenate([s["top_rank"] for s in shards])
    label = np.concatenate([s["top_label"] for s in shards])
    assert summary["labelled@1"] == int((rank == 0).sum())
    assert summary["precision@1"] == pytest.approx(label[rank == 0].mean())
    assert summary["labelled@4"] == len(label)
    assert summary["phases"] == sum(len(s["k"]) for s in shards)


def test_scenes_draw_the_datasets_objects_alone() -> None:
    """``val`` scenes hold only the train objects held out for validation, ``train`` ones
    none of them (the library's train split holds both)."""
    from heapgrasp.data.loop_grasps import draw_scene
    from heapgrasp.data.scenes import object_split
    from heapgrasp.sim.build import object_library

    library = object_library(CONFIG.run_config("mixed", "pile"))
    for split in ("train", "val", "test"):
        config = LoopGraspDataConfig(split=split)
        names = {m.name for i in range(12) for m in draw_scene(config, i, library)[0].models}
        assert names and {
            object_split(n, m.split) for m in library.models() for n in [m.name] if n in names
        } == {split}
        assert names <= set(config.object_names())


def test_bad_settings_are_named(tmp_path: Path) -> None:
    for kwargs, message in (
        ({"driver": "human"}, "driver must be one of network, default"),
        ({"method": "giga"}, "method must be one of heapgrasp, no-vp, vgn"),
        ({"weights": str(tmp_path / "nope.onnx")}, "nope.onnx is not a file"),
        ({"top": 0}, "top must be an integer >= 1"),
        ({"points": -1}, "points must be an integer >= 0"),
        ({"gripper": "robotiq-2f140"}, "the loop's simulated hand is the Panda"),
    ):
        with pytest.raises(ValueError, match=message):
            LoopGraspDataConfig(**kwargs)


def test_a_method_without_a_shipped_network_fails_before_any_shard(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """No network ships for the TSDF: one clear error up front, nothing written (it was
    one failure per shard, after the pool had started)."""
    import heapgrasp.inference

    monkeypatch.setattr(heapgrasp.inference, "shipped_grasp_network", lambda kind: None)
    with pytest.raises(ValueError, match="no grasp network for tsdf grids ships"):
        LoopGraspDataConfig(method="vgn")
    out = tmp_path / "d"
    assert main(["grasps", "loop-data", str(out), "--method", "vgn", "--quiet"]) == 2
    assert "pass one (heapgrasp grasps train --input tsdf" in capsys.readouterr().err
    assert not out.exists()


def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "d"
    args = ["grasps", "loop-data", str(out), "--scenes", "1", "--objects", "2", "--points", "20"]
    assert main([*args, "--top", "2", "--workers", "1", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["complete"] and summary["samples"] >= 1
    assert summary["network_on_these_phases"]["phases"] == summary["samples"]
    assert main([*args, "--weights", str(tmp_path / "x.onnx")]) == 2
    err = capsys.readouterr().err
    assert "x.onnx is not a file" in err and "Traceback" not in err
    # the same directory with other settings is refused, the shards kept
    assert main([*args, "--top", "3", "--workers", "1", "--quiet"]) == 2
    assert "top" in capsys.readouterr().err
    assert shard_path(out, 0).exists()
