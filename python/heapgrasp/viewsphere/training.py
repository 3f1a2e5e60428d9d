"""Training Natarajan et al.'s learned viewsphere policies (§4.3): PCA + logistic regression and
PCA + LDA on the paths dataset (:mod:`heapgrasp.viewsphere.data`), and the deep
Q-network by playing episodes in the simulator. Each writes a policy file
(:func:`~heapgrasp.viewsphere.learned.policy_onnx`), ``metrics.json`` and
``metrics.png``.

**PCA + LR / LDA** (scikit-learn): the states standardised, PCA keeping 85 % of the
variance, then a multinomial logistic regression or an LDA classifier predicting the
label. All three steps are linear, so the file is one dense layer (the paper compresses
to 26 components; ours keeps what holds 85 %). Validation: the share of states whose
predicted direction is one of the shortest paths' first directions (``top_accuracy``),
the exact-label accuracy, and the mean extra moves of the predicted direction's path
over the shortest (its path not found: ``path_steps + 1``).

**Imitation** (beyond the paper; scikit-learn): a multilayer perceptron (two hidden
layers of 128, ReLU) on the standardised state, trained to give the datasets' optimal
first directions (with ``viewsphere data --labels bfs``, every first move of a shortest
path by breadth-first search, on states after 0–2 random moves and on procedural
objects of many shapes), one training row per optimal direction; validated as above.

**Deep Q-learning** (PyTorch, §4.3.2): 4 dense layers of 128 with ReLU and 8 outputs,
ε-greedy (ε from 1 decaying by ``epsilon_decay`` an episode to ``epsilon_min``),
experience replay (``replay`` transitions, batches of 64, one Adam step of learning
rate 0.005 per move), reward +5 when the views yield a grasp and −1 per move, γ = 0.9,
at most ``max_steps`` moves an episode. Episodes start at the benchmark's start view
around a training shape (all six by default, as the paper's) or, with ``procedural > 0``,
in turn around them and that many procedural objects of each kind (those of ``viewsphere
data --procedural``), at one of ``yaws`` yaws per object drawn once from the seed;
worlds are kept (their renders and syntheses cached) for the most recent ``worlds``
(object, yaw) pairs.
"""

from __future__ import annotations

import datetime as _dt
import itertools
import json
import math
import os
import platform
import sys
import time
import warnings
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.inference import write_atomically
from heapgrasp.viewsphere.grasps import ViewsphereConfig

__all__ = [
    "DqnConfig",
    "fold_linear",
    "load_paths",
    "train_dqn",
    "train_linear",
    "train_mlp",
]

F64 = npt.NDArray[np.float64]


def load_paths(paths: Sequence[Path]) -> dict[str, npt.NDArray[Any]]:
    """The samples of one or more paths datasets, concatenated (FileNotFoundError or
    ValueError naming a directory that is not one)."""
    from heapgrasp.data.shards import read_manifest
    from heapgrasp.viewsphere.data import SPEC

    parts: dict[str, list[npt.NDArray[Any]]] = {}
    for root in paths:
        manifest = read_manifest(Path(root), SPEC)
        for name in sorted(manifest["shards"]):
            with np.load(Path(root) / name) as data:
                for key in ("state", "label", "lengths"):
                    parts.setdefault(key, []).append(np.asarray(data[key]))
    if not parts or sum(len(a) for a in parts["label"]) == 0:
        raise ValueError(f"no samples in {', '.join(str(p) for p in paths)}")
    return {k: np.concatenate(v) for k, v in parts.items()}


def fold_linear(
    mean: F64,
    scale: F64,
    pca_mean: F64,
    components: F64,
    coef: F64,
    intercept: F64,
    classes: Sequence[int],
    n_out: int = 8,
) -> tuple[F64, F64]:
    """One dense layer ``(W, b)`` computing ``((x − mean) / scale − pca_mean) @
    componentsᵀ @ coefᵀ + intercept``, the classifier's rows placed at their
    ``classes`` among ``n_out`` (a class never seen scores −10⁴)."""
    a = coef @ components / scale  # (classes, features)
    b = intercept - coef @ components @ (mean / scale + pca_mean)
    w_out = np.zeros((n_out, len(mean)))
    b_out = np.full(n_out, -1e4)
    for row, cls in enumerate(classes):
        w_out[int(cls)] = a[row]
        b_out[int(cls)] = b[row]
    return w_out, b_out


def _provenance(data: Mapping[str, Any], metrics: Mapping[str, Any]) -> dict[str, Any]:
    import heapgrasp

    return {
        "command": " ".join(sys.argv),
        "created": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "package_version": heapgrasp.__version__,
        "data": dict(data),
        "metrics": dict(metrics),
    }


def _path_metrics(pred: npt.NDArray[np.int64], lengths: npt.NDArray[np.int64]) -> dict[str, float]:
    """How good the predicted first directions are against each sample's paths."""
    found = np.where(lengths > 0, lengths, lengths.max(initial=0) + 1)
    shortest = found.min(axis=1)
    chosen = found[np.arange(len(pred)), pred]
    return {
        "top_accuracy": float(np.mean(chosen == shortest)),
        "extra_moves": float(np.mean(chosen - shortest)),
    }


def train_linear(
    kind: str,
    train: Sequence[Path],
    val: Sequence[Path],
    out: Path,
    *,
    variance: float = 0.85,
    seed: int = 0,
) -> dict[str, Any]:
    """PCA + ``kind`` (``lr`` or ``lda``) on the ``train`` datasets, measured on
    ``val``; writes ``out/viewsphere_pca_KIND.onnx``, ``metrics.json`` and
    ``metrics.png``. Returns the metrics."""
    try:
        from sklearn.decomposition import PCA
        from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
        from sklearn.linear_model import LogisticRegression
        from sklearn.preprocessing import StandardScaler
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            f"training PCA + {kind} needs scikit-learn: pip install 'heapgrasp[train]'"
        ) from exc
    from heapgrasp.viewsphere.learned import policy_onnx

    if kind not in ("lr", "lda"):
        raise ValueError(f"kind must be 'lr' or 'lda', got {kind!r}")
    if not 0.0 < variance <= 1.0:
        raise ValueError(f"variance must be in (0, 1], got {variance}")
    t0 = time.perf_counter()
    tr, va = load_paths(train), load_paths(val)
    x, y = tr["state"].astype(np.float64), tr["label"]
    scaler = StandardScaler().fit(x)
    pca = PCA(n_components=variance, svd_solver="full", random_state=seed).fit(scaler.transform(x))
    z = pca.transform(scaler.transform(x))
    clf: Any = (
        LogisticRegression(max_iter=5000, random_state=seed)
        if kind == "lr"
        else LinearDiscriminantAnalysis()
    )
    clf.fit(z, y)
    if len(clf.classes_) < 3:  # scikit-learn's binary case keeps one row
        raise ValueError(
            f"the training labels hold {len(clf.classes_)} direction(s); generate more scenes"
        )
    w, b = fold_linear(
        scaler.mean_,
        scaler.scale_,
        pca.mean_,
        pca.components_,
        np.atleast_2d(clf.coef_),
        np.atleast_1d(clf.intercept_),
        [int(c) for c in clf.classes_],
    )

    def predict(states: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        scores = states.astype(np.float64) @ w.T + b
        out_: npt.NDArray[np.int64] = np.argmax(scores, axis=1)
        return out_

    metrics: dict[str, Any] = {
        "model": f"pca-{kind}",
        "components": int(pca.n_components_),
        "variance_kept": float(np.sum(pca.explained_variance_ratio_)),
        "train_samples": len(y),
        "val_samples": len(va["label"]),
        "train_accuracy": float(np.mean(predict(x) == y)),
        "val_accuracy": float(np.mean(predict(va["state"]) == va["label"])),
        **{f"val_{k}": v for k, v in _path_metrics(predict(va["state"]), va["lengths"]).items()},
        "label_counts": np.bincount(y, minlength=8).tolist(),
        "seconds": round(time.perf_counter() - t0, 2),
    }
    # The folded layer must agree with scikit-learn's own predictions.
    agree = float(np.mean(predict(x) == clf.predict(z)))
    metrics["sklearn_agreement"] = agree
    if agree < 0.999:
        raise RuntimeError(f"the folded PCA + {kind} disagrees with scikit-learn ({agree:.4f})")
    data = {"train": [str(p) for p in train], "val": [str(p) for p in val]}
    onnx_bytes = policy_onnx(
        [(w, b)],
        hparams={"model": f"pca-{kind}", "components": int(pca.n_components_)},
        provenance=_provenance(data, metrics),
    )
    out.mkdir(parents=True, exist_ok=True)
    write_atomically(onnx_bytes, out / f"viewsphere_pca_{kind}.onnx")
    _write_metrics(out, metrics, None)
    return metrics


def _optimal_rows(
    states: npt.NDArray[Any], lengths: npt.NDArray[np.int64], labels: npt.NDArray[np.int64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """One row per sample and optimal first direction (its shortest length; the label
    where no length is known), so that ties are learned as the set they are."""
    rows, ys = [], []
    for x, ln, y in zip(states, lengths, labels, strict=True):
        found = ln[ln > 0]
        best = np.flatnonzero(ln == found.min()) if len(found) else np.array([y])
        for d in best:
            rows.append(x)
            ys.append(int(d))
    return np.asarray(rows, dtype=np.float64), np.asarray(ys, dtype=np.int64)


def train_mlp(
    train: Sequence[Path],
    val: Sequence[Path],
    out: Path,
    *,
    hidden: Sequence[int] = (128, 128),
    alpha: float = 1e-3,
    max_iter: int = 200,
    seed: int = 0,
) -> dict[str, Any]:
    """A next-move policy imitating the datasets' labels (beyond the paper: with
    ``viewsphere data --labels bfs``, breadth-first search's every optimal first move):
    a multilayer perceptron (scikit-learn's, ReLU, Adam, an L2 penalty ``alpha``) on the
    standardised state, one training row per optimal direction; measured on ``val``.
    Writes ``out/viewsphere_imitation.onnx`` (the standardisation folded into the first
    layer), ``metrics.json`` and ``metrics.png``. Returns the metrics."""
    try:
        from sklearn.neural_network import MLPClassifier
        from sklearn.preprocessing import StandardScaler
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(
            "training the imitation policy needs scikit-learn: pip install 'heapgrasp[train]'"
        ) from exc
    from heapgrasp.viewsphere.learned import policy_onnx

    if not hidden or any(int(h) < 1 for h in hidden):
        raise ValueError(f"hidden must be one or more layer widths >= 1, got {list(hidden)}")
    t0 = time.perf_counter()
    tr, va = load_paths(train), load_paths(val)
    x, y = _optimal_rows(tr["state"], tr["lengths"], tr["label"])
    scaler = StandardScaler().fit(x)
    scale = np.where(scaler.scale_ > 0, scaler.scale_, 1.0)
    clf = MLPClassifier(
        hidden_layer_sizes=tuple(int(h) for h in hidden),
        alpha=alpha,
        max_iter=max_iter,
        random_state=seed,
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        clf.fit((x - scaler.mean_) / scale, y)
    converged = not any("converge" in str(w.message).lower() for w in caught)
    classes = [int(c) for c in clf.classes_]
    if len(classes) < 3:  # scikit-learn's binary case keeps one output
        raise ValueError(
            f"the training labels hold {len(classes)} direction(s); generate more scenes"
        )
    ws = [np.asarray(w, dtype=np.float64).T for w in clf.coefs_]
    bs = [np.asarray(b, dtype=np.float64) for b in clf.intercepts_]
    # The standardisation folded into the first layer; the output rows at their classes.
    bs[0] = bs[0] - ws[0] @ (scaler.mean_ / scale)
    ws[0] = ws[0] / scale
    w_out = np.zeros((8, ws[-1].shape[1]))
    b_out = np.full(8, -1e4)
    for row, cls in enumerate(classes):
        w_out[cls], b_out[cls] = ws[-1][row], bs[-1][row]
    ws[-1], bs[-1] = w_out, b_out
    layers = list(zip(ws, bs, strict=True))

    def predict(states: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        h = states.astype(np.float64)
        for i, (w, b) in enumerate(layers):
            h = h @ w.T + b
            if i < len(layers) - 1:
                h = np.maximum(h, 0.0)
        out_: npt.NDArray[np.int64] = np.argmax(h, axis=1)
        return out_

    agree = float(np.mean(predict(x) == clf.predict((x - scaler.mean_) / scale)))
    if agree < 0.999:
        raise RuntimeError(f"the folded perceptron disagrees with scikit-learn ({agree:.4f})")
    metrics: dict[str, Any] = {
        "model": "imitation",
        "hidden": [int(h) for h in hidden],
        "alpha": alpha,
        "iterations": int(clf.n_iter_),
        "converged": converged,
        "train_samples": len(tr["label"]),
        "train_rows": len(y),
        "val_samples": len(va["label"]),
        "train_top_accuracy": _path_metrics(predict(tr["state"]), tr["lengths"])["top_accuracy"],
        **{f"val_{k}": v for k, v in _path_metrics(predict(va["state"]), va["lengths"]).items()},
        "label_counts": np.bincount(y, minlength=8).tolist(),
        "sklearn_agreement": agree,
        "seconds": round(time.perf_counter() - t0, 2),
    }
    data = {"train": [str(p) for p in train], "val": [str(p) for p in val]}
    onnx_bytes = policy_onnx(
        layers,
        hparams={"model": "imitation", "hidden": [int(h) for h in hidden]},
        provenance=_provenance(data, metrics),
    )
    out.mkdir(parents=True, exist_ok=True)
    write_atomically(onnx_bytes, out / "viewsphere_imitation.onnx")
    _write_metrics(out, metrics, None)
    return metrics


@dataclass(frozen=True)
class DqnConfig:
    """What :func:`train_dqn` runs (module doc)."""

    episodes: int = 2600
    """Episodes (the paper's 1,300, on its six shapes only)."""
    objects: tuple[str, ...] = ()
    """Training shapes (default: all six)."""
    procedural: int = 8
    """Procedural objects per kind beside ``objects`` (:mod:`heapgrasp.viewsphere.data`'s;
    0: the paper's shapes alone)."""
    yaws: int = 12
    seed: int = 0
    hidden: int = 128
    layers: int = 4
    learning_rate: float = 0.005
    gamma: float = 0.9
    batch: int = 64
    replay: int = 10_000
    epsilon_decay: float = 0.995
    epsilon_min: float = 0.05
    reward_grasp: float = 5.0
    reward_step: float = -1.0
    max_steps: int = 6
    worlds: int = 24

    def __post_init__(self) -> None:
        for name in ("episodes", "yaws", "hidden", "layers", "batch", "replay", "worlds"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an int >= 1, got {value!r}")
        if isinstance(self.procedural, bool) or not isinstance(self.procedural, int):
            raise ValueError(f"procedural must be an int >= 0, got {self.procedural!r}")
        if self.procedural < 0:
            raise ValueError(f"procedural must be an int >= 0, got {self.procedural!r}")
        if not 0.0 < self.learning_rate < 1.0:
            raise ValueError(f"learning_rate must be in (0, 1), got {self.learning_rate}")
        if not 0.0 <= self.gamma < 1.0:
            raise ValueError(f"gamma must be in [0, 1), got {self.gamma}")
        if not (0.0 < self.epsilon_decay <= 1.0 and 0.0 <= self.epsilon_min <= 1.0):
            raise ValueError("epsilon_decay must be in (0, 1] and epsilon_min in [0, 1]")
        from heapgrasp.viewsphere.objects import TRAIN_OBJECTS

        bad = [o for o in self.objects if o not in TRAIN_OBJECTS]
        if bad:
            raise ValueError(
                f"objects must be training shapes ({', '.join(TRAIN_OBJECTS)}); got "
                + ", ".join(bad)
            )

    def object_names(self) -> tuple[str, ...]:
        """The episodes' objects in turn: the training shapes, then the procedural ones."""
        from heapgrasp.sim.procedural import PROCEDURAL_KINDS
        from heapgrasp.viewsphere.objects import TRAIN_OBJECTS

        extra = tuple(
            f"procedural/{k}_{i:02d}" for k in PROCEDURAL_KINDS for i in range(self.procedural)
        )
        return (*(self.objects or tuple(TRAIN_OBJECTS)), *extra)


@dataclass
class _Worlds:
    """The most recent worlds by (object, yaw), their caches kept."""

    limit: int
    config: ViewsphereConfig
    cache: OrderedDict[tuple[str, float], Any] = field(default_factory=OrderedDict)

    def get(self, name: str, yaw: float) -> Any:
        from heapgrasp.viewsphere.data import _object_meshes
        from heapgrasp.viewsphere.world import ViewsphereWorld

        key = (name, yaw)
        if key in self.cache:
            self.cache.move_to_end(key)
            return self.cache[key]
        c, s = math.cos(yaw), math.sin(yaw)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        world = ViewsphereWorld(
            [(v @ turn.T, f) for v, f in _object_meshes(name)], config=self.config
        )
        self.cache[key] = world
        while len(self.cache) > self.limit:
            self.cache.popitem(last=False)
        return world


def train_dqn(
    config: DqnConfig,
    out: Path,
    *,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Deep Q-learning (module doc); writes ``out/viewsphere_dqn.onnx``,
    ``metrics.json`` (per-episode return and steps) and ``metrics.png``."""
    try:
        import torch
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError("training the DQN needs PyTorch: pip install 'heapgrasp[train]'") from exc
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    from heapgrasp.viewsphere.learned import N_FEATURES, policy_onnx, state_features
    from heapgrasp.viewsphere.sphere import DIRECTIONS

    t0 = time.perf_counter()
    rng = np.random.default_rng(config.seed)
    torch.manual_seed(config.seed)
    objects = config.object_names()
    yaws = {o: rng.uniform(0, 2 * math.pi, config.yaws).round(6).tolist() for o in objects}
    vs = ViewsphereConfig()
    worlds = _Worlds(config.worlds, vs)
    n_actions = len(DIRECTIONS)
    widths = [N_FEATURES] + [config.hidden] * config.layers
    mods: list[torch.nn.Module] = []
    for a, b in itertools.pairwise(widths):
        mods += [torch.nn.Linear(a, b), torch.nn.ReLU()]
    net = torch.nn.Sequential(*mods, torch.nn.Linear(widths[-1], n_actions))
    opt = torch.optim.Adam(net.parameters(), lr=config.learning_rate)
    buf_s = np.zeros((config.replay, N_FEATURES), np.float32)
    buf_a = np.zeros(config.replay, np.int64)
    buf_r = np.zeros(config.replay, np.float32)
    buf_s2 = np.zeros((config.replay, N_FEATURES), np.float32)
    buf_done = np.zeros(config.replay, np.float32)
    stored = 0
    epsilon = 1.0
    history: list[dict[str, Any]] = []
    bar = tqdm(total=config.episodes, unit="episode", file=sys.stderr, disable=not progress)
    for episode in range(config.episodes):
        name = objects[episode % len(objects)]
        yaw = float(yaws[name][int(rng.integers(config.yaws))])
        world = worlds.get(name, yaw)
        scorer = vs.view_scorer(world.sphere, world.camera)
        poses = [world.start]

        def state(ps: list[Any], _w: Any = world, _s: Any = scorer) -> npt.NDArray[np.float32]:
            obj, unexplored = _w.grasps.fused(ps)
            return state_features(obj, _s.targets(unexplored), ps[-1], _w.sphere)

        total, moves = 0.0, 0
        found = world.grasp(poses) is not None
        s = state(poses)
        while not found and moves < config.max_steps:
            if rng.random() < epsilon:
                action = int(rng.integers(n_actions))
            else:
                with torch.no_grad():
                    action = int(torch.argmax(net(torch.from_numpy(s[None]))[0]))
            poses.append(world.sphere.move(poses[-1], action)[1])
            moves += 1
            found = world.grasp(poses) is not None
            reward = config.reward_step + (config.reward_grasp if found else 0.0)
            s2 = state(poses)
            done = found or moves == config.max_steps
            i = stored % config.replay
            buf_s[i], buf_a[i], buf_r[i], buf_s2[i], buf_done[i] = s, action, reward, s2, done
            stored += 1
            total += reward
            s = s2
            if stored >= config.batch:
                idx = rng.integers(min(stored, config.replay), size=config.batch)
                q = net(torch.from_numpy(buf_s[idx])).gather(
                    1, torch.from_numpy(buf_a[idx])[:, None]
                )[:, 0]
                with torch.no_grad():
                    nxt_q = net(torch.from_numpy(buf_s2[idx])).max(dim=1).values
                    target = torch.from_numpy(buf_r[idx]) + config.gamma * nxt_q * (
                        1 - torch.from_numpy(buf_done[idx])
                    )
                loss = torch.nn.functional.smooth_l1_loss(q, target)
                opt.zero_grad()
                loss.backward()  # type: ignore[no-untyped-call]
                opt.step()
        epsilon = max(config.epsilon_min, epsilon * config.epsilon_decay)
        history.append(
            {"episode": episode, "object": name, "return": total, "moves": moves, "found": found}
        )
        if log is not None and (episode + 1) % 50 == 0:
            recent = history[-50:]
            log(
                f"episode {episode + 1}: mean return {np.mean([h['return'] for h in recent]):.2f}, "
                f"found {np.mean([h['found'] for h in recent]):.2f}, epsilon {epsilon:.3f}"
            )
        bar.update(1)
    bar.close()
    linears = [m for m in net if isinstance(m, torch.nn.Linear)]
    layers = [
        (m.weight.detach().double().numpy(), m.bias.detach().double().numpy()) for m in linears
    ]
    last = history[-100:]
    metrics: dict[str, Any] = {
        "model": "dqn",
        "config": {**asdict(config), "objects": list(objects)},
        "episodes": len(history),
        "last_100_mean_return": float(np.mean([h["return"] for h in last])),
        "last_100_found": float(np.mean([h["found"] for h in last])),
        "last_100_mean_moves": float(np.mean([h["moves"] for h in last])),
        "seconds": round(time.perf_counter() - t0, 1),
        "history": history,
    }
    summary = {k: v for k, v in metrics.items() if k != "history"}
    onnx_bytes = policy_onnx(
        layers,
        hparams={"model": "dqn", "hidden": config.hidden, "layers": config.layers},
        provenance=_provenance(
            {"objects": list(objects), "yaws": config.yaws, "procedural": config.procedural},
            summary,
        ),
    )
    out.mkdir(parents=True, exist_ok=True)
    write_atomically(onnx_bytes, out / "viewsphere_dqn.onnx")
    _write_metrics(out, metrics, history)
    return metrics


def _write_metrics(
    out: Path, metrics: Mapping[str, Any], history: Sequence[Mapping[str, Any]] | None
) -> None:
    """``metrics.json`` and ``metrics.png`` (the DQN's return per episode, smoothed; a
    linear policy's label counts)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    (out / "metrics.json").write_text(json.dumps(metrics, indent=1) + "\n")
    fig = Figure(figsize=(5, 3))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if history:
        r = np.array([h["return"] for h in history], dtype=np.float64)
        k = min(50, len(r))
        ax.plot(r, lw=0.5, alpha=0.4, label="return")
        smooth = np.convolve(r, np.ones(k) / k, "valid")
        ax.plot(np.arange(k - 1, len(r)), smooth, label=f"mean of {k}")
        ax.set_xlabel("episode")
        ax.set_ylabel("return")
        ax.legend(fontsize=7)
    else:
        ax.bar(range(8), metrics["label_counts"], color="tab:gray")
        ax.set_xticks(range(8), ["N", "NE", "E", "SE", "S", "SW", "W", "NW"])
        ax.set_ylabel("training labels")
        ax.set_title(
            f"{metrics['model']}: val top accuracy {metrics['val_top_accuracy']:.2f}", fontsize=9
        )
    fig.tight_layout()
    fig.savefig(out / "metrics.png", dpi=110)
