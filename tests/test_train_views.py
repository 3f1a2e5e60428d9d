"""The view network's training (heapgrasp.training.train_views, heapgrasp views train): the
problem's symmetries proved with the exact scorer, exact resume, the metrics, and the
command's errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")

import heapgrasp as hg  # noqa: E402
import trimesh  # noqa: E402
from heapgrasp.cli import main  # noqa: E402
from heapgrasp.geometry.camera import CameraSpec  # noqa: E402
from heapgrasp.geometry.motion import ViewSphere  # noqa: E402
from heapgrasp.planning.views import OracleViewScorer, ViewContext  # noqa: E402
from heapgrasp.training.models import ViewNet  # noqa: E402
from heapgrasp.training.train_views import (  # noqa: E402
    TrainConfig,
    TrainSetupError,
    distinct_views,
    load_view_network,
    ranking_metrics,
    spearman,
    top1_regret,
    train,
)
from heapgrasp.training.view_data import (  # noqa: E402
    SYMMETRIES,
    ViewDataError,
    batch_inputs,
    concatenate,
    load_view_dataset,
    transform_grid,
    transform_scores,
)
from heapgrasp.training.view_eval import evaluate, selection_agreement  # noqa: E402

SIZE = 0.30
THETA_MAX = math.pi / 5


# --------------------------------------------------------------------------- synthetic data


def write_dataset(
    out: Path,
    *,
    split: str = "train",
    n: int = 12,
    r: int = 8,
    u: int = 8,
    v: int = 4,
    seed: int = 0,
    objects: tuple[str, ...] | None = None,
    shard_size: int = 5,
) -> Path:
    """A view dataset in the format of ``heapgrasp views data`` with random contents
    (counts, a label map that depends on the grid, poses of the sphere's candidates)."""
    g = np.random.default_rng(seed)
    out.mkdir(parents=True)
    sphere = ViewSphere.for_cube((0, 0, 0), SIZE, radius=0.33)
    cands = sphere.candidates(u, v, THETA_MAX)
    shards = {}
    for s, start in enumerate(range(0, n, shard_size)):
        m = min(shard_size, n - start)
        vis = g.integers(0, 6, (m, r, r, r)).astype(np.uint16)
        seg = np.minimum(vis, g.integers(0, 6, (m, r, r, r))).astype(np.uint16)
        region = np.ones((m, r, r), bool)
        region[: m // 2, : r // 2] = False
        # Labels that a network can learn: the mean occupancy seen from each azimuth's side.
        occ = np.divide(seg, np.maximum(vis, 1)).mean(axis=3)
        side = np.stack([np.roll(occ, i, axis=1)[:, 0, :].mean(axis=1) for i in range(u)], 1)
        scores = (side[:, :, None] * np.linspace(0.5, 1.0, v)[None, None]).astype(np.float32)
        scores -= 0.05  # a few negative labels, as eq. 14 can give
        current = cands[g.integers(0, u, m), g.integers(1, v, m)]
        target = np.full((m, 4, 4), np.nan)
        target[::2] = np.eye(4)
        target[::2, :3, 3] = [0.15, 0.15, 0.02]
        arrays = {
            "segmented": seg,
            "visible": vis,
            "region": region,
            "scores": scores,
            "current": current,
            "target": target,
            "scene_seed": np.arange(start, start + m, dtype=np.int64),
            "scene_index": np.arange(start, start + m, dtype=np.int64),
            "k": g.integers(0, 3, m).astype(np.int64),
            "scenes": np.int64(m),
            "dropped": np.int64(0),
        }
        name = f"shard-{s:05d}.npz"
        np.savez_compressed(out / name, **arrays)
        shards[name] = {"samples": m, "scenes": m, "dropped": 0}
    manifest = {
        "format": "heapgrasp-view-data",
        "version": 1,
        "split": split,
        "root_seed": seed,
        "objects": list(objects if objects is not None else (f"{split}-object-{seed}",)),
        "config": {
            "resolution": r,
            "U": u,
            "V": v,
            "lam": 0.9,
            "cube_size": SIZE,
            "radius": 0.33,
            "theta_max": THETA_MAX,
        },
        "shards": shards,
        "samples": n,
        "package_version": hg.__version__,
    }
    (out / "manifest.json").write_text(json.dumps(manifest))
    return out


@pytest.fixture
def datasets(tmp_path: Path) -> dict[str, Path]:
    return {
        "train": write_dataset(tmp_path / "train", split="train", n=12, seed=1),
        "val": write_dataset(tmp_path / "val", split="val", n=6, seed=2),
        "test": write_dataset(tmp_path / "test", split="test", n=6, seed=3),
    }


# --------------------------------------------------------------------------- symmetries

BOXES = [
    ((0.10, 0.12, 0.03), (0.06, 0.04, 0.06)),
    ((0.19, 0.15, 0.05), (0.05, 0.09, 0.10)),
    ((0.14, 0.21, 0.02), (0.08, 0.05, 0.04)),
]


def _scene(linear: np.ndarray) -> hg.MeshScene:
    """The boxes mapped by ``linear`` (3 × 3) about the cube's vertical centre axis."""
    centre = np.array([SIZE / 2, SIZE / 2, 0.0])
    scene = hg.MeshScene()
    for position, extents in BOXES:
        mesh = trimesh.creation.box(extents=extents)
        vertices = (np.asarray(mesh.vertices) + position - centre) @ linear.T + centre
        faces = np.asarray(mesh.faces)
        if np.linalg.det(linear) < 0:  # a mirror turns the faces inside out
            faces = faces[:, ::-1]
        scene.add_mesh(np.ascontiguousarray(vertices), np.ascontiguousarray(faces), np.eye(4))
    return scene


def test_quarter_turn_and_mirror_are_exact_symmetries_of_eq14() -> None:
    """The proof of the mapping the training relies on: the whole scene (meshes, camera
    pose, SfS counts) turned by +90° about the cube's vertical axis is scored by the exact
    eq. 14 as ``roll(scores, +U/4, axis=0)`` (``np.rot90(grid, 1, axes=(0, 1))``), and
    mirrored ``y → −y`` (``np.flip(grid, axis=1)``) as ``scores[(−u) mod U]``. The other
    7 maps of the group are far off."""
    r, (u, v) = 40, (40, 20)
    sphere = ViewSphere.for_cube((0, 0, 0), SIZE, radius=0.33)
    cands = sphere.candidates(u, v, THETA_MAX)
    spec = CameraSpec()
    cam = spec.core()
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    mirror = np.diag([1.0, -1.0, 1.0])
    carve_phis, carve_theta = (0.3, 1.4, 2.9), 0.5
    cur_phi, cur_theta = 0.7, 0.45

    def carve(scene: hg.MeshScene, phis: tuple[float, ...]) -> hg.OccupancyGrid:
        grid = hg.OccupancyGrid((0, 0, 0), SIZE, r)
        for phi in phis:
            pose = sphere.pose(phi, carve_theta)
            grid.integrate(scene.render_mask(cam, pose), cam, pose)
        return grid

    def score(scene: hg.MeshScene, grid: hg.OccupancyGrid, phi: float) -> np.ndarray:
        ctx = ViewContext(grid, sphere.pose(phi, cur_theta), cands, sphere, spec, 0.9, scene)
        return OracleViewScorer().scores(ctx)

    base_scene = _scene(np.eye(3))
    base = carve(base_scene, carve_phis)
    scores = score(base_scene, base, cur_phi)
    assert scores.std() > 0.05  # a map with a ranking to preserve
    seg, vis = (torch.from_numpy(c.astype(np.int64)) for c in base.counts())

    def alternatives(s: np.ndarray) -> dict[tuple[int, bool], np.ndarray]:
        return {g: transform_scores(torch.from_numpy(s), *g).numpy() for g in SYMMETRIES}

    cases = [
        ((1, False), turn, tuple(p + math.pi / 2 for p in carve_phis), cur_phi + math.pi / 2),
        ((0, True), mirror, tuple(-p for p in carve_phis), -cur_phi),
    ]
    for g, linear, phis, phi in cases:
        scene = _scene(linear)
        # The counts the transformed scene gives are the transformed counts ...
        carved = [c.astype(np.int64) for c in carve(scene, phis).counts()]
        moved = [transform_grid(c, *g).numpy() for c in (seg, vis)]
        for a, b in zip(carved, moved, strict=True):
            assert (a == b).mean() > 0.999
        grid = hg.OccupancyGrid.from_counts(
            (0, 0, 0), SIZE, *(np.ascontiguousarray(m, dtype=np.uint32) for m in moved)
        )
        # ... and its exact scores are the transformed scores.
        got = score(scene, grid, phi)
        agree = {h: float((np.abs(got - m) < 1e-3).mean()) for h, m in alternatives(scores).items()}
        expected = transform_scores(torch.from_numpy(scores), *g).numpy()
        assert max(agree, key=lambda h: agree[h]) == g
        assert all(a < 0.5 for h, a in agree.items() if h != g)
        # Exact off the pole (pixel borders aside); the pole (v = 0, θ = 0) is one camera
        # with a fixed roll and a 320 × 240 image, which a quarter turn does not map onto
        # itself: close, not equal.
        assert np.abs(got[:, 1:] - expected[:, 1:]).max() < 2e-3
        assert np.abs(got[:, 0] - expected[:, 0]).max() < 1e-2


def test_the_symmetries_are_the_square_group() -> None:
    g = torch.Generator().manual_seed(0)
    grid = torch.rand(2, 1, 8, 8, 3, generator=g)
    scores = torch.rand(2, 8, 4, generator=g)
    grids = [transform_grid(grid, *s) for s in SYMMETRIES]
    maps = [transform_scores(scores, *s) for s in SYMMETRIES]
    for items in (grids, maps):  # 8 different elements
        assert all(not torch.equal(a, b) for i, a in enumerate(items) for b in items[i + 1 :])
    assert torch.equal(transform_grid(grid, 4, False), grid)
    quarter = scores
    for _ in range(4):
        quarter = transform_scores(quarter, 1, False)
    assert torch.equal(quarter, scores)
    twice = transform_scores(transform_scores(scores, 0, True), 0, True)
    assert torch.equal(twice, scores)
    # u → (−u) mod U: row 0 stays, row 1 goes to U − 1.
    mirrored = transform_scores(scores, 0, True)
    assert torch.equal(mirrored[:, 0], scores[:, 0]) and torch.equal(mirrored[:, 7], scores[:, 1])
    assert torch.equal(transform_scores(scores, 1, False)[:, 2], scores[:, 0])  # +U/4
    with pytest.raises(ValueError, match="4 divides U"):
        transform_scores(torch.zeros(1, 6, 2), 1, False)


# --------------------------------------------------------------------------- data


def test_dataset_loads_and_inputs_are_the_grids_occupancy(datasets: dict[str, Path]) -> None:
    data = load_view_dataset(datasets["train"])
    assert len(data) == 12 and data.split == "train"
    assert data.geometry.view_shape == (8, 4) and data.geometry.resolution == 8
    x = batch_inputs(data, [0, 3], in_channels=2)
    assert x.shape == (2, 2, 8, 8, 8) and x.dtype == np.float32
    for row, i in enumerate((0, 3)):
        grid = hg.OccupancyGrid.from_counts(
            (0, 0, 0),
            SIZE,
            data.segmented[i].astype(np.uint32),
            data.visible[i].astype(np.uint32),
        )
        np.testing.assert_array_equal(x[row, 0], grid.occupancy())
        np.testing.assert_array_equal(x[row, 1], np.repeat(data.region[i][:, :, None], 8, 2))
    both = concatenate([data, load_view_dataset(datasets["train"])])
    assert len(both) == 24 and len(both.sources) == 2


def test_dataset_errors_name_the_directory(tmp_path: Path, datasets: dict[str, Path]) -> None:
    with pytest.raises(ViewDataError, match="no such directory"):
        load_view_dataset(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ViewDataError, match=r"empty: not a view dataset \(no manifest"):
        load_view_dataset(tmp_path / "empty")
    (datasets["train"] / "shard-00001.npz").unlink()
    with pytest.raises(ViewDataError, match=r"shard-00001\.npz: listed in manifest\.json but"):
        load_view_dataset(datasets["train"])
    wide = write_dataset(tmp_path / "wide", r=16)
    with pytest.raises(ViewDataError, match="resolution = 8 vs 16"):
        concatenate([load_view_dataset(datasets["val"]), load_view_dataset(wide)])


# --------------------------------------------------------------------------- training


def _same_weights(a: ViewNet, b: ViewNet) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


def test_resume_continues_exactly(tmp_path: Path, datasets: dict[str, Path]) -> None:
    """Stopped after epoch 1 and resumed, training ends with the weights, metrics and
    best epoch of an uninterrupted run."""
    tr, va = load_view_dataset(datasets["train"]), load_view_dataset(datasets["val"])
    config = TrainConfig(epochs=2, batch_size=4, seed=3)
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
    assert [{k: v for k, v in r.items() if k not in drop} for r in resumed.history] == [
        {k: v for k, v in r.items() if k not in drop} for r in whole.history
    ]
    rows = (tmp_path / "cut" / "metrics.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[0].startswith("epoch,lr_end,train_loss,val_loss")
    assert (tmp_path / "cut" / "metrics.png").stat().st_size > 0
    with pytest.raises(TrainSetupError, match="pass --resume"):
        train(config, tr, va, tmp_path / "cut", progress=False, log=None)
    other = TrainConfig(epochs=2, batch_size=4, seed=3, lr=0.01)
    with pytest.raises(TrainSetupError, match=r"config.lr: 0.001 there, 0.01 now"):
        train(other, tr, va, tmp_path / "cut", resume=True, progress=False, log=None)


def test_a_killed_training_resumes_to_the_uninterrupted_weights(
    tmp_path: Path, datasets: dict[str, Path]
) -> None:
    """SIGKILL (no clean-up at all) once the first checkpoint is on disk, then
    ``--resume``: the final weights are those of a run never stopped."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from safetensors.numpy import load_file

    def command(out: Path, *extra: str) -> list[str]:
        return [
            sys.executable, "-m", "heapgrasp", "views", "train", str(datasets["train"]),
            "--val", str(datasets["val"]), "--out", str(out), "--epochs", "6",
            "--batch-size", "4", "--seed", "3", "--workers", "1", "--no-progress", *extra,
        ]  # fmt: skip

    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    subprocess.run(command(whole), check=True, capture_output=True, env=env)
    proc = subprocess.Popen(
        command(cut), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env
    )
    try:
        while not (cut / "checkpoint.safetensors").exists() and proc.poll() is None:
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, "it finished before the kill: nothing tested"
    assert not (cut / "view_network.safetensors").exists()
    done = subprocess.run(command(cut, "--resume"), capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "resuming" in done.stdout + done.stderr
    a = load_file(str(whole / "view_network.safetensors"))
    b = load_file(str(cut / "view_network.safetensors"))
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])


def test_a_test_or_shared_object_dataset_is_never_trained_on(
    tmp_path: Path, datasets: dict[str, Path]
) -> None:
    te, va = load_view_dataset(datasets["test"]), load_view_dataset(datasets["val"])
    with pytest.raises(TrainSetupError, match="'test' dataset cannot be trained on"):
        train(TrainConfig(epochs=1), te, va, tmp_path / "out", progress=False, log=None)
    leaky = write_dataset(tmp_path / "leaky", split="val", objects=("train-object-1",))
    tr = load_view_dataset(datasets["train"])
    with pytest.raises(TrainSetupError, match="share objects"):
        train(TrainConfig(epochs=1), tr, load_view_dataset(leaky), tmp_path / "o", log=None)


def test_a_one_channel_network_leaves_region_samples_out(
    tmp_path: Path, datasets: dict[str, Path]
) -> None:
    tr, va = load_view_dataset(datasets["train"]), load_view_dataset(datasets["val"])
    assert tr.whole_grid.sum() == 7 and len(tr.for_network(2)) == 12  # shards 5, 5, 2
    lines: list[str] = []
    result = train(TrainConfig(epochs=1), tr, va, tmp_path / "o", progress=False, log=lines.append)
    assert lines[0].startswith("in_channels = 1: 5 training and 2 validation samples")
    assert len(result.history) == 1
    only_regions = tr.subset(np.flatnonzero(~tr.whole_grid))
    with pytest.raises(TrainSetupError, match="use --in-channels 2"):
        train(TrainConfig(epochs=1), only_regions, va, tmp_path / "p", progress=False, log=None)


def test_in_channels_two_reads_the_region_mask() -> None:
    net = ViewNet(8, (8, 4), in_channels=2)
    assert net.hparams()["in_channels"] == 2
    assert net(torch.zeros(3, 2, 8, 8, 8)).shape == (3, 8, 4)
    with pytest.raises(ValueError, match=r"expects a \(B, 2, 8, 8, 8\) grid"):
        net(torch.zeros(1, 1, 8, 8, 8))


def test_in_channels_three_reads_where_the_camera_is(datasets: dict[str, Path]) -> None:
    from heapgrasp.geometry.grid import GridFrame

    data = load_view_dataset(datasets["train"])
    assert len(data.for_network(3)) == len(data)  # region samples too
    x = batch_inputs(data, [0, 3], 3)
    np.testing.assert_array_equal(x[:, :2], batch_inputs(data, [0, 3], 2))
    geo = data.geometry
    frame = GridFrame((0.0, 0.0, 0.0), geo.cube_size, geo.resolution)
    for j, i in enumerate([0, 3]):
        np.testing.assert_array_equal(x[j, 2], frame.distance_field(data.current[i][:3, 3]))
    # the channel turns with the grid: the field of the camera turned by +90° about the
    # cube's axis is the turned field (so the 8 symmetries still hold)
    c = geo.cube_size / 2
    eye = data.current[0][:3, 3]
    turned_eye = (c - (eye[1] - c), c + (eye[0] - c), eye[2])
    turned = transform_grid(torch.from_numpy(x[0, 2]), 1, False).numpy()
    np.testing.assert_allclose(turned, frame.distance_field(turned_eye), atol=1e-6)
    net = ViewNet(geo.resolution, geo.view_shape, in_channels=3)
    assert net(torch.from_numpy(x)).shape == (2, *geo.view_shape)


# --------------------------------------------------------------------------- metrics


def test_metrics_on_hand_made_maps() -> None:
    g = np.random.default_rng(0)
    labels = g.normal(size=(5, 8, 4))
    labels[:, :, 0] = labels[:, :1, 0]  # the pole: one pose, one score for every u
    m = ranking_metrics(labels, labels)
    assert m["regret_mean"] == 0.0 and m["top1_exact"] == 1.0
    assert m["spearman_median"] == pytest.approx(1.0)
    monotone = ranking_metrics(np.exp(3 * labels) - 7, labels)
    assert monotone["spearman_mean"] == pytest.approx(1.0) and monotone["regret_mean"] == 0.0
    assert ranking_metrics(-labels, labels)["spearman_mean"] == pytest.approx(-1.0)
    # Constant labels have no ranking (NaN, left out); a constant prediction ranks nothing.
    rho = spearman(np.array([[1.0, 2.0, 3.0], [5.0, 5.0, 5.0]]), np.array([[0, 0, 0], [1, 2, 3.0]]))
    assert math.isnan(rho[0]) and rho[1] == 0.0
    regret = top1_regret(np.array([[0.9, 0.1, 0.2]]), np.array([[0.3, 0.5, 0.1]]))
    assert regret.tolist() == pytest.approx([0.2])
    # The pole's U copies count once.
    assert distinct_views(np.ones((2, 8, 4))).shape == (2, 1 + 8 * 3)


def test_eq18_agreement(datasets: dict[str, Path]) -> None:
    data = load_view_dataset(datasets["val"])
    cands = data.geometry.candidates()
    same = selection_agreement(data.scores, data.scores, cands, data.current, data.target, 0.35)
    assert same.tolist() == [1.0] * len(data)
    # Two maps whose best is the pole at different u: the same pose.
    a, b = np.zeros((1, 8, 4)), np.zeros((1, 8, 4))
    a[0, 2, 0], b[0, 5, 0] = 1.0, 1.0
    cur, nan = data.current[:1], np.full((1, 4, 4), np.nan)
    assert selection_agreement(a, b, cands, cur, nan, 0.0).tolist() == [1.0]
    b[0, 5, 0], b[0, 5, 1] = 0.0, 1.0
    assert selection_agreement(a, b, cands, cur, nan, 0.0).tolist() == [0.0]
    torch.manual_seed(0)
    report = evaluate(ViewNet(8, (8, 4), in_channels=2), data)
    assert report["samples"] == 6.0
    assert report["with_target"] == 4.0  # every other sample of each shard (5 + 1)
    # A 1-channel network is measured on the whole-grid samples only.
    assert evaluate(ViewNet(8, (8, 4)), data)["samples"] == 4.0
    assert {"loss", "spearman_median", "regret_mean", "eq18_match_g0", "eq18_match_g0.35"} <= set(
        report
    )


# --------------------------------------------------------------------------- command line


def test_train_views_command_writes_the_network_and_its_card(
    tmp_path: Path, datasets: dict[str, Path]
) -> None:
    out = tmp_path / "net"
    args = [
        "views", "train", str(datasets["train"]), "--val", str(datasets["val"]),
        "--test", str(datasets["test"]), "--out", str(out), "--epochs", "1",
        "--batch-size", "6", "--no-progress", "--in-channels", "2",
    ]  # fmt: skip
    assert main(args) == 0
    card = json.loads((out / "view_network.json").read_text())
    assert card["architecture"]["in_channels"] == 2
    assert card["data"]["train"][0]["samples"] == 12 and card["training"]["epochs"] == 1
    assert card["machine"]["torch"] == torch.__version__
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) == {"best_epoch", "val", "test"}
    assert metrics["test"]["samples"] == 6.0
    net = load_view_network(out / "view_network.safetensors")
    assert net.in_channels == 2 and net.view_shape == (8, 4)


def test_train_views_command_errors_exit_2_naming_the_input(
    tmp_path: Path, datasets: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    out = str(tmp_path / "out")
    base = ["views", "train", "--out", out, "--epochs", "1", "--no-progress"]
    tr, va, te = (str(datasets[k]) for k in ("train", "val", "test"))
    wide = str(write_dataset(tmp_path / "wide", split="val", r=16))
    (tmp_path / "empty").mkdir()
    cases = [
        ([str(tmp_path / "missing"), "--val", va], "missing: no such directory"),
        ([str(tmp_path / "empty"), "--val", va], "empty: not a view dataset"),
        ([te, "--val", va], "'test' dataset; only 'train' datasets"),
        ([tr, "--val", te], "validation needs a 'val' dataset"),
        ([tr, "--val", va, "--test", va], "not a 'test' one"),
        ([tr, "--val", wide], "resolution = 8 vs 16"),
        ([tr, "--val", va, "--resume"], "no checkpoint.safetensors"),
        ([tr, "--val", va, "--device", "gpu"], "'gpu'"),
        ([tr, "--val", va, "--in-channels", "4"], "invalid choice: 4"),
        ([tr, "--val", va, "--lr", "-1"], "-1"),
    ]
    for extra, message in cases:
        capsys.readouterr()
        assert main([*base, *extra]) == 2, extra
        assert message in capsys.readouterr().err, extra
    assert not (tmp_path / "out" / "checkpoint.safetensors").exists()
