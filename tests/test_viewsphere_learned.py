"""Seed 001's learned viewsphere policies: the state, policy files, the paths dataset and
the trainers (viewsphere.learned, viewsphere.data, viewsphere.training)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from heapgrasp.data import shards
from heapgrasp.data.shards import generate
from heapgrasp.inference import OnnxNetwork
from heapgrasp.inference.errors import WeightsError
from heapgrasp.viewsphere import data as vp
from heapgrasp.viewsphere.grasps import VIEWSPHERE_CAMERA
from heapgrasp.viewsphere.heuristics import ViewsphereScorer
from heapgrasp.viewsphere.learned import (
    N_FEATURES,
    LearnedPolicy,
    policy_onnx,
    state_features,
)
from heapgrasp.viewsphere.policies import ViewState
from heapgrasp.viewsphere.sphere import DIRECTIONS, DiscreteViewsphere, SpherePose
from heapgrasp.viewsphere.training import (
    DqnConfig,
    fold_linear,
    train_dqn,
    train_linear,
    train_mlp,
)

SPHERE = DiscreteViewsphere()
SCORER = ViewsphereScorer(SPHERE, VIEWSPHERE_CAMERA)


def _turn(points: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return points @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T


def test_the_state_turns_with_the_camera():
    rng = np.random.default_rng(0)
    obj = rng.uniform([-0.05, -0.03, 0.0], [0.05, 0.03, 0.08], (300, 3))
    unexplored = rng.uniform([-0.08, -0.08, 0.0], [0.08, 0.08, 0.1], (2000, 3))
    pose = SpherePose(0.3, 0.6)
    x = state_features(obj, unexplored, pose, SPHERE)
    assert x.shape == (N_FEATURES,) and x.dtype == np.float32
    assert x[:25].max() == pytest.approx(obj[:, 2].max(), abs=1e-6)
    assert x[25:50].sum() == pytest.approx(1.0, abs=1e-5)
    assert tuple(x[-2:]) == pytest.approx((0.6, 0.3))
    # The scene and the camera turned together: the same grids.
    turned = state_features(
        _turn(obj, 1.1), _turn(unexplored, 1.1), SpherePose(0.3 + 1.1, 0.6), SPHERE
    )
    np.testing.assert_allclose(turned[:50], x[:50], atol=1e-5)
    # The camera alone turned: other grids.
    assert not np.allclose(
        state_features(obj, unexplored, SpherePose(1.4, 0.6), SPHERE)[:50], x[:50]
    )
    empty = state_features(np.zeros((0, 3)), unexplored, pose, SPHERE)
    assert not empty[:50].any()


def _one_hot_policy(direction: int) -> bytes:
    w = np.zeros((8, N_FEATURES))
    b = np.zeros(8)
    b[direction] = 1.0
    return policy_onnx([(w, b)], hparams={"model": "pca-lr"}, provenance={"test": True})


def test_a_policy_file_runs_and_takes_its_best_valid_direction(tmp_path: Path):
    path = tmp_path / "p.onnx"
    path.write_bytes(_one_hot_policy(DIRECTIONS.index("S")))
    policy = LearnedPolicy.from_file(path, SCORER)
    assert policy.name == "pca-lr"
    obj = np.random.default_rng(1).uniform(-0.03, 0.03, (100, 3)) + np.array([0, 0, 0.04])
    state = ViewState(SpherePose(0.0, 0.5), (SpherePose(0.0, 0.5),), 0, lambda p: (obj, obj))
    assert policy.choose(state) == DIRECTIONS.index("S")
    # South of 80° is off the sphere: the best valid direction instead.
    low = SpherePose(0.0, math.radians(80.0))
    assert policy.choose(ViewState(low, (low,), 0, lambda p: (obj, obj))) != DIRECTIONS.index("S")


def test_a_policy_does_not_step_back_onto_a_view_it_has_taken(tmp_path: Path):
    # Its state holds no history: scored alone, it would go back and forth (N, S, N, …).
    north, south = DIRECTIONS.index("N"), DIRECTIONS.index("S")
    w = np.zeros((8, N_FEATURES))
    b = np.arange(8, dtype=float)  # the last directions score best …
    b[south], b[north] = 10.0, 9.0  # … and S best of all, then N
    path = tmp_path / "p.onnx"
    path.write_bytes(policy_onnx([(w, b)], hparams={"model": "pca-lr"}, provenance={}))
    policy = LearnedPolicy.from_file(path, SCORER)
    obj = np.random.default_rng(1).uniform(-0.03, 0.03, (100, 3)) + np.array([0, 0, 0.04])
    start = SpherePose(0.0, 0.5)
    _, below = SPHERE.move(start, south)
    # Fresh, it steps south; having come from the south, it does not step back there.
    assert policy.choose(ViewState(start, (start,), 0, lambda p: (obj, obj))) == south
    back = ViewState(start, (below, start), 1, lambda p: (obj, obj))
    assert policy.choose(back) == north  # the next-best, a new view
    # The same from below the start: N (back to it) would be best, S is the new best.
    b[north], b[south] = 10.0, 9.0
    path.write_bytes(policy_onnx([(w, b)], hparams={"model": "pca-lr"}, provenance={}))
    policy = LearnedPolicy.from_file(path, SCORER)
    went = ViewState(below, (start, below), 1, lambda p: (obj, obj))
    assert policy.choose(went) == south
    # Where every step returns to a view taken, it still moves: the best of them.
    ring = tuple(SPHERE.move(below, d)[1] for d in range(8))
    assert policy.choose(ViewState(below, (*ring, below), 8, lambda p: (obj, obj))) == north


def test_bad_policy_layers_and_files_are_refused(tmp_path: Path):
    with pytest.raises(ValueError, match="8 scores"):
        policy_onnx([(np.zeros((4, N_FEATURES)), np.zeros(4))], hparams={}, provenance={})
    with pytest.raises(ValueError, match="layer 1"):
        policy_onnx(
            [(np.zeros((16, N_FEATURES)), np.zeros(16)), (np.zeros((8, 15)), np.zeros(8))],
            hparams={},
            provenance={},
        )
    with pytest.raises(ValueError, match="NaN"):
        policy_onnx([(np.full((8, N_FEATURES), np.nan), np.zeros(8))], hparams={}, provenance={})
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(_one_hot_policy(0)[:-50])
    with pytest.raises(WeightsError, match=str(bad)):
        LearnedPolicy.from_file(bad, SCORER)
    small = tmp_path / "small.onnx"
    small.write_bytes(
        policy_onnx([(np.zeros((8, 10)), np.zeros(8))], hparams={"model": "x"}, provenance={})
    )
    with pytest.raises(ValueError, match="10 features"):
        LearnedPolicy.from_file(small, SCORER)


def test_the_folded_layer_is_the_pipeline():
    from sklearn.decomposition import PCA
    from sklearn.linear_model import LogisticRegression
    from sklearn.preprocessing import StandardScaler

    rng = np.random.default_rng(0)
    x = rng.normal(size=(300, 12)) * rng.uniform(0.1, 5, 12) + rng.normal(size=12)
    y = rng.choice([0, 2, 5, 7], 300)
    scaler = StandardScaler().fit(x)
    pca = PCA(n_components=0.85).fit(scaler.transform(x))
    z = pca.transform(scaler.transform(x))
    clf = LogisticRegression(max_iter=2000).fit(z, y)
    w, b = fold_linear(
        scaler.mean_,
        scaler.scale_,
        pca.mean_,
        pca.components_,
        clf.coef_,
        clf.intercept_,
        clf.classes_,
    )
    np.testing.assert_allclose((x @ w.T + b)[:, clf.classes_], clf.decision_function(z), atol=1e-8)
    assert ((x @ w.T + b)[:, [1, 3, 4, 6]] < -1e3).all()  # directions never seen


def _fake_sample(config: Any, index: int) -> dict[str, Any] | None:
    """A paths sample whose label is readable from its state (index 7: dropped)."""
    if index == 7:
        return None
    rng = np.random.default_rng(index)
    label = index % 4 * 2
    state = rng.normal(size=N_FEATURES).astype(np.float32)
    state[label] += 4.0
    lengths = np.zeros(8, dtype=np.int64)
    lengths[label] = 1
    lengths[(label + 1) % 8] = 3
    return {
        "state": state,
        "label": label,
        "lengths": lengths,
        "object": 0,
        "yaw": 0.0,
        "start": (0.0, 0.5),
        "prefix": 0,
        "k": index,
    }


def test_paths_datasets_train_pca_policies(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(vp, "scene_sample", _fake_sample)
    train, val = tmp_path / "train", tmp_path / "val"
    manifest = generate(vp.ViewspherePathsConfig(scenes=60, shard_size=25), train, progress=False)
    assert manifest["samples"] == 59 and manifest["dropped"] == 1 and manifest["complete"]
    assert manifest["objects"] == list(vp.SUPERVISED_OBJECTS)
    generate(vp.ViewspherePathsConfig(scenes=30, root_seed=1, shard_size=30), val, progress=False)
    for kind in ("lr", "lda"):
        out = tmp_path / kind
        metrics = train_linear(kind, [train], [val], out)
        assert metrics["val_top_accuracy"] > 0.9 and metrics["sklearn_agreement"] == 1.0
        assert json.loads((out / "metrics.json").read_text())["model"] == f"pca-{kind}"
        assert (out / "metrics.png").is_file()
        policy = LearnedPolicy.from_file(out / f"viewsphere_pca_{kind}.onnx", SCORER)
        assert policy.name == f"pca-{kind}"
    with pytest.raises(FileNotFoundError, match="manifest"):
        train_linear("lr", [tmp_path / "nothing"], [val], tmp_path / "x")
    with pytest.raises(ValueError, match="kind"):
        train_linear("svm", [train], [val], tmp_path / "x")


def test_the_imitation_policy_learns_every_optimal_direction(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr(vp, "scene_sample", _fake_sample)
    train, val = tmp_path / "train", tmp_path / "val"
    generate(vp.ViewspherePathsConfig(scenes=120, shard_size=40), train, progress=False)
    generate(vp.ViewspherePathsConfig(scenes=30, root_seed=1, shard_size=30), val, progress=False)
    out = tmp_path / "imitation"
    metrics = train_mlp([train], [val], out, hidden=(32,), seed=0)
    assert metrics["val_top_accuracy"] > 0.9 and metrics["sklearn_agreement"] == 1.0
    assert metrics["train_rows"] == metrics["train_samples"]  # one optimal direction each
    policy = LearnedPolicy.from_file(out / "viewsphere_imitation.onnx", SCORER)
    assert policy.name == "imitation"
    # The file computes the folded perceptron: its best direction is the sample's label.
    sample = _fake_sample(None, 2)
    assert sample is not None
    scores = policy.network.run(sample["state"][None])[0][0]
    assert int(np.argmax(scores)) == sample["label"]
    with pytest.raises(ValueError, match="hidden"):
        train_mlp([train], [val], out, hidden=())


def test_bfs_labels_are_every_first_move_of_a_shortest_path():
    from heapgrasp.viewsphere.policies import breadth_first
    from heapgrasp.viewsphere.world import ViewsphereWorld

    config = vp.ViewspherePathsConfig(
        objects=("prism_20x6x5",), labels="bfs", prefix_steps=1, procedural=1
    )
    assert config.object_names() == [
        "prism_20x6x5",
        *(f"procedural/{k}_00" for k in ("box", "cylinder", "bottle", "bowl", "cup")),
    ]
    meshes = vp._object_meshes("procedural/box_00")
    v = np.vstack([m[0] for m in meshes])
    assert v[:, 2].min() == pytest.approx(0.0) and np.abs(v[:, :2].mean(axis=0)).max() < 0.05
    world = ViewsphereWorld(vp._object_meshes("prism_20x6x5"))
    start = SpherePose(0.3, 1.2)
    best = vp.optimal_first_moves(world, [start], max_steps=3, max_sets=600)
    episode = breadth_first(world.grasp_found, sphere=world.sphere, start=start, max_steps=3)
    if episode.found and episode.steps > 0:
        assert best is not None and best[0] == episode.steps
        assert episode.directions[0] in best[1]
    else:
        assert best is None or episode.steps == 0
    assert vp.optimal_first_moves(world, [start], max_steps=3, max_sets=1) in (None, best)


def test_the_paths_config_keeps_test_objects_out_of_training():
    with pytest.raises(ValueError, match="003_cracker_box"):
        vp.ViewspherePathsConfig(objects=("003_cracker_box",))
    with pytest.raises(ValueError, match="tries"):
        vp.ViewspherePathsConfig(tries=0)
    with pytest.raises(ValueError, match="labels must be one of paths, bfs"):
        vp.ViewspherePathsConfig(labels="oracle")
    with pytest.raises(ValueError, match="prefix_steps needs labels='bfs'"):
        vp.ViewspherePathsConfig(prefix_steps=2)
    with pytest.raises(ValueError, match="procedural must be an int >= 0"):
        vp.ViewspherePathsConfig(procedural=-1)


def test_the_paths_dataset_resumes_and_extends_its_last_shard(tmp_path: Path):
    # The objects are a tuple in the config and a list in the manifest: the same
    # command run twice resumes; more scenes in the same shard write it again, whole.
    config = vp.ViewspherePathsConfig(scenes=1, objects=("prism_6x6x6",), tries=1, path_steps=2)
    first = generate(config, tmp_path, progress=False)
    shard = tmp_path / "shard-00000.npz"
    before = shard.read_bytes()
    again = generate(config, tmp_path, progress=False)
    assert again["complete"] and shard.read_bytes() == before
    bigger = vp.ViewspherePathsConfig(**{**config.__dict__, "scenes": 2})
    # before the shard is written again, a manifest does not call it complete
    partial = shards._write_manifest(tmp_path, bigger.spec, bigger, bigger.object_names(), 0.0)
    assert not partial["complete"]
    more = generate(bigger, tmp_path, progress=False)
    assert first["shards"]["shard-00000.npz"]["scenes"] == 1
    assert more["shards"]["shard-00000.npz"]["scenes"] == 2
    assert more["samples"] + more["dropped"] == 2
    # fewer scenes than a shard holds: the shard is kept whole, nothing is lost
    grown = shard.read_bytes()
    fewer = generate(config, tmp_path, progress=False)
    assert fewer["complete"] and shard.read_bytes() == grown
    with pytest.raises(ValueError, match="tries: 1 there, 2 asked"):
        generate(
            vp.ViewspherePathsConfig(**{**config.__dict__, "tries": 2}), tmp_path, progress=False
        )


def test_a_real_scene_is_labelled_with_a_shortest_first_direction():
    config = vp.ViewspherePathsConfig(objects=("prism_6x6x6",), tries=1, path_steps=2)
    samples = [s for s in (vp.scene_sample(config, i) for i in range(3)) if s is not None]
    for s in samples:
        lengths = s["lengths"]
        assert lengths[s["label"]] == lengths[lengths > 0].min()
        assert s["state"].shape == (N_FEATURES,)
    again = vp.scene_sample(config, 0)
    first = vp.scene_sample(config, 0)
    assert (again is None) == (first is None)
    if first is not None and again is not None:
        np.testing.assert_array_equal(first["state"], again["state"])


def test_the_dqn_trains_and_writes_a_policy_file(tmp_path: Path):
    config = DqnConfig(episodes=3, batch=2, yaws=1, objects=("prism_6x6x6",))
    metrics = train_dqn(config, tmp_path, progress=False)
    assert metrics["episodes"] == 3 and len(metrics["history"]) == 3
    network = OnnxNetwork(tmp_path / "viewsphere_dqn.onnx", kind="viewsphere-policy")
    assert network.hparams["model"] == "dqn" and network.hparams["layers"] == 4
    assert network.run(np.zeros((2, N_FEATURES)))[0].shape == (2, 8)
    with pytest.raises(ValueError, match="training shapes"):
        DqnConfig(objects=("025_mug",))


def test_the_dqn_plays_around_procedural_objects_in_turn(tmp_path: Path):
    config = DqnConfig(episodes=2, batch=2, yaws=1, objects=("prism_6x6x6",), procedural=1)
    assert config.object_names()[:2] == ("prism_6x6x6", "procedural/box_00")
    assert len(config.object_names()) == 6  # one of each of the five kinds
    metrics = train_dqn(config, tmp_path, progress=False)
    assert [h["object"] for h in metrics["history"]] == ["prism_6x6x6", "procedural/box_00"]
    assert metrics["config"]["procedural"] == 1
    for bad in (-1, True, 1.5):
        with pytest.raises(ValueError, match="procedural"):
            DqnConfig(procedural=bad)  # type: ignore[arg-type]
