"""The grasp network's training (heapgrasp.training.grasp_data, heapgrasp.training.train_grasps,
heapgrasp grasps train): VGN's losses and the gripper's symmetry, the exact
augmentations, the metrics, exact resume, the exported ONNX file in the planner, and the
command's errors. A tiny synthetic dataset of 40³ grids in the format of ``heapgrasp
grasps data`` and tiny networks keep it fast."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")

from heapgrasp.cli import main  # noqa: E402
from heapgrasp.geometry.grid import GridFrame  # noqa: E402
from heapgrasp.training.common import TrainSetupError  # noqa: E402
from heapgrasp.training.grasp_data import (  # noqa: E402
    DATA_FORMAT,
    Augment,
    GraspDataError,
    augment_scene,
    concatenate,
    find_datasets,
    load_grasp_dataset,
    make_batch,
    quat_multiply,
)
from heapgrasp.training.train_grasps import (  # noqa: E402
    GraspTrainConfig,
    average_precision,
    grasp_losses,
    load_grasp_network,
    rotation_error_deg,
    train,
)

R = 40
SIZE = 0.30
VOXEL = SIZE / R
ORIGIN = (-0.15, -0.15, 0.0)
TINY = ["--channels", "2", "2", "2", "--head-kernel", "3"]


# --------------------------------------------------------------------------- synthetic data


def _unit_quats(g: np.random.Generator, n: int) -> np.ndarray:
    q = g.normal(size=(n, 4))
    return (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)


def write_dataset(
    out: Path,
    *,
    split: str = "train",
    n: int = 4,
    seed: int = 0,
    objects: tuple[str, ...] | None = None,
    shard_size: int = 3,
    resolution: int = R,
    grid: str = "occupancy",
) -> Path:
    """A grasp dataset of ``grid`` in the format of ``heapgrasp grasps data``: boxes on
    the floor of the grid, grasps at voxels over them (successes) and elsewhere."""
    g = np.random.default_rng(seed)
    r = resolution
    out.mkdir(parents=True)
    shards = {}
    for s, start in enumerate(range(0, n, shard_size)):
        m = min(shard_size, n - start)
        occ = np.zeros((m, r, r, r), np.float32)
        tsdf = np.zeros((m, r, r, r), np.float32)
        per: dict[str, list[np.ndarray]] = {k: [] for k in ("scene", "voxel", "pos", "label")}
        for i in range(m):
            for _ in range(3):
                lo = g.integers(2, r - 8, 2)
                h = int(g.integers(2, r // 3))
                occ[i, lo[0] : lo[0] + 6, lo[1] : lo[1] + 6, :h] = 1.0
            tsdf[i] = np.where(occ[i] > 0, -0.5, 1.0) * (g.random((r, r, r)) > 0.2)
            count = int(g.integers(6, 12))
            columns = np.argwhere(occ[i, :, :, 0] > 0)  # half of them over a box
            on_box = columns[g.integers(0, len(columns), count // 2)]
            off = g.integers(0, r, (count - count // 2, 2))
            height = g.integers(0, r // 2, (count, 1))
            voxel = np.concatenate([np.concatenate([on_box, off]), height], 1)
            per["voxel"].append(voxel)
            per["pos"].append(
                np.asarray(ORIGIN) + (voxel + g.uniform(0.1, 0.9, (count, 3))) * VOXEL
            )
            per["label"].append((occ[i, voxel[:, 0], voxel[:, 1], 0] > 0).astype(np.uint8))
            per["scene"].append(np.full(count, i))
        count = sum(len(v) for v in per["voxel"])
        arrays = {
            grid: occ if grid == "occupancy" else tsdf,
            "origin": np.tile(np.asarray(ORIGIN), (m, 1)),
            "voxel_size": np.full(m, VOXEL),
            "scene_seed": np.arange(start, start + m, dtype=np.int64),
            "scene_index": np.arange(start, start + m, dtype=np.int64),
            "k": g.integers(-1, 3, m).astype(np.int64),
            "grasp_scene": np.concatenate(per["scene"]).astype(np.int64),
            "grasp_voxel": np.concatenate(per["voxel"]).astype(np.int64),
            "grasp_position": np.concatenate(per["pos"]).astype(np.float32),
            "grasp_quat": _unit_quats(g, count),
            "grasp_width": g.uniform(0.01, 0.08, count).astype(np.float32),
            "grasp_label": np.concatenate(per["label"]),
            "scenes": np.int64(m),
            "dropped": np.int64(0),
        }
        name = f"shard-{s:05d}.npz"
        np.savez_compressed(out / name, **arrays)
        shards[name] = {"samples": m, "scenes": m, "dropped": 0, "grasps": count}
    manifest = {
        "format": DATA_FORMAT,
        "version": 2,
        "split": split,
        "root_seed": seed,
        "objects": list(objects if objects is not None else (f"{split}-object-{seed}",)),
        "config": {
            "input": grid,
            "resolution": r,
            "cube_size": SIZE,
            "lam": 0.9,
            "max_opening": 0.08,
        },
        "shards": shards,
        "samples": n,
    }
    (out / "manifest.json").write_text(json.dumps(manifest))
    return out


@pytest.fixture(scope="module")
def root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``DATA/train``, ``DATA/val``, ``DATA/test``."""
    base = tmp_path_factory.mktemp("grasps")
    write_dataset(base / "train", split="train", n=4, seed=1)
    write_dataset(base / "val", split="val", n=2, seed=2)
    write_dataset(base / "test", split="test", n=2, seed=3)
    return base


def test_the_data_modules_format_is_read() -> None:
    grasps = pytest.importorskip("heapgrasp.data.grasps")
    assert grasps.FORMAT == DATA_FORMAT


def test_dataset_loads_either_grid_and_keeps_each_scenes_grasps(root: Path, tmp_path: Path) -> None:
    occ = load_grasp_dataset(root / "train")
    raw = [np.load(p) for p in sorted((root / "train").glob("shard-*.npz"))]
    assert len(occ) == 4 and occ.grids.dtype == np.float32 and occ.input_kind == "occupancy"
    np.testing.assert_array_equal(occ.grids, np.concatenate([r["occupancy"] for r in raw]))
    made = write_dataset(tmp_path / "tsdf", n=4, seed=1, grid="tsdf")
    tsdf = load_grasp_dataset(made, workers=2)
    raw_tsdf = [np.load(p) for p in sorted(made.glob("shard-*.npz"))]
    assert tsdf.input_kind == "tsdf" and tsdf.grids.dtype == np.float32
    np.testing.assert_array_equal(tsdf.grids, np.concatenate([r["tsdf"] for r in raw_tsdf]))
    np.testing.assert_array_equal(tsdf.voxel, occ.voxel)
    with pytest.raises(GraspDataError, match="a dataset of 'tsdf' grids"):
        load_grasp_dataset(made, input_kind="occupancy")
    assert occ.grasps == sum(len(r["grasp_label"]) for r in raw)
    first = raw[0]
    rows = occ.scene_grasps(1)
    np.testing.assert_array_equal(occ.voxel[rows], first["grasp_voxel"][first["grasp_scene"] == 1])
    both = concatenate([occ, load_grasp_dataset(root / "train")])
    assert len(both) == 8 and both.grasps == 2 * occ.grasps
    assert [p.name for p in find_datasets([root])] == ["test", "train", "val"]
    batch = make_batch(occ, [1, 0])
    assert batch.grids.shape == (2, 1, R, R, R) and len(batch) == occ.offsets[2]
    np.testing.assert_array_equal(batch.grids[0, 0], occ.grids[1])
    assert (batch.scene[: rows.stop - rows.start] == 0).all()


def test_dataset_errors_name_the_file(tmp_path: Path) -> None:
    bad = write_dataset(tmp_path / "bad", n=2, shard_size=2)
    shard = bad / "shard-00000.npz"
    arrays = dict(np.load(shard))
    arrays["grasp_voxel"][0] = (R, 0, 0)
    np.savez_compressed(shard, **arrays)
    with pytest.raises(GraspDataError, match=r"shard-00000.npz: 'grasp_voxel' outside"):
        load_grasp_dataset(bad)
    del arrays["occupancy"]
    arrays["grasp_voxel"][0] = (0, 0, 0)
    np.savez_compressed(shard, **arrays)
    with pytest.raises(GraspDataError, match=r"missing array\(s\) occupancy"):
        load_grasp_dataset(bad)
    with pytest.raises(GraspDataError, match="no such directory"):
        find_datasets([tmp_path / "nothing"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(GraspDataError, match="empty: not a grasp dataset"):
        find_datasets([tmp_path / "empty"])


# --------------------------------------------------------------------------- losses


def _flip(q: np.ndarray) -> np.ndarray:
    return quat_multiply(q, [0.0, 0.0, 1.0, 0.0]).astype(np.float32)


def test_losses_are_vgns_and_see_the_grippers_symmetry() -> None:
    g = np.random.default_rng(0)
    n = 64
    target = _unit_quats(g, n)
    pred = _unit_quats(g, n)
    label = (g.random(n) > 0.5).astype(np.float32)
    quality = g.uniform(0.05, 0.95, n).astype(np.float32)
    width = g.uniform(0.0, 0.08, n).astype(np.float32)
    w_target = g.uniform(0.0, 0.08, n).astype(np.float32)
    vs = np.full(n, VOXEL, np.float32)

    def losses(p: np.ndarray, t: np.ndarray, w: np.ndarray = width) -> dict[str, torch.Tensor]:
        args = (quality, p, w, label, t, w_target, vs)
        return grasp_losses(*(torch.from_numpy(a) for a in args))

    base = losses(pred, target)
    # The finger-swapped label (q ⊗ rot_z(π)) is the same grasp: the same loss.
    flipped = losses(pred, _flip(target))
    torch.testing.assert_close(flipped["rotation_each"], base["rotation_each"])
    torch.testing.assert_close(flipped["loss"], base["loss"])
    # Predicting the label, or its twin, exactly: no rotation loss.
    for p in (target, _flip(target), -target):
        assert float(losses(p, target)["rotation_each"].abs().max()) < 1e-6
    assert float(losses(pred, target, w_target)["width_each"].max()) == 0.0
    # VGN's sum, written out.
    dot = np.abs((pred * target).sum(1))
    dot_flip = np.abs((pred * _flip(target)).sum(1))
    rot = np.minimum(1 - dot, 1 - dot_flip)
    wid = ((width - w_target) / VOXEL) ** 2
    bce = -(label * np.log(quality) + (1 - label) * np.log(1 - quality))
    want = (bce + label * (rot + 0.01 * wid)).mean()
    assert float(base["loss"]) == pytest.approx(want, rel=1e-5)
    assert float(base["rotation"]) == pytest.approx(rot[label > 0].mean(), rel=1e-5)
    assert float(base["width"]) == pytest.approx(wid[label > 0].mean(), rel=1e-5)
    # The rotation error is symmetric the same way; 180° about z is 0°, 90° is 90°.
    np.testing.assert_allclose(rotation_error_deg(_flip(target), target), 0.0, atol=1e-3)
    quarter = quat_multiply(target, [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)])
    np.testing.assert_allclose(rotation_error_deg(quarter, target), 90.0, atol=1e-3)


def test_average_precision_matches_the_step_sum() -> None:
    assert average_precision([0.9, 0.8, 0.7, 0.6], [1, 1, 0, 0]) == pytest.approx(1.0)
    # Ranks: P at each positive = 1/1, 2/3 → (1 + 2/3) / 2.
    assert average_precision([0.9, 0.8, 0.7], [1, 0, 1]) == pytest.approx(5 / 6)
    # Ties enter together: all at one threshold → precision 1/2 at recall 1.
    assert average_precision([0.5, 0.5, 0.5, 0.5], [1, 0, 1, 0]) == pytest.approx(0.5)
    assert math.isnan(average_precision([0.1, 0.2], [0, 0]))


# --------------------------------------------------------------------------- augmentation


def _matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = np.moveaxis(np.asarray(q, np.float64), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


@pytest.mark.parametrize("turns", [0, 1, 2, 3])
@pytest.mark.parametrize("shift", [(0, 0), (3, -2), (-4, 4)])
def test_turns_and_shifts_move_grid_voxels_positions_and_quaternions_together(
    turns: int, shift: tuple[int, int]
) -> None:
    """The grid's value at each grasp's new voxel is the one at its old voxel (a unique
    marker per grasp), each new position lies in its new voxel, and each orientation is
    turned by the same rotation about z; what leaves the grid is dropped, what enters
    it is empty."""
    g = np.random.default_rng(turns)
    n = 300
    voxel = g.integers(0, R, (n, 3))
    voxel = voxel[np.unique(voxel @ [R * R, R, 1], return_index=True)[1]]
    grid = np.zeros((R, R, R), np.float32)
    grid[voxel[:, 0], voxel[:, 1], voxel[:, 2]] = np.arange(1, len(voxel) + 1)
    frame = GridFrame(ORIGIN, SIZE, R)
    position = frame.centers(voxel) + g.uniform(-0.4, 0.4, voxel.shape) * VOXEL
    quat = _unit_quats(g, len(voxel))
    out, v, p, q, keep = augment_scene(
        grid, voxel, position, quat, ORIGIN, VOXEL, Augment(turns, shift)
    )
    assert out.shape == grid.shape and keep.sum() == len(v)
    assert keep.all() == (shift == (0, 0))
    np.testing.assert_array_equal(out[v[:, 0], v[:, 1], v[:, 2]], np.flatnonzero(keep) + 1)
    np.testing.assert_array_equal(frame.index(p), v)
    # The same rigid motion for the voxel centres and the positions.
    c = np.array([0.0, 0.0, 0.0])  # ORIGIN + SIZE / 2 in x and y
    a = turns * math.pi / 2
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    moved = (position[keep] - c) @ rz.T + c + np.array([*shift, 0]) * VOXEL
    np.testing.assert_allclose(p, moved, atol=1e-6)
    np.testing.assert_allclose(_matrix(q), rz @ _matrix(quat[keep]), atol=1e-6)
    # Voxels shifted in from outside are empty; four turns are none.
    assert (out > 0).sum() == len(v)
    back = out
    for _ in range(4):
        back = augment_scene(back, v, p, q, ORIGIN, VOXEL, Augment(1))[0]
    np.testing.assert_array_equal(back, out)


# --------------------------------------------------------------------------- training


def _same_weights(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


def test_resume_continues_exactly(tmp_path: Path, root: Path) -> None:
    """Stopped after epoch 1 and resumed, a 2-epoch training ends with the weights,
    metrics and best epoch of an uninterrupted run; resumed with more epochs, it ends
    as a run asked for them from the start."""
    tr, va = load_grasp_dataset(root / "train"), load_grasp_dataset(root / "val")
    small = {"channels": (2, 2, 2), "head_kernel": 3, "lr": 1e-2, "batch_size": 2}
    config = GraspTrainConfig(epochs=2, seed=3, **small)
    whole = train(config, tr, va, tmp_path / "whole", progress=False, log=None)

    def stop_after_first(line: str) -> None:
        if line.startswith("epoch 1/2"):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(config, tr, va, tmp_path / "cut", progress=False, log=stop_after_first)
    resumed = train(config, tr, va, tmp_path / "cut", resume=True, progress=False, log=None)
    assert _same_weights(whole.net, resumed.net)
    assert resumed.best_epoch == whole.best_epoch
    drop = ("seconds",)
    np.testing.assert_equal(
        [{k: v for k, v in r.items() if k not in drop} for r in resumed.history],
        [{k: v for k, v in r.items() if k not in drop} for r in whole.history],
    )
    with pytest.raises(TrainSetupError, match="pass --resume"):
        train(config, tr, va, tmp_path / "cut", progress=False, log=None)
    other = GraspTrainConfig(epochs=2, seed=4, **small)
    with pytest.raises(TrainSetupError, match=r"config.seed: 3 there, 4 now"):
        train(other, tr, va, tmp_path / "cut", resume=True, progress=False, log=None)
    # a finished run goes on for more epochs: as if it had been asked for them at first
    longer = GraspTrainConfig(epochs=3, seed=3, **small)
    extended = train(longer, tr, va, tmp_path / "cut", resume=True, progress=False, log=None)
    three = train(longer, tr, va, tmp_path / "three", progress=False, log=None)
    assert _same_weights(extended.net, three.net) and len(extended.history) == 3


def test_init_starts_from_given_weights_and_refuses_others(tmp_path: Path, root: Path) -> None:
    """--init (a DAgger round): the run starts from the file's weights (at a zero
    learning rate it ends with them), its digest is part of what a resume must match,
    and weights of another size or grid are refused naming the file."""
    tr, va = load_grasp_dataset(root / "train"), load_grasp_dataset(root / "val")
    small = {"channels": (2, 2, 2), "head_kernel": 3, "batch_size": 2}
    first = train(
        GraspTrainConfig(epochs=1, seed=3, lr=1e-2, **small),
        tr,
        va,
        tmp_path / "a",
        log=None,
        progress=False,
    )
    start = tmp_path / "a" / "best.safetensors"
    from heapgrasp.training.train_grasps import save_grasp_network

    weights, _ = save_grasp_network(
        first.net, tmp_path / "start.safetensors", {"input_kind": "occupancy"}
    )
    still = GraspTrainConfig(epochs=1, seed=9, lr=1e-12, **small)
    tuned = train(still, tr, va, tmp_path / "b", init=weights, progress=False, log=None)
    sa, sb = first.net.state_dict(), tuned.net.state_dict()
    assert all(torch.allclose(sa[k], sb[k], atol=1e-6) for k in sa)
    fresh = train(still, tr, va, tmp_path / "c", progress=False, log=None)
    assert not _same_weights(fresh.net, tuned.net)
    with pytest.raises(TrainSetupError, match=r"config\.init"):
        train(still, tr, va, tmp_path / "b", resume=True, progress=False, log=None)
    wider = GraspTrainConfig(epochs=1, seed=9, lr=1e-3, channels=(3, 3, 3), batch_size=2)
    with pytest.raises(TrainSetupError, match=r"start.safetensors: its network is not of the size"):
        train(wider, tr, va, tmp_path / "d", init=weights, progress=False, log=None)
    (tmp_path / "start.json").write_text(json.dumps({"input_kind": "tsdf"}))
    with pytest.raises(TrainSetupError, match=r"a network of 'tsdf' grids"):
        train(still, tr, va, tmp_path / "e", init=weights, progress=False, log=None)
    with pytest.raises(TrainSetupError, match=r"--init: .*missing.safetensors"):
        train(
            still,
            tr,
            va,
            tmp_path / "f",
            init=tmp_path / "missing.safetensors",
            progress=False,
            log=None,
        )
    assert start.exists()


def test_train_grasps_command_writes_a_network_the_planner_runs(tmp_path: Path, root: Path) -> None:
    """One epoch: checkpoint, CSV, plot, weights and card, metrics of val and test, and
    an ONNX file NetworkGraspPlanner loads and that gives PyTorch's outputs."""
    from heapgrasp.planning.grasp_network import NetworkGraspPlanner, tsdf_valid

    data = tmp_path / "data"
    for split, n, seed in (("train", 4, 1), ("val", 2, 2), ("test", 2, 3)):
        write_dataset(data / split, split=split, n=n, seed=seed, grid="tsdf")
    out = tmp_path / "net"
    args = ["grasps", "train", str(data), "--out", str(out), "--epochs", "1"]
    assert main([*args, "--batch-size", "4", "--no-progress", *TINY]) == 0
    for name in ("checkpoint.safetensors", "best.safetensors", "metrics.png"):
        assert (out / name).stat().st_size > 0, name
    rows = (out / "metrics.csv").read_text().splitlines()
    assert len(rows) == 2
    for column in ("train_loss", "val_average_precision", "val_precision_0.9", "val_recall_0.5"):
        assert column in rows[0].split(","), column
    for column in ("val_width_error_m", "val_rotation_error_deg"):
        assert column in rows[0].split(","), column
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) == {"best_epoch", "val", "test"} and metrics["test"]["grasps"] > 0
    card = json.loads((out / "grasp_network.json").read_text())
    assert card["input_kind"] == "tsdf" and card["training"]["channels"] == [2, 2, 2]
    assert card["architecture"]["head_kernel"] == 3
    net = load_grasp_network(out / "grasp_network.safetensors")
    planner = NetworkGraspPlanner(out / "grasp_network.onnx")
    assert planner.network.hparams["input_kind"] == "tsdf"
    # free space made the band in front of a surface, where VGN's mask keeps the quality
    grid = load_grasp_dataset(data / "val").grids[0]
    grid = np.where(grid == 1.0, 0.5, grid).astype(np.float32)
    volumes = planner.predict(grid, GridFrame(ORIGIN, SIZE, R))
    with torch.no_grad():
        quality, rotation, width = net(torch.from_numpy(grid)[None, None])
    # the quality kept where VGN's mask keeps it, 0 elsewhere
    valid = tsdf_valid(grid)
    assert valid.any() and (~valid).any()
    np.testing.assert_allclose(volumes.quality[valid], quality[0, 0].numpy()[valid], atol=1e-5)
    assert (volumes.quality[~valid] == 0.0).all()
    np.testing.assert_allclose(volumes.widths, width[0, 0].numpy(), atol=1e-5)
    np.testing.assert_allclose(
        volumes.quaternions, rotation[0].permute(1, 2, 3, 0).numpy(), atol=1e-5
    )


def test_train_grasps_command_errors_exit_2_naming_the_input(
    tmp_path: Path, root: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = str(tmp_path / "out")
    base = ["grasps", "train", "--out", out, "--epochs", "1", "--no-progress", *TINY]
    tr, va, te = (str(root / k) for k in ("train", "val", "test"))
    (tmp_path / "empty").mkdir()
    shared = str(write_dataset(tmp_path / "shared", split="test", objects=("train-object-1",)))
    small = str(write_dataset(tmp_path / "small", split="val", resolution=16))
    cases = [
        ([str(tmp_path / "missing")], "missing: no such directory"),
        ([str(tmp_path / "empty")], "empty: not a grasp dataset"),
        ([tr], "no 'val' grasp dataset"),
        ([va, te], "no 'train' grasp dataset"),
        ([tr, shared, va], "share objects (train-object-1)"),
        ([tr, small], "resolution = 40 vs 16"),
        ([str(root), "--resume"], "no checkpoint.safetensors"),
        ([str(root), "--device", "gpu"], "'gpu'"),
        ([str(root), "--input", "depth"], "invalid choice: 'depth'"),
        ([str(root), "--input", "tsdf"], "a dataset of 'occupancy' grids"),
        ([str(root), "--channels", "8", "0", "8"], "must be >= 1, got 0"),
        ([str(root), "--batch-size", "x"], "not an integer: 'x'"),
        ([str(root), "--lr", "-1"], "-1"),
    ]
    for extra, message in cases:
        capsys.readouterr()
        assert main([*base, *extra]) == 2, extra
        err = capsys.readouterr().err
        assert message in err, (extra, err)
        assert "Traceback" not in err
    assert not (tmp_path / "out" / "checkpoint.safetensors").exists()


def test_a_format_1_dataset_is_rewritten_with_the_palm_origin(tmp_path: Path) -> None:
    """scripts/grasp_data_v1_to_v2.py: positions move back along the approach by
    -palm_front, voxels follow them, grasps leaving the grid are dropped, the rest is
    copied; format-1 data is refused by the loader and accepted after conversion."""
    import importlib.util

    from heapgrasp.geometry.gripper import PANDA_HAND
    from scipy.spatial.transform import Rotation

    path = Path(__file__).resolve().parents[1] / "scripts" / "grasp_data_v1_to_v2.py"
    spec = importlib.util.spec_from_file_location("grasp_data_v1_to_v2", path)
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    old = write_dataset(tmp_path / "v1", n=5, shard_size=2, seed=7)
    manifest = json.loads((old / "manifest.json").read_text())
    manifest.update(version=1, complete=True)
    (old / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(GraspDataError, match="version 1"):
        load_grasp_dataset(old)
    kept = script.convert(old, tmp_path / "v2")
    new = load_grasp_dataset(tmp_path / "v2")
    before = [dict(np.load(f)) for f in sorted(old.glob("shard-*.npz"))]
    position = np.concatenate([b["grasp_position"] for b in before]).astype(np.float64)
    quat = np.concatenate([b["grasp_quat"] for b in before])
    moved = position + Rotation.from_quat(quat).as_matrix()[:, :, 2] * PANDA_HAND.palm_front
    frame = GridFrame(ORIGIN, VOXEL * R, R)
    voxel = frame.index(moved)
    inside = ((voxel >= 0) & (voxel < R)).all(axis=1)
    assert kept == len(new.label) == inside.sum() and 0 < kept < len(position)
    np.testing.assert_allclose(new.position, moved[inside], atol=1e-6)
    np.testing.assert_array_equal(new.voxel, voxel[inside])
    np.testing.assert_array_equal(new.quat, quat[inside])
    label = np.concatenate([b["grasp_label"] for b in before])
    np.testing.assert_array_equal(new.label, label[inside])
    assert script.main([str(tmp_path / "v2"), str(tmp_path / "v3")]) == 2  # not format 1
