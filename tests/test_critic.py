"""The learned grasp critic: features in the grasp frame, the model, its file, its data."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import box_model
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.protocol import StopReason, run_clutter_removal
from heapgrasp.loop.stages import make_critic
from heapgrasp.planning.critic import (
    ARRAYS,
    CROP_SHAPE,
    N_SCALARS,
    GraspCritic,
    candidate_features,
    crop_in_grasp_frame,
    flip_pose,
    view_features,
)
from heapgrasp.planning.volumes import GraspCandidate
from heapgrasp.sim.build import sim_pipeline
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.world import SimWorld
from heapgrasp.training.train_critic import (
    Design,
    auc,
    cross_validate,
    design_matrix,
    fit_critic,
    fit_logistic,
    hull_kind,
    phase_picks,
    save_critic,
)

FRAME = GridFrame((0.0, 0.0, 0.0), 0.30, 40)
N_CROP = int(np.prod(CROP_SHAPE))


def top_down(position: np.ndarray, yaw: float = 0.0) -> np.ndarray:
    """TCP pose at ``position`` approaching straight down, fingers closing along
    (cos yaw, sin yaw)."""
    c, s = np.cos(yaw), np.sin(yaw)
    pose = np.eye(4)
    pose[:3, 1] = [c, s, 0.0]
    pose[:3, 2] = [0.0, 0.0, -1.0]
    pose[:3, 0] = np.cross(pose[:3, 1], pose[:3, 2])
    pose[:3, 3] = position
    return pose


def box_grid() -> np.ndarray:
    g = np.zeros((40, 40, 40), dtype=np.float32)
    g[17:23, 15:25, 0:8] = 1.0  # 4.5 × 7.5 × 6 cm
    return g


def test_crop_reads_the_grid_in_the_grasp_frame() -> None:
    g = box_grid()
    centre = FRAME.centers([19, 19, 5])
    crop = crop_in_grasp_frame(g, FRAME, top_down(centre)).reshape(CROP_SHAPE)
    # Lattice index (3, 6, 6) is the TCP: inside the box.
    assert crop[3, 6, 6] == 1.0
    # Behind the TCP (toward the palm, z index < 6) is above the box: free.
    assert crop[3, 6, 0] == 0.0
    # Beyond the TCP lies the table: occupied below the grid's bottom face.
    assert crop[3, 6, -1] == 1.0
    # Unyawed the fingers close along x, across the box's short side; yawed along y.
    yawed = crop_in_grasp_frame(g, FRAME, top_down(centre, yaw=np.pi / 2)).reshape(CROP_SHAPE)
    assert crop[3, 6 + 5, 6] == 0.0 and yawed[3, 6 + 5, 6] == 1.0


def test_flipped_pose_mirrors_the_crop() -> None:
    g = box_grid()
    pose = top_down(FRAME.centers([18, 17, 4]), yaw=0.3)
    a = crop_in_grasp_frame(g, FRAME, pose).reshape(CROP_SHAPE)
    b = crop_in_grasp_frame(g, FRAME, flip_pose(pose)).reshape(CROP_SHAPE)
    assert a.sum() > 0
    np.testing.assert_array_equal(a[::-1, ::-1, :], b)


def test_crop_rejects_a_bad_pose() -> None:
    with pytest.raises(ValueError, match="pose"):
        crop_in_grasp_frame(box_grid(), FRAME, np.full((4, 4), np.nan))


def test_view_features_tell_one_sided_views_from_views_all_around() -> None:
    pose = top_down(np.array([0.15, 0.15, 0.03]))
    ring = [
        [0.15 + 0.3 * np.cos(a), 0.15 + 0.3 * np.sin(a), 0.3]
        for a in np.linspace(0, 2 * np.pi, 12, endpoint=False)
    ]
    one_side = [[0.15, 0.15 - 0.3, 0.3 + 0.01 * k] for k in range(12)]
    around, side = view_features(pose, ring), view_features(pose, one_side)
    assert around[3] < 0.05 and side[3] > 0.99
    with pytest.raises(ValueError, match="camera"):
        view_features(pose, np.zeros((0, 3)))


def test_candidate_features_have_the_documented_layout() -> None:
    g = box_grid()
    pose = top_down(FRAME.centers([19, 19, 5]))
    f = candidate_features(g, g, FRAME, pose, 0.05, 0.7, [[0.15, 0.15, 0.5]])
    assert f.shape == (2 * N_CROP + N_SCALARS,)
    assert f[2 * N_CROP] == 0.7  # the planner's score first
    with pytest.raises(ValueError, match="shape"):
        candidate_features(g, g[:20], FRAME, pose, 0.05, 0.7, [[0.15, 0.15, 0.5]])


def test_logistic_regression_separates_a_linear_rule() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, 3))
    y = (x[:, 0] - 2 * x[:, 1] > 0).astype(float)
    w = fit_logistic(x, y, l2=0.1)
    pred = (np.hstack([x, np.ones((400, 1))]) @ w) > 0
    assert np.mean(pred == (y > 0.5)) > 0.95
    assert w[0] > 0 > w[1]
    with pytest.raises(ValueError, match="len"):
        fit_logistic(x, y[:10])


def test_auc() -> None:
    assert auc([0.1, 0.2, 0.8, 0.9], [0, 0, 1, 1]) == 1.0
    assert auc([0.9, 0.8, 0.2, 0.1], [0, 0, 1, 1]) == 0.0
    assert auc([0.5, 0.5], [0, 1]) == 0.5
    assert np.isnan(auc([0.5, 0.5], [1, 1]))


def synthetic_critic(rng: np.random.Generator) -> tuple[GraspCritic, np.ndarray, np.ndarray]:
    n = 2 * N_CROP + N_SCALARS
    x = rng.random((200, n)).round()
    x[:, 2 * N_CROP] = rng.random(200)
    y = (x[:, 2 * N_CROP] > 0.5).astype(float)
    return fit_critic(x, y, components=4, l2=1.0), x, y


def test_critic_learns_and_round_trips_through_its_file(tmp_path: Path) -> None:
    critic, x, y = synthetic_critic(np.random.default_rng(1))
    assert critic.model == "linear"
    p = critic.probability(x)
    assert auc(p, y) > 0.95
    path = tmp_path / "critic.onnx"
    save_critic(
        critic, path, command="heapgrasp critic train d --out critic.onnx", metadata={"a": 1}
    )
    back = GraspCritic.load(path)
    np.testing.assert_array_equal(back.probability(x), p)  # the same graph, the same runtime
    assert back.metadata["command"].startswith("heapgrasp critic train")
    assert back.metadata["a"] == 1
    assert back.network.hparams["components"] == 4


def test_critic_file_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nothere"):
        GraspCritic.load(tmp_path / "nothere.onnx")
    bad = tmp_path / "bad.npz"  # the former format: convert it first
    np.savez(bad, something=np.zeros(3))
    with pytest.raises(ValueError, match=r"bad\.npz: a zip archive .*not an ONNX model"):
        GraspCritic.load(bad)
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"not a model")
    with pytest.raises(ValueError, match=r"junk\.onnx: not a valid ONNX model"):
        GraspCritic.load(junk)


def test_critic_arrays_must_fit_together() -> None:
    from heapgrasp.training.critic_net import critic_onnx

    n = 2 * N_CROP + N_SCALARS
    mean, scale = np.zeros(n), np.ones(n)
    hp = {"threshold": 0.5, "candidate_epsilon": 0.2}
    with pytest.raises(ValueError, match="fit together"):
        critic_onnx(
            mean,
            scale,
            components=np.zeros((4, 2 * N_CROP)),
            weights=np.zeros(15),
            hparams=hp,
            provenance={},
        )
    with pytest.raises(ValueError, match="scale > 0"):
        critic_onnx(mean, scale * 0, components=None, weights=None, hparams=hp, provenance={})
    critic, _, _ = synthetic_critic(np.random.default_rng(2))
    with pytest.raises(ValueError, match="threshold"):
        GraspCritic(critic.network, 1.5)
    with pytest.raises(ValueError, match="candidate_epsilon"):
        GraspCritic(critic.network, 0.5, float("nan"))


def test_cnn_critic_runs_in_onnxruntime_as_in_torch_and_round_trips(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    from heapgrasp.training.critic_net import ConvCritic, _torch_module, fit_conv

    rng = np.random.default_rng(3)
    _, x, y = synthetic_critic(rng)
    critic = fit_critic(x, y, model="cnn", epochs=3, seed=1)
    assert critic.model == "cnn" and critic.network.hparams["hidden"] == 64
    mean, scale = x.mean(axis=0), x.std(axis=0)
    scale[scale < 1e-6] = 1.0
    z = (x - mean) / scale
    weights = fit_conv(z, y, epochs=3, seed=1)
    again = fit_conv(z, y, epochs=3, seed=1)
    for name in ARRAYS:  # deterministic for a seed
        np.testing.assert_array_equal(getattr(weights, name), getattr(again, name))
    # The graph is PyTorch's forward pass (same layouts, pooling bins, flattening).
    net = _torch_module(8, 16, 64).double().eval()
    layers = {"conv1": "conv1", "conv2": "conv2", "fc1": "fc1", "fc2": "fc2"}
    state = {
        f"{layer}.{kind}": torch.from_numpy(getattr(weights, f"{name}_{kind[0]}"))
        for layer, name in layers.items()
        for kind in ("weight", "bias")
    }
    net.load_state_dict(state)
    with torch.no_grad():
        expected = 1.0 / (1.0 + np.exp(-np.clip(net(torch.from_numpy(z)).numpy(), -30, 30)))
    p = critic.probability(x)
    np.testing.assert_allclose(p, expected, atol=1e-5)
    assert np.all((p > 0) & (p < 1))
    # Its file gives the same probabilities back.
    path = tmp_path / "cnn.onnx"
    save_critic(critic, path, command="heapgrasp critic train d --model cnn --out cnn.onnx")
    back = GraspCritic.load(path)
    assert back.model == "cnn" and back.metadata["command"].endswith("cnn.onnx")
    np.testing.assert_array_equal(back.probability(x), p)
    with pytest.raises(ValueError, match="fc2_w"):
        ConvCritic(*(getattr(weights, n) if n != "fc2_w" else np.zeros((2, 64)) for n in ARRAYS))
    with pytest.raises(ValueError, match="model"):
        fit_critic(x, y, model="forest")


def test_phase_picks_on_hand_made_phases() -> None:
    # Two phases of one scene, three candidates each (rows come in flip pairs).
    labels = np.repeat([1.0, 0.0, 0.0, 0.0, 0.0, 1.0], 2)
    score = np.repeat([0.5, 0.9, 0.1, 0.3, 0.45, 0.2], 2)
    design = Design(
        np.zeros((12, 1)),
        labels,
        np.zeros(12, dtype=np.int64),
        np.repeat([0, 0, 0, 1, 1, 1], 2),
        score,
        np.array(["heapgrasp_top"] * 12),
    )
    prob = np.array([0.9, 0.2, 0.1, 0.5, 0.4, 0.8])
    out = phase_picks(design, prob, threshold=0.6, epsilon=0.4)["heapgrasp_top_start"]
    assert out["phases"] == 2
    assert out["planner_pick_success"] == 0.0  # 0.9 then 0.45: both failed
    assert out["critic_pick_success"] == 1.0  # 0.9 then 0.8: both held
    assert out["planner_kept_success"] == pytest.approx(0.25)  # (1/2 + 0/1) / 2
    assert out["planner_no_candidate"] == 0 and out["critic_no_candidate"] == 0
    assert out["any_candidate_success"] == 1.0
    strict = phase_picks(design, prob, threshold=0.85, epsilon=0.95)["heapgrasp_top_start"]
    assert strict["planner_no_candidate"] == 2 and strict["critic_no_candidate"] == 1
    assert strict["planner_pick_success"] is None


def test_hull_kind_tells_early_stopped_hulls_apart() -> None:
    assert hull_kind({}) == "heapgrasp"  # files written before --method existed
    assert hull_kind({"method": np.str_("no-vp")}) == "no-vp"
    stop = json.dumps({"gamma2": 0.0, "stop_below": 0.02})
    assert hull_kind({"method": np.str_("heapgrasp"), "overrides": np.str_(stop)}) == (
        "heapgrasp-stop"
    )
    assert hull_kind({"method": "heapgrasp", "overrides": json.dumps({"stop_below": 0})}) == (
        "heapgrasp"
    )
    assert hull_kind({"method": "heapgrasp", "overrides": "{}"}) == "heapgrasp"


def candidates_on_the_box() -> list[GraspCandidate]:
    out = []
    for k, (i, j) in enumerate([(19, 19), (19, 17), (30, 30)]):
        pose = top_down(FRAME.centers([i, j, 5]))
        out.append(GraspCandidate(pose, 0.06, 0.9 - 0.1 * k, (i, j, 5)))
    return out


def test_rescore_puts_the_probability_in_place_of_the_score() -> None:
    critic, _, _ = synthetic_critic(np.random.default_rng(3))
    g = box_grid()
    cands = candidates_on_the_box()
    cams = [[0.15, 0.0, 0.4]]
    prob = critic.score_candidates(cands, g, g, FRAME, cams)
    assert prob.shape == (3,) and np.all((prob >= 0) & (prob <= 1))
    critic.threshold = 0.0
    ranked = critic.rescore(cands, g, g, FRAME, cams)
    assert [c.score for c in ranked] == sorted(prob.tolist(), reverse=True)
    assert {c.index for c in ranked} == {c.index for c in cands}
    critic.threshold = float(np.median(prob))
    kept = critic.rescore(cands, g, g, FRAME, cams)
    assert all(c.score >= critic.threshold for c in kept) and 1 <= len(kept) <= 2
    critic.threshold = 1.0
    assert critic.rescore(cands, g, g, FRAME, cams) == []  # logits are clipped: p < 1
    assert critic.rescore([], g, g, FRAME, cams) == []


def test_config_and_builder_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="grasp_critic"):
        RunConfig(method="vgn", grasp_critic="default")
    with pytest.raises(ConfigError, match="grasp_critic"):
        RunConfig(grasp_critic="")
    assert make_critic(RunConfig(grasp_critic="none")) is None
    with pytest.raises(ConfigError, match="unknown parameter 'critic_threshold'"):
        RunConfig.from_mapping({"critic_threshold": 0.5})  # retired: docs/experiments.md
    # A missing file is a bad setting, as a missing network weights file is.
    with pytest.raises(ConfigError, match=r"grasp_critic: .*not found: .*missing\.npz"):
        make_critic(RunConfig(grasp_critic=str(tmp_path / "missing.npz")))


def test_auto_critic_applies_where_the_shipped_weights_were_trained() -> None:
    for method in ("heapgrasp", "no-vp", "hemisphere6"):
        assert RunConfig(method=method).critic == "default"
    auto = make_critic(RunConfig())
    assert auto is not None and auto.threshold == pytest.approx(0.6)
    # vgn (TSDF) and the network planner are not what the weights were trained on.
    assert RunConfig(method="vgn").critic is None
    assert make_critic(RunConfig(method="vgn")) is None
    assert RunConfig(grasp_planner="network").critic is None
    assert RunConfig(grasp_critic="none").critic is None
    # a critic file is kept as an absolute path (a run is resumed from anywhere)
    assert RunConfig(grasp_critic="x.npz", method="no-vp").critic == str(Path("x.npz").absolute())


def test_shipped_critic_loads_with_its_command_and_measurements() -> None:
    critic = make_critic(RunConfig(grasp_critic="default"))
    assert critic is not None
    meta = critic.metadata
    assert meta["command"].startswith("heapgrasp critic train")
    cv = meta["cross_validation"]
    assert 0.5 < cv["auc_critic"] <= 1.0
    assert cv["candidates"] > 500


def test_loop_with_the_shipped_critic_grasps_a_lone_box(tmp_path: Path) -> None:
    model = box_model(tmp_path, (0.05, 0.04, 0.07))
    config = RunConfig(objects=1, category="opaque", grasp_critic="default")
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(config, world)
        assert pipeline.critic is not None
        phases, reason = run_clutter_removal(pipeline.robot, pipeline.plan, truth=pipeline.truth)
    assert reason == StopReason.CLEARED, [p.to_dict()["outcome"] for p in phases]


def test_data_phases_can_be_steered_by_a_critic(tmp_path: Path) -> None:
    from heapgrasp.data.critic import CriticDataConfig

    assert CriticDataConfig().run_config(0).critic is None  # the planner alone by default
    steered = CriticDataConfig(critic="default")
    assert steered.run_config(0).critic == "default"
    assert steered.run_config(1).start != steered.run_config(0).start
    with pytest.raises(FileNotFoundError, match=r"nope\.npz"):
        CriticDataConfig(critic=str(tmp_path / "nope.npz"))
    with pytest.raises(ValueError, match="auto"):
        CriticDataConfig(critic="auto")


def test_test_split_data_measures_but_never_trains(tmp_path: Path) -> None:
    from heapgrasp.cli import main
    from heapgrasp.data.critic import CriticDataConfig, load_dataset

    with pytest.raises(ValueError, match="split"):
        CriticDataConfig(split="val")
    with pytest.raises(ValueError, match="object_seeds"):
        CriticDataConfig(split="test", object_seeds=(1,))
    assert CriticDataConfig(split="test").run_config(0).split == "test"
    data = tmp_path / "data"
    data.mkdir()
    n = 2
    scene = {
        "seed": np.int64(0),
        "split": np.str_("test"),
        "phase": np.zeros(n, np.int64),
        "outcome": np.array(["success", "empty"]),
    }
    np.savez(data / "scene_000000.npz", **scene)
    assert load_dataset([data / "scene_000000.npz"])[0]["split"] == "test"
    with pytest.raises(ValueError, match=r"scene_000000\.npz holds test-split objects"):
        load_dataset([data / "scene_000000.npz"], training=True)
    assert main(["critic", "train", str(data), "--out", str(tmp_path / "c.onnx")]) == 2
    assert not (tmp_path / "c.onnx").exists()


def test_data_phases_take_other_run_settings(tmp_path: Path) -> None:
    from heapgrasp.cli import main
    from heapgrasp.data.critic import CriticDataConfig, scene_data
    from heapgrasp.loop.config import ConfigError

    config = CriticDataConfig(
        scenes=1, objects=2, max_phases=1, max_candidates=1, overrides=(("L", 2),)
    )
    assert config.run_config(0).L == 2 and config.run_config(1).L == 2
    assert config.run_config(0).start == "above"  # the data's own start stays
    assert json.loads(str(scene_data(config, 0)["overrides"])) == {"L": 2}
    with pytest.raises(ValueError, match="method, seed set by the critic data's own"):
        CriticDataConfig(overrides=(("seed", 3), ("method", "vgn")))
    with pytest.raises(ConfigError, match="nope"):
        CriticDataConfig(overrides=(("nope", 1),))
    with pytest.raises(ConfigError, match="L"):
        CriticDataConfig(overrides=(("L", "three"),))
    out = tmp_path / "d"
    assert (
        main(["critic", "data", "--set", "nope=1", "--out", str(out)]) == 2
    )  # a configuration error
    assert main(["critic", "data", "--set", "L", "--out", str(out)]) == 2
    assert not out.exists()


@pytest.mark.parametrize("seeds", [(0,), (-1,), (2, 2), (True,)])
def test_data_object_seeds_are_checked(seeds: tuple[int, ...]) -> None:
    from heapgrasp.data.critic import CriticDataConfig

    with pytest.raises(ValueError, match="object_seeds"):
        CriticDataConfig(object_seeds=seeds)


def test_data_with_extra_objects_never_draws_a_test_object(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from heapgrasp.cli import main
    from heapgrasp.data.critic import CriticDataConfig, scene_data
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.sim.build import object_library

    test_names = {m.name for m in object_library(RunConfig()).models(split="test")}
    config = CriticDataConfig(scenes=1, objects=5, max_phases=1, max_candidates=1)
    wide = CriticDataConfig(scenes=1, objects=5, max_phases=1, max_candidates=1, object_seeds=(7,))
    names = {str(n) for n in scene_data(config, 0)["objects"]}
    s = scene_data(wide, 0)
    wide_names = {str(n) for n in s["objects"]}
    assert len(names) >= 3 and len(wide_names) >= 3  # a pile may drop one off the grid
    assert not (names | wide_names) & test_names
    assert all(n.startswith("procedural/") for n in names | wide_names)
    assert not any(n.startswith("procedural/seed7/") for n in names)
    # 16 x 5 new objects beside the library's 69 train objects: a 5-object draw
    # without any of them has probability C(69,5)/C(149,5) < 0.03.
    assert any(n.startswith("procedural/seed7/") for n in wide_names)
    assert s["object_seeds"].tolist() == [7]
    assert main(["critic", "data", "--object-seeds", "0,1", "--out", "unused"]) == 2
    assert "seeds must be integers >= 1" in capsys.readouterr().err


def test_data_of_one_scene_is_consistent_and_trains(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from heapgrasp.cli import main
    from heapgrasp.data.critic import CriticDataConfig, scene_data

    config = CriticDataConfig(scenes=1, objects=2, max_phases=1, max_candidates=3)
    s = scene_data(config, 0)
    n = len(s["phase"])
    assert n >= 1 and s["pose"].shape == (n, 4, 4)
    assert s["grasp_input"].shape == (1, 40, 40, 40)
    assert s["camera_counts"].sum() == len(s["camera_positions"]) > 10
    assert set(s["outcome"]) <= {"success", "empty", "collision", "unreachable"}
    assert str(s["critic"]) == "none"
    # Five copies of the scene make a design for 5-fold cross-validation.
    design = design_matrix([s] * 5, FRAME)
    assert len(design) == 5 * n and design.features.shape[0] == 10 * n
    if 0 < design.labels.mean() < 1:
        report = cross_validate(design, components=2, l2=10.0, thresholds=[0.5])  # linear
        assert report["candidates"] == 5 * n
    # The command line: an empty folder is an error; five scene files make a critic.
    data = tmp_path / "data"
    data.mkdir()
    assert main(["critic", "train", str(data), "--out", str(tmp_path / "c.onnx")]) == 2
    for k in range(5):  # both classes, whatever happened in the simulator
        labelled = dict(s, outcome=np.full(n, "success" if k % 2 else "empty"))
        np.savez(data / f"scene_{k:06d}.npz", **labelled)
    out = tmp_path / "c.onnx"
    assert main(["critic", "train", str(data), "--out", str(out), "--components", "2"]) == 0
    critic = GraspCritic.load(out)
    assert critic.metadata["scenes"] == 5
    assert critic.metadata["command"].startswith("heapgrasp critic train")
    assert (tmp_path / "c.json").is_file()
    # critic eval scores the files without refitting: the trained critic separates them.
    capsys.readouterr()
    assert main(["critic", "eval", str(out), str(data), "--report-thresholds", "0.5"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["candidates"] == 5 * n and report["scenes"] == 5
    assert report["success_fraction"] == pytest.approx(0.4)  # files 1 and 3 held
    # The copies have the same features, so no critic can tell them apart: AUC 0.5.
    assert report["auc_critic"] == pytest.approx(0.5)
    assert set(report["picks"]) == {"0.5", f"{critic.threshold:g}"}
    assert main(["critic", "eval", str(out), str(tmp_path / "empty")]) == 2


def test_the_critic_scores_the_candidates_wherever_grasps_are_planned(tmp_path: Path) -> None:
    model = box_model(tmp_path, (0.05, 0.04, 0.07))
    config = RunConfig(objects=1, category="opaque", grasp_critic="default")
    critic = make_critic(config)
    assert critic is not None
    critic.threshold = 0.0  # keep every candidate, to compare them with the plain ones
    with SimWorld(ObjectLibrary([model]), seed=0) as world:
        world.reset(layout="packed", n_objects=1, category="opaque", seed=0, models=[model])
        pipeline = sim_pipeline(config, world, critic=critic)
        plain = sim_pipeline(config.replace({"grasp_critic": "none"}), world)
        frames = [world.capture(pipeline.initial_pose(), pipeline.camera)]
        pipeline.perception.update(frames)
        plain.perception.update(frames)
        scored = pipeline.grasp_candidates()
        reference = plain.grasp_candidates()
    assert reference, "the lone box must have candidates"
    # The critic's probabilities are the scores (any order of them).
    assert {c.index for c in scored} >= {c.index for c in reference}
    assert [c.score for c in scored] == sorted((c.score for c in scored), reverse=True)
    assert [c.score for c in scored] != [c.score for c in reference]
