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

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.data.scenes import (
    VAL_FRACTION,
    capture_random_views,
    object_split,
    run_config,
    split_models,
)
from heapgrasp.data.shards import (
    SPLITS,
    DatasetSpec,
    ShardedConfig,
    ShardFailure,
    generate,
    run_scenes,
    shard_path,
    write_shard,
)
from heapgrasp.data.shards import read_manifest as _read_manifest

__all__ = [
    "FORMAT",
    "SPLITS",
    "VAL_FRACTION",
    "ShardFailure",
    "ViewDataConfig",
    "generate",
    "object_split",
    "read_manifest",
    "scene_sample",
    "shard_path",
    "shard_samples",
    "write_shard",
]

F64 = npt.NDArray[np.float64]

FORMAT = "heapgrasp-view-data"
VERSION = 1

_COUNT_MAX = np.iinfo(np.uint16).max


def _settings() -> dict[str, Any]:
    from heapgrasp.loop.config import RunConfig

    run = RunConfig()
    names = ("resolution", "U", "V", "lam", "cube_size", "radius", "theta_max", "fps")
    return {name: getattr(run, name) for name in names}


SPEC = DatasetSpec(FORMAT, VERSION, "view dataset", _settings)
"""What the manifest says of the view dataset."""


@dataclass(frozen=True)
class ViewDataConfig(ShardedConfig):
    """What :func:`generate` makes. The defaults are Algorithm 1 with Table I's values."""

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

    spec: ClassVar[DatasetSpec] = SPEC

    def __post_init__(self) -> None:
        super().__post_init__()
        self.positive("max_objects", "L", "frames_per_candidate")
        if not (math.isfinite(self.region_fraction) and 0.0 <= self.region_fraction <= 1.0):
            raise ValueError(f"region_fraction must be in [0, 1], got {self.region_fraction!r}")
        if not (math.isfinite(self.target_radius) and self.target_radius > 0.0):
            raise ValueError(f"target_radius must be > 0, got {self.target_radius!r}")

    def run_shard(self, shard: int) -> dict[str, Any]:
        """Arrays of ``shard`` (:func:`shard_samples`)."""
        return shard_samples(self, shard)


# --------------------------------------------------------------------------- one scene


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
    from heapgrasp.perception.silhouette import SilhouettePerception
    from heapgrasp.planning.views import OracleViewScorer, ViewContext
    from heapgrasp.sim.build import object_library, sim_pipeline
    from heapgrasp.sim.world import SimWorld, WorldConfig

    rng = np.random.default_rng(np.random.SeedSequence([config.root_seed, index]))
    world_seed = int(rng.integers(2**31))
    start = "side" if rng.random() < 0.5 else "above"
    run = run_config(config.split, start, config.L)
    if library is None:
        library = object_library(run)
    pool = split_models(library, config.split)
    n_ob = int(rng.integers(1, config.max_objects + 1))
    chosen = [pool[i] for i in rng.choice(len(pool), size=min(n_ob, len(pool)), replace=False)]
    layout: Literal["pile", "packed"] = "pile" if rng.random() < 0.5 else "packed"
    category = ("transparent", "opaque", "specular", "mixed")[int(rng.integers(4))]
    k = int(rng.integers(0, config.L))
    region_sample = k >= 1 and rng.random() < config.region_fraction
    with SimWorld(library, config=WorldConfig(cube_size=run.cube_size), seed=world_seed) as world:
        world.reset(layout=layout, category=category, seed=world_seed, models=chosen)
        if not world.objects:
            return None
        pipeline = sim_pipeline(run, world, seed=world_seed)
        perception = pipeline.perception
        assert isinstance(perception, SilhouettePerception)
        assert pipeline.truth is not None
        current = capture_random_views(pipeline, rng, k)
        grid = perception.grid
        high = grid.high_confidence(run.lam) > 0.0
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
            run.lam,
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


def shard_samples(config: ViewDataConfig, shard: int) -> dict[str, Any]:
    """Arrays of ``shard`` (every scene of it run in this process)."""
    samples, scenes = run_scenes(config, shard, scene_sample)
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


def read_manifest(out: Path) -> dict[str, Any]:
    """The dataset's ``manifest.json``; ValueError naming the file when it is not one."""
    return _read_manifest(out, SPEC)
