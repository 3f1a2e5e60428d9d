"""On-policy grasp-network data: the grids the closed loop meets, and the network's own
top grasps on them, labelled on the true meshes (issue 58; DAgger's rounds).

:mod:`heapgrasp.data.grasps` samples fresh scenes after random views. The loop meets
other grids: later phases of a pile, after objects were taken or knocked over, carved by
the views its planner chose; and it executes the network's *best* grasps, where the
network's mistakes matter most (``heapgrasp bench topk``: its precision@1 on the loop's
grids is 71 %, though its offline average precision is 0.90). This dataset holds those
grids and grasps. For every scene (seed from the dataset's root seed and the scene's
index, so a shard re-run is identical):

1. a pile or packed scene (probability 1/2 each) of ``objects`` objects of the dataset's
   split (:func:`heapgrasp.data.scenes.split_models`: ``val`` holds out train objects), in
   a random scene group (transparent, opaque, specular or mixed), runs the
   clutter-removal protocol as ``heapgrasp run --method METHOD`` does, driven by
   ``driver``: ``network`` (the grasp network of ``weights`` executes its own best
   grasps, DAgger) or ``default`` (the method's default planner);
2. every phase gives one sample: the grid the grasp network reads at that moment
   (``occupancy``: ``Ŝ≥λ`` as :meth:`~heapgrasp.loop.phase.Pipeline.grasp_candidates`
   feeds it; ``tsdf`` for ``method = "vgn"``), and its grasps:

   - the network's top ``top`` candidates through the loop's own selection (eq. 15's
     smoothing, ε and NMS, the hull check, for ``tsdf`` also the contact check of
     :mod:`heapgrasp.planning.surface_contacts`, the failed-grasp memory), each labelled by
     the exact labeller (:func:`heapgrasp.sim.grasp_labels.labeller`, fingers fully
     open), kept whatever the label: the grasps the loop would execute;
   - VGN's grasps at ``points`` points of the surface the grid shows, balanced, as
     :mod:`heapgrasp.data.grasps` labels them.

The shards have :mod:`heapgrasp.data.grasps`' format (``heapgrasp grasps train`` reads
them beside that data), with ``k = −2`` (:data:`LOOP_PHASE`) on every sample and, per
labelled top candidate, ``top_scene`` (its sample), ``top_rank`` (0 = best),
``top_score`` and ``top_label``: the network's precision@k on the loop's grids, which
each DAgger round's data measures as a by-product (:func:`top_precision`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from heapgrasp.data.grasps import (
    _PER_GRASP,
    _PER_SCENE,
    FORMAT,
    VERSION,
    grasp_records,
    surface_grasps,
)
from heapgrasp.data.grasps import _settings as _grasp_settings
from heapgrasp.data.shards import DatasetSpec, ShardedConfig, run_scenes

__all__ = [
    "DRIVERS",
    "LOOP_PHASE",
    "LoopGraspDataConfig",
    "LoopScene",
    "draw_scene",
    "phase_sample",
    "scene_samples",
    "shard_samples",
    "top_precision",
]

LOOP_PHASE = -2
"""``k`` of a sample from a loop phase (:mod:`heapgrasp.data.grasps`: ``k ≥ 1`` random
view waypoints, −1 the circle)."""
DRIVERS = ("network", "default")
"""Who executes the grasps: the grasp network of ``weights`` or the method's default
planner."""
METHODS = ("heapgrasp", "no-vp", "vgn")
CATEGORIES = ("transparent", "opaque", "specular", "mixed")


def _settings() -> dict[str, Any]:
    return {**_grasp_settings(), "source": "loop phases"}


SPEC = DatasetSpec(
    FORMAT,
    VERSION,
    "grasp dataset",
    _settings,
    {"grasps": "grasp_label", "top_grasps": "top_label"},
)


def _digest(path: str) -> str:
    digest = hashlib.sha256(Path(path).read_bytes())
    return digest.hexdigest()[:16]


@dataclass(frozen=True)
class LoopGraspDataConfig(ShardedConfig):
    """What ``heapgrasp grasps loop-data`` makes (module docstring)."""

    shard_size: int = 5
    """Scenes per shard file (each gives one sample per phase, ~4)."""
    objects: int = 5
    """Objects per scene (the protocol's, §VI-C)."""
    method: str = "heapgrasp"
    """Whose views carve the grids: ``heapgrasp``, ``no-vp`` (occupancy) or ``vgn``
    (the TSDF)."""
    driver: str = "network"
    """:data:`DRIVERS`."""
    weights: str | None = None
    """The grasp network ranked (and, with ``driver = "network"``, executed): an ONNX
    file, or None for the one that ships for the method's grid."""
    top: int = 8
    """The network's best candidates labelled per phase."""
    points: int = 300
    """VGN's surface points per phase."""
    yaws: int = 6
    """Yaws per point, in [0, π) (VGN)."""
    gripper: str = "panda"
    """The hand the grasps are labelled for (the simulator's Panda; see
    :class:`heapgrasp.data.grasps.GraspDataConfig`)."""

    spec: ClassVar[DatasetSpec] = SPEC

    def __post_init__(self) -> None:
        super().__post_init__()
        self.positive("objects", "top", "yaws")
        if isinstance(self.points, bool) or not isinstance(self.points, int) or self.points < 0:
            raise ValueError(f"points must be an integer >= 0, got {self.points!r}")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        if self.driver not in DRIVERS:
            raise ValueError(f"driver must be one of {', '.join(DRIVERS)}, got {self.driver!r}")
        if self.weights is not None and not Path(self.weights).is_file():
            raise ValueError(f"weights: {self.weights} is not a file")
        if self.weights is None:
            from heapgrasp.inference import shipped_grasp_network

            if shipped_grasp_network(self.input) is None:  # one error, not one per shard
                raise ValueError(
                    f"weights: no grasp network for {self.input} grids ships with this "
                    f"version; pass one (heapgrasp grasps train --input {self.input} writes it)"
                )
        if self.gripper != "panda":
            raise ValueError(
                f"gripper: the loop's simulated hand is the Panda; got {self.gripper!r}"
            )

    @property
    def input(self) -> str:
        """The grid the network reads: the method's (``tsdf`` for ``vgn``, else
        ``occupancy``: :func:`~heapgrasp.loop.methods.method_of`)."""
        from heapgrasp.loop.methods import method_of

        return method_of(self.run_config("opaque", "pile")).grid

    def identity(self) -> dict[str, Any]:
        """As every dataset's, with the network's file named by its digest (the same
        weights elsewhere add to the dataset) and the grid it reads."""
        d = super().identity()
        d["weights"] = None if self.weights is None else _digest(self.weights)
        d["input"] = self.input
        return d

    def run_config(self, category: str, layout: str) -> Any:
        """The run's settings of one scene, as ``heapgrasp run`` has them."""
        from heapgrasp.loop.config import RunConfig

        return RunConfig().replace(
            {
                "method": self.method,
                "objects": self.objects,
                # the library's split; the dataset's objects are drawn by scene_samples
                "split": "test" if self.split == "test" else "train",
                "category": category,
                "layout": layout,
            },
            source="data loop-grasps",
        )

    def ranker_config(self, base: Any) -> Any:
        """``base`` planning with the network of :attr:`weights`, without a critic."""
        return base.replace(
            {"grasp_planner": "network", "grasp_critic": "none", "grasp_weights": self.weights},
            source="data loop-grasps",
        )

    def run_shard(self, shard: int) -> dict[str, Any]:
        """Arrays of ``shard`` (:func:`shard_samples`)."""
        return shard_samples(self, shard)


def phase_sample(
    pipeline: Any,
    world: Any,
    ranker: tuple[Any, Any],
    config: LoopGraspDataConfig,
    rng: np.random.Generator,
) -> dict[str, Any] | None:
    """One phase's sample (module docstring) from ``pipeline``'s grid as it stands, the
    network's candidates through ``ranker`` (its run settings and planner); None when
    neither kind of grasp gave a labelled grasp in the grid."""
    from scipy.spatial.transform import Rotation

    from heapgrasp.geometry.gripper import gripper_named
    from heapgrasp.sim.grasp_labels import labeller

    hand = gripper_named(config.gripper)
    frame = pipeline.frame
    perception = pipeline.perception
    grid = np.array(
        perception.tsdf_values() if config.input == "tsdf" else perception.grasp_input(),
        dtype=np.float32,
    )
    rank_config, planner = ranker
    with pipeline.planning_as(rank_config, planner, None):
        top = pipeline.grasp_candidates()[: config.top]
    parts = []
    top_out: dict[str, np.ndarray] = {
        "top_rank": np.zeros(0, np.int64),
        "top_score": np.zeros(0, np.float32),
        "top_label": np.zeros(0, np.uint8),
    }
    if top:
        poses = np.ascontiguousarray(np.stack([c.pose for c in top]), dtype=np.float64)
        ok, width, _, _ = labeller(world).label(poses, threads=1)
        label = np.asarray(ok, dtype=np.uint8)
        labelled = {
            "pose": poses,
            "quat": Rotation.from_matrix(poses[:, :3, :3]).as_quat(),
            "width": np.asarray(width, dtype=np.float32),
            "label": label,
        }
        record = grasp_records(labelled, frame, hand, None, balance=False)
        if record is not None:
            parts.append(record)
        top_out = {
            "top_rank": np.arange(len(top), dtype=np.int64),
            "top_score": np.array([c.score for c in top], dtype=np.float32),
            "top_label": label,
        }
    if config.points:
        vgn = surface_grasps(
            world,
            rng,
            grid,
            config.input,
            frame,
            points=config.points,
            yaws=config.yaws,
            gripper=config.gripper,
        )
        record = grasp_records(vgn, frame, hand, rng, balance=True)
        if record is not None:
            parts.append(record)
    if not parts:
        return None
    grasps = {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return {
        config.input: grid,
        "origin": np.asarray(frame.origin, dtype=np.float64),
        "voxel_size": np.float64(frame.voxel_size),
        **grasps,
        **top_out,
        "k": np.int64(LOOP_PHASE),
    }


@dataclass(frozen=True)
class LoopScene:
    """What scene ``index`` of a dataset is (:func:`draw_scene`)."""

    seed: int
    """The world's and the pipeline's seed (the samples' ``scene_seed``)."""
    category: str
    layout: Literal["pile", "packed"]
    models: tuple[Any, ...]
    """The objects, of the dataset's split."""


def draw_scene(
    config: LoopGraspDataConfig, index: int, library: Any
) -> tuple[LoopScene, np.random.Generator]:
    """Scene ``index`` and the generator its labels draw from next."""
    from heapgrasp.data.scenes import split_models

    rng = np.random.default_rng(np.random.SeedSequence([config.root_seed, index]))
    seed = int(rng.integers(2**31))
    category = CATEGORIES[int(rng.integers(len(CATEGORIES)))]
    layout: Literal["pile", "packed"] = "pile" if rng.random() < 0.5 else "packed"
    pool = split_models(library, config.split)
    count = min(config.objects, len(pool))
    models = tuple(pool[i] for i in rng.choice(len(pool), size=count, replace=False))
    return LoopScene(seed, category, layout, models), rng


def scene_samples(
    config: LoopGraspDataConfig, index: int, library: Any = None
) -> list[dict[str, Any]]:
    """Scene ``index`` through the protocol; one sample per phase that gave one."""
    from heapgrasp.geometry.gripper import PANDA_HAND
    from heapgrasp.loop.protocol import PlanResult, run_clutter_removal
    from heapgrasp.loop.stages import make_grasp_planner
    from heapgrasp.sim.build import object_library, sim_pipeline
    from heapgrasp.sim.optics import DepthModel
    from heapgrasp.sim.world import SimWorld, WorldConfig

    if library is None:
        library = object_library(config.run_config("mixed", "pile"))
    scene, rng = draw_scene(config, index, library)
    seed, category, layout, models = scene.seed, scene.category, scene.layout, scene.models
    base = config.run_config(category, layout)
    rank_config = config.ranker_config(base)
    planner = make_grasp_planner(rank_config, PANDA_HAND)
    drive = rank_config if config.driver == "network" else base
    samples: list[dict[str, Any]] = []
    with SimWorld(
        library,
        config=WorldConfig(cube_size=base.cube_size),
        depth_model=DepthModel(ideal=base.ideal_depth),
        seed=seed,
    ) as world:
        world.reset(layout=layout, category=category, seed=seed, models=models)
        pipeline = sim_pipeline(
            drive,
            world,
            seed=seed,
            grasp_planner=planner if config.driver == "network" else None,
        )

        def plan() -> PlanResult:
            result = pipeline.plan()
            sample = phase_sample(pipeline, world, (rank_config, planner), config, rng)
            if sample is not None:
                samples.append(
                    {**sample, "scene_seed": np.int64(seed), "scene_index": np.int64(index)}
                )
            return result

        run_clutter_removal(
            pipeline.robot,
            plan,
            truth=pipeline.truth,
            max_attempts=base.max_attempts,
            on_outcome=pipeline.record_outcome,
        )
    return samples


_PER_TOP: dict[str, Any] = {"top_rank": np.int64, "top_score": np.float32, "top_label": np.uint8}


def shard_samples(config: LoopGraspDataConfig, shard: int) -> dict[str, Any]:
    """Arrays of ``shard`` (every scene of it run in this process)."""
    from heapgrasp.loop.config import RunConfig

    per_scene: list[list[dict[str, Any]]] = []

    def sample(cfg: Any, index: int, library: Any) -> dict[str, Any] | None:
        found = scene_samples(cfg, index, library)
        per_scene.append(found)
        return {"found": len(found)} if found else None

    _, scenes = run_scenes(config, shard, sample)
    samples = [s for found in per_scene for s in found]
    r = RunConfig().resolution
    data: dict[str, Any] = {}
    grids = [s[config.input] for s in samples]
    data[config.input] = np.stack(grids) if grids else np.zeros((0, r, r, r), np.float32)
    for key, dtype in _PER_SCENE.items():
        shape = (3,) if key == "origin" else ()
        data[key] = (
            np.stack([s[key] for s in samples]).astype(dtype)
            if samples
            else np.zeros((0, *shape), dtype)
        )
    counts = [len(s["grasp_label"]) for s in samples]
    data["grasp_scene"] = np.repeat(np.arange(len(samples), dtype=np.int64), counts)
    for key, (kind, dims) in _PER_GRASP.items():
        parts = [s[key] for s in samples]
        data[key] = np.concatenate(parts).astype(kind) if parts else np.zeros((0, *dims), kind)
    tops = [len(s["top_label"]) for s in samples]
    data["top_scene"] = np.repeat(np.arange(len(samples), dtype=np.int64), tops)
    for key, top_kind in _PER_TOP.items():
        parts = [s[key] for s in samples]
        data[key] = np.concatenate(parts).astype(top_kind) if parts else np.zeros(0, top_kind)
    data["scenes"] = np.int64(len(scenes))
    data["dropped"] = np.int64(sum(1 for found in per_scene if not found))
    return data


def top_precision(out: str | Path, ks: tuple[int, ...] = (1, 3, 8)) -> dict[str, Any]:
    """The network's precision@k on the dataset's phases (the share of labelled
    successes among the candidates it ranked ≤ k), and the phases with a candidate."""
    from heapgrasp.data.shards import read_manifest

    manifest = read_manifest(Path(out), SPEC)
    ranks, labels, with_candidate, phases = [], [], 0, 0
    for name in sorted(manifest["shards"]):
        with np.load(Path(out) / name) as z:
            ranks.append(z["top_rank"])
            labels.append(z["top_label"])
            phases += len(z["k"])
            with_candidate += len(np.unique(z["top_scene"]))
    rank = np.concatenate(ranks) if ranks else np.zeros(0, np.int64)
    label = np.concatenate(labels) if labels else np.zeros(0, np.uint8)
    out_: dict[str, Any] = {"phases": phases, "with_candidate": with_candidate}
    for k in ks:
        sel = label[rank < k]
        out_[f"precision@{k}"] = float(sel.mean()) if len(sel) else None
        out_[f"labelled@{k}"] = len(sel)
    return out_
