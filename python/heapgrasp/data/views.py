"""The view network's dataset: HEAPGrasp's Algorithm 1 with exact eq. 14 labels.

For every scene (seed derived from the dataset's root seed and the scene's index, so a
shard re-run is identical):

1. ``n_ob ~ U{1..N_ob}`` objects of the dataset's object split, ``pile`` or ``packed``
   (each with probability 1/2), in a random scene group (transparent, opaque, specular or
   mixed; the silhouettes are ideal, so the group changes only which models are drawn);
2. ``k ~ U{0..L−1}`` view waypoints drawn without replacement from the ``U × V``
   candidates of eq. 12;
3. the camera starts at ``p⁰`` (``side`` or ``above``, each with probability 1/2: where a
   phase of :class:`~heapgrasp.loop.phase.Pipeline` starts) and captures continuously
   along ``f(p⁰, p̄¹), …, f(p̄^{k−1}, p̄^k)`` as the loop does (timed paths, 30 fps, the
   simulated robot's camera, ideal silhouettes), giving the SfS grid of eq. 10;
4. the labels ``s^{u,v}``: eq. 14 for every candidate from
   :class:`~heapgrasp.planning.views.OracleViewScorer` (exact, from the true meshes).
   With probability ``region_fraction`` a sample with ``k ≥ 1`` is a *region* sample:
   eq. 14 counted on the column of radius ``target_radius`` around a target (the
   ``target_radius`` extension the loop applies from the second view waypoint on), the
   target placed on top of a random column of ``Ŝ≥λ``; the others count the whole grid
   (the paper's eq. 14).

A scene whose grid (or target column) holds no high-confidence voxel has no eq. 14 and
is dropped and counted, as the paper's "invalid samples".

Layout on disk (``OUT``)::

    manifest.json          what was asked, what was made (rebuilt from the shards)
    shard-00000.npz        samples of scenes 0 .. shard_size − 1
    ...

A shard is written to a temporary file and renamed, so it is whole or absent; a re-run
(``resume``) skips the shards already there and a shard re-run gives the same bytes of
data. Each shard holds, with leading sample axis ``N``: ``segmented``, ``visible``
(uint16 SfS counts, ``(N, R, R, R)``, indexed ``[x, y, z]``), ``region`` (bool
``(N, R, R)``, the x–y column eq. 14 was counted on; all True = the whole grid),
``scores`` (float32 ``(N, U, V)``, row ``u`` = azimuth ``2πu/U``, column ``v`` = polar
angle ``θ_max v / V``), ``current`` (the camera pose scored from, ``(N, 4, 4)``),
``target`` (``(N, 4, 4)``, NaN where none), ``scene_seed``, ``scene_index``, ``k``, and
the counts ``scenes`` and ``dropped``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

__all__ = [
    "FORMAT",
    "SPLITS",
    "ShardFailure",
    "ViewDataConfig",
    "generate",
    "object_split",
    "read_manifest",
    "scene_sample",
    "shard_samples",
]

F64 = npt.NDArray[np.float64]

FORMAT = "heapgrasp-view-data"
VERSION = 1
SPLITS = ("train", "val", "test")
VAL_FRACTION = 0.2
"""Share of the library's train objects held out for validation (:func:`object_split`)."""

_COUNT_MAX = np.iinfo(np.uint16).max


def object_split(name: str, library_split: str) -> str:
    """``train``, ``val`` or ``test`` for an object of the library's ``train`` or
    ``test`` split: the test split stays the benchmark's held-out objects; a stable hash
    of the name moves :data:`VAL_FRACTION` of the train objects to ``val``."""
    if library_split == "test":
        return "test"
    digest = hashlib.sha256(f"heapgrasp-val:{name}".encode()).digest()
    return "val" if int.from_bytes(digest[:8], "big") / 2**64 < VAL_FRACTION else "train"


@dataclass(frozen=True)
class ViewDataConfig:
    """What :func:`generate` makes. The defaults are Algorithm 1 with Table I's values."""

    scenes: int = 1000
    """Scenes to run (each gives at most one sample)."""
    root_seed: int = 0
    """Seed every scene's seed derives from."""
    split: str = "train"
    """Objects of ``train``, ``val`` (held out of training) or ``test`` (the benchmark's)."""
    shard_size: int = 50
    """Scenes per shard file."""
    max_objects: int = 5
    """N_ob (Table I)."""
    L: int = 3
    """View waypoints (Table I): ``k ~ U{0..L−1}``."""
    region_fraction: float = 0.5
    """Share of the ``k ≥ 1`` samples labelled on a target's column."""
    target_radius: float = 0.08
    """Radius of that column (m; the loop's ``target_radius`` default)."""
    frames_per_candidate: int = 10
    """Silhouettes per hypothetical trajectory (the oracle's)."""

    def __post_init__(self) -> None:
        def positive(name: str) -> None:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")

        for name in ("scenes", "shard_size", "max_objects", "L", "frames_per_candidate"):
            positive(name)
        if isinstance(self.root_seed, bool) or not isinstance(self.root_seed, int):
            raise ValueError(f"root_seed must be an integer, got {self.root_seed!r}")
        if self.root_seed < 0:
            raise ValueError(f"root_seed must be >= 0, got {self.root_seed}")
        if self.split not in SPLITS:
            raise ValueError(f"split must be one of {', '.join(SPLITS)}; got {self.split!r}")
        if not (math.isfinite(self.region_fraction) and 0.0 <= self.region_fraction <= 1.0):
            raise ValueError(f"region_fraction must be in [0, 1], got {self.region_fraction!r}")
        if not (math.isfinite(self.target_radius) and self.target_radius > 0.0):
            raise ValueError(f"target_radius must be > 0, got {self.target_radius!r}")

    @property
    def shards(self) -> int:
        """Number of shard files."""
        return -(-self.scenes // self.shard_size)

    def shard_scenes(self, shard: int) -> range:
        """Scene indices of ``shard``."""
        return range(shard * self.shard_size, min(self.scenes, (shard + 1) * self.shard_size))

    def identity(self) -> dict[str, Any]:
        """What must match to add shards to an existing dataset (everything but the
        number of scenes)."""
        d = dataclasses.asdict(self)
        d.pop("scenes")
        return d


class ShardFailure(RuntimeError):
    """Shards that failed; the others are written."""

    def __init__(self, failures: dict[int, str]) -> None:
        self.failures = failures
        lines = [f"shard {i}: {msg}" for i, msg in sorted(failures.items())]
        super().__init__(f"{len(failures)} shard(s) failed:\n" + "\n".join(lines))


# --------------------------------------------------------------------------- one scene


def _run_config(config: ViewDataConfig, start: str) -> Any:
    from heapgrasp.loop.config import RunConfig

    return RunConfig(
        method="heapgrasp",
        view_planner="oracle",
        split="test" if config.split == "test" else "train",
        start=start,
        L=config.L,
        grasp_critic="none",
    )


def _models(library: Any, split: str) -> list[Any]:
    library_split = "test" if split == "test" else "train"
    models = [
        m for m in library.models(split=library_split) if object_split(m.name, m.split) == split
    ]
    if not models:
        raise ValueError(f"the object library has no {split!r} objects")
    return models


def _top_down(position: F64, yaw: float) -> F64:
    """A grasp pose at ``position`` approaching straight down (z = approach)."""
    c, s = math.cos(yaw), math.sin(yaw)
    pose = np.eye(4)
    pose[:3, 0] = (c, -s, 0.0)
    pose[:3, 1] = (-s, -c, 0.0)
    pose[:3, 2] = (0.0, 0.0, -1.0)
    pose[:3, 3] = position
    return pose


def scene_sample(config: ViewDataConfig, index: int, library: Any = None) -> dict[str, Any] | None:
    """Runs scene ``index`` of Algorithm 1; its sample, or None when dropped."""
    from heapgrasp.geometry.motion import plan_waypoints
    from heapgrasp.perception.silhouette import SilhouettePerception
    from heapgrasp.planning.views import OracleViewScorer, ViewContext
    from heapgrasp.sim.build import object_library, sim_pipeline
    from heapgrasp.sim.world import SimWorld, WorldConfig

    rng = np.random.default_rng(np.random.SeedSequence([config.root_seed, index]))
    world_seed = int(rng.integers(2**31))
    start = "side" if rng.random() < 0.5 else "above"
    run_config = _run_config(config, start)
    if library is None:
        library = object_library(run_config)
    pool = _models(library, config.split)
    n_ob = int(rng.integers(1, config.max_objects + 1))
    chosen = [pool[i] for i in rng.choice(len(pool), size=min(n_ob, len(pool)), replace=False)]
    layout: Literal["pile", "packed"] = "pile" if rng.random() < 0.5 else "packed"
    category = ("transparent", "opaque", "specular", "mixed")[int(rng.integers(4))]
    k = int(rng.integers(0, config.L))
    region_sample = k >= 1 and rng.random() < config.region_fraction
    with SimWorld(
        library, config=WorldConfig(cube_size=run_config.cube_size), seed=world_seed
    ) as world:
        world.reset(layout=layout, category=category, seed=world_seed, models=chosen)
        if not world.objects:
            return None
        pipeline = sim_pipeline(run_config, world, seed=world_seed)
        perception = pipeline.perception
        assert isinstance(perception, SilhouettePerception)
        assert pipeline.truth is not None
        arm = pipeline.robot.arm
        arm.park()
        perception.reset()
        first = arm.look(pipeline.initial_pose())
        perception.update([first])
        current = first.cam2world
        u_count, v_count = pipeline.candidates.shape[:2]
        picks = rng.choice(u_count * v_count, size=k, replace=False)
        for flat in picks:
            goal = pipeline.candidates[flat // v_count, flat % v_count]
            (path,) = plan_waypoints(
                current, [goal], pipeline.sphere, pipeline.limits, run_config.fps
            )
            cap = arm.follow(path)
            perception.update(cap.frames[1:])
            current = cap.poses[-1]
        grid = perception.grid
        high = grid.high_confidence(run_config.lam) > 0.0
        if not high.any():
            return None
        target: F64 | None = None
        if region_sample:
            columns = np.argwhere(high.any(axis=2))
            a, b = columns[int(rng.integers(len(columns)))]
            c = int(np.flatnonzero(high[a, b]).max())
            centre = np.asarray(grid.origin) + (np.array([a, b, c]) + 0.5) * grid.voxel_size
            target = _top_down(centre, float(rng.uniform(0.0, math.pi)))
        scorer = OracleViewScorer(
            frames_per_candidate=config.frames_per_candidate,
            target_radius=config.target_radius if target is not None else 0.0,
        )
        ctx = ViewContext(
            grid,
            current,
            pipeline.candidates,
            pipeline.sphere,
            pipeline.camera,
            run_config.lam,
            pipeline.truth.meshes(),
            target=target,
        )
        scores = scorer.scores(ctx)
        region = scorer.region(ctx)
        if target is not None and not scores.any() and region is not None:
            return None
        segmented, visible = grid.counts()
    if int(visible.max()) > _COUNT_MAX:
        raise ValueError(f"scene {index}: a voxel was seen {int(visible.max())} times (> 65535)")
    r = grid.resolution
    return {
        "segmented": segmented.astype(np.uint16),
        "visible": visible.astype(np.uint16),
        "region": np.ones((r, r), bool) if region is None else region[:, :, 0].copy(),
        "scores": scores.astype(np.float32),
        "current": np.asarray(current, dtype=np.float64),
        "target": np.full((4, 4), np.nan) if target is None else target,
        "scene_seed": np.int64(world_seed),
        "scene_index": np.int64(index),
        "k": np.int64(k),
    }


# --------------------------------------------------------------------------- shards


def shard_path(out: Path, shard: int) -> Path:
    """File of ``shard``."""
    return out / f"shard-{shard:05d}.npz"


def shard_samples(config: ViewDataConfig, shard: int) -> dict[str, Any]:
    """Arrays of ``shard`` (every scene of it run in this process)."""
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.sim.build import object_library

    library = object_library(RunConfig())
    samples = []
    scenes = config.shard_scenes(shard)
    for index in scenes:
        sample = scene_sample(config, index, library)
        if sample is not None:
            samples.append(sample)
    keys = ("segmented", "visible", "region", "scores", "current", "target")
    ints = ("scene_seed", "scene_index", "k")
    data: dict[str, Any] = {}
    for key in keys:
        data[key] = np.stack([s[key] for s in samples]) if samples else np.zeros((0,))
    for key in ints:
        data[key] = np.asarray([s[key] for s in samples], dtype=np.int64)
    data["scenes"] = np.int64(len(scenes))
    data["dropped"] = np.int64(len(scenes) - len(samples))
    return data


def write_shard(config: ViewDataConfig, shard: int, out: str) -> tuple[int, int, int]:
    """Runs and writes ``shard`` (atomically: a temporary file renamed); returns
    ``(shard, samples, dropped)``. Idempotent: the same bytes of data on every run."""
    path = shard_path(Path(out), shard)
    data = shard_samples(config, shard)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    np.savez_compressed(tmp, **data)
    os.replace(tmp, path)
    return shard, len(data["k"]), int(data["dropped"])


def _init_worker() -> None:
    os.environ["HEAPGRASP_NUM_THREADS"] = "1"


# --------------------------------------------------------------------------- manifest


def _shard_entry(path: Path) -> dict[str, Any]:
    with np.load(path) as data:
        return {
            "samples": len(data["k"]),
            "scenes": int(data["scenes"]),
            "dropped": int(data["dropped"]),
            "bytes": path.stat().st_size,
        }


def read_manifest(out: Path) -> dict[str, Any]:
    """The dataset's ``manifest.json``; ValueError naming the file when it is not one."""
    path = out / "manifest.json"
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no view dataset here (no manifest.json)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise ValueError(f"{path}: not a {FORMAT} manifest")
    return manifest


def _write_manifest(
    out: Path, config: ViewDataConfig, objects: list[str], started: float
) -> dict[str, Any]:
    import heapgrasp
    from heapgrasp.loop.config import RunConfig

    run = RunConfig()
    shards = {}
    for shard in range(config.shards):
        path = shard_path(out, shard)
        if path.exists():
            shards[path.name] = _shard_entry(path)
    manifest = {
        "format": FORMAT,
        "version": VERSION,
        "split": config.split,
        "root_seed": config.root_seed,
        "objects": objects,
        "config": {
            **config.identity(),
            "scenes": config.scenes,
            "resolution": run.resolution,
            "U": run.U,
            "V": run.V,
            "lam": run.lam,
            "cube_size": run.cube_size,
            "radius": run.radius,
            "theta_max": run.theta_max,
            "fps": run.fps,
        },
        "shards": shards,
        "samples": sum(s["samples"] for s in shards.values()),
        "dropped": sum(s["dropped"] for s in shards.values()),
        "complete": len(shards) == config.shards,
        "package_version": heapgrasp.__version__,
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "command": " ".join(sys.argv),
        "seconds_this_run": round(time.monotonic() - started, 1),
    }
    tmp = out / ".manifest.json.tmp"
    tmp.write_text(json.dumps(manifest, indent=1) + "\n")
    os.replace(tmp, out / "manifest.json")
    return manifest


def _check_compatible(out: Path, config: ViewDataConfig) -> None:
    if not (out / "manifest.json").exists():
        if any(out.glob("shard-*.npz")):
            raise ValueError(f"{out}: shard files without a manifest.json; use an empty directory")
        return
    old = read_manifest(out)["config"]
    mine = config.identity()
    diff = sorted(k for k in mine if old.get(k) != mine[k])
    if diff:
        what = ", ".join(f"{k}: {old.get(k)!r} there, {mine[k]!r} asked" for k in diff)
        raise ValueError(f"{out} holds a dataset made with other settings ({what})")


def generate(
    config: ViewDataConfig,
    out: Path,
    *,
    workers: int = 1,
    ray_address: str | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Writes every shard of ``config`` not yet in ``out`` and the manifest; returns the
    manifest. A shard that fails (an exception, or a worker process that died) is
    reported by :class:`ShardFailure` after every other shard is written.

    ``workers``: processes of a local pool (1: this process). ``ray_address``: run the
    shards as Ray tasks instead (``"local"`` starts a local cluster, else the address of
    a running one); Ray retries a task whose worker died, which writing a shard
    tolerates (idempotent, atomic).
    """
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    from heapgrasp.sim.build import object_library

    started = time.monotonic()
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    out.mkdir(parents=True, exist_ok=True)
    _check_compatible(out, config)
    library = object_library(_run_config(config, "side"))
    objects = sorted(m.name for m in _models(library, config.split))
    todo = [s for s in range(config.shards) if not shard_path(out, s).exists()]
    _write_manifest(out, config, objects, started)
    bar = tqdm(
        total=config.scenes,
        initial=config.scenes - sum(len(config.shard_scenes(s)) for s in todo),
        unit="scene",
        file=sys.stderr,
        disable=not progress,
    )
    failures: dict[int, str] = {}

    def done(shard: int) -> None:
        bar.update(len(config.shard_scenes(shard)))
        _write_manifest(out, config, objects, started)

    if ray_address is not None:
        _run_ray(config, out, todo, ray_address, done, failures)
    elif workers == 1:
        for shard in todo:
            try:
                write_shard(config, shard, str(out))
            except Exception as exc:  # reported with its shard; the others go on
                failures[shard] = f"{type(exc).__name__}: {exc}"
                continue
            done(shard)
    else:
        _run_pool(config, out, todo, workers, done, failures)
    bar.close()
    manifest = _write_manifest(out, config, objects, started)
    if failures:
        raise ShardFailure(failures)
    return manifest


def _run_pool(
    config: ViewDataConfig,
    out: Path,
    todo: list[int],
    workers: int,
    done: Callable[[int], None],
    failures: dict[int, str],
) -> None:
    """The shards on a process pool. A worker that dies (a native crash) breaks the
    pool, and every shard it had not finished fails with it; those are run again, each
    in a pool of its own, so the guilty one fails alone and the others are written."""
    crashed: list[int] = []
    with ProcessPoolExecutor(min(workers, len(todo)), initializer=_init_worker) as pool:
        futures = {pool.submit(write_shard, config, s, str(out)): s for s in todo}
        remaining = set(futures)
        while remaining:
            finished, remaining = wait(remaining, return_when=FIRST_COMPLETED)
            for fut in finished:
                shard = futures[fut]
                try:
                    fut.result()
                except BrokenProcessPool:
                    crashed.append(shard)
                    continue
                except Exception as exc:
                    failures[shard] = f"{type(exc).__name__}: {exc}"
                    continue
                done(shard)
    for shard in sorted(crashed):
        with ProcessPoolExecutor(1, initializer=_init_worker) as single:
            try:
                single.submit(write_shard, config, shard, str(out)).result()
            except BrokenProcessPool:
                failures[shard] = "the worker process died (a native crash)"
                continue
            except Exception as exc:
                failures[shard] = f"{type(exc).__name__}: {exc}"
                continue
        done(shard)


def _run_ray(
    config: ViewDataConfig,
    out: Path,
    todo: list[int],
    address: str,
    done: Callable[[int], None],
    failures: dict[int, str],
) -> None:
    """The shards as Ray tasks (``pip install 'heapgrasp[ray]'``)."""
    try:
        ray: Any = importlib.import_module("ray")  # optional; typed loosely either way
    except ImportError:
        raise ImportError(
            "--ray needs Ray, which is not installed: pip install 'heapgrasp[ray]'"
        ) from None
    if address == "local":
        ray.init(runtime_env={"env_vars": {"HEAPGRASP_NUM_THREADS": "1"}})
    else:
        ray.init(address=address, runtime_env={"env_vars": {"HEAPGRASP_NUM_THREADS": "1"}})
    try:
        task = ray.remote(max_retries=2, num_cpus=1)(write_shard)
        refs = {task.remote(config, s, str(out)): s for s in todo}
        remaining = list(refs)
        while remaining:
            ready, remaining = ray.wait(remaining, num_returns=1)
            for ref in ready:
                shard = refs[ref]
                try:
                    ray.get(ref)
                except Exception as exc:
                    failures[shard] = f"{type(exc).__name__}: {exc}"
                    continue
                done(shard)
    finally:
        ray.shutdown()
