"""The grasp network's dataset: VGN's scheme on the grids the loop feeds the network.

For every scene (seed derived from the dataset's root seed and the scene's index, so a
shard re-run is identical):

1. ``min(Poisson(4) + 1, max_objects)`` objects of the dataset's object split
   (:func:`~heapgrasp.data.scenes.object_split`), ``pile`` or ``packed`` (each with
   probability 1/2), in a random scene group (transparent, opaque, specular or mixed),
   as VGN's scenes and the view data's;
2. a dataset holds one network input, ``input`` (each network learns its own):
   ``occupancy`` (HEAPGrasp and no-vp): the camera starts at ``p⁰`` (``side`` or
   ``above``, each with probability 1/2) and captures, as the loop's phase does (timed
   paths, 30 fps, ideal silhouettes), either (half the scenes) Algorithm 1's
   ``k ~ U{1..L}`` random view waypoints (the loop plans grasps after waypoints 1 to L)
   (:func:`~heapgrasp.data.scenes.capture_random_views`, as the view data) or (the
   other half, ``k = −1``) no-vp's circle (:meth:`~heapgrasp.loop.phase.Pipeline.plan`
   of ``method = "no-vp"``). ``occupancy`` is what the loop's
   :meth:`~heapgrasp.loop.phase.Pipeline.grasp_candidates` then feeds the grasp
   network: :meth:`~heapgrasp.perception.silhouette.SilhouettePerception.grasp_input`,
   ``Ŝ≥λ`` with the loop's settings (roof trimming included where ``roof_radius`` > 0);
   ``tsdf`` (the VGN baseline): its phase (``method = "vgn"``: the circle, the 640×480
   depth camera with the per-category sensor model) gives the TSDF the loop feeds the
   network of ``input_kind = "tsdf"``. The two are separate datasets because the depth
   frames cost ~20 times the silhouettes (``docs/benchmarks.md``);
3. the labels (:mod:`heapgrasp.sim.grasp_labels`): VGN's sampler, ``points`` surface points ×
   ``yaws`` yaws, labelled on the exact geometry, reduced to one grasp per point as VGN
   does. The points lie on the surface the grid shows (:func:`observed_surface`: the
   TSDF's zero crossings, the hull's boundary), as VGN samples them on the cloud it
   reconstructed; a grasp whose origin (below) lies outside the grid is dropped; then
   balanced: every positive and as many negatives drawn at random (all of them where
   there are fewer).

The grid is ``(R, R, R)`` float32 indexed ``[i, j, k]`` along the world's x, y, z
from ``origin`` (the grid frame of the loop; voxel ``[i, j, k]`` spans ``origin +
[i, j, k] · voxel_size`` to ``origin + [i+1, j+1, k+1] · voxel_size``). A scene with no
object left on the table, or no positive grasp in the grid, is dropped and counted.

Layout on disk (``OUT``): as the view data (:mod:`heapgrasp.data.shards`). Each shard
holds, with leading sample axis ``S`` and grasp axis ``G``: ``occupancy`` or ``tsdf``
(the dataset's input, ``(S, R, R, R)`` float32), ``origin`` (``(S, 3)`` float64),
``voxel_size`` (``(S,)`` float64), ``grasp_scene`` (``(G,)`` int64, the sample of each
grasp), ``grasp_voxel`` (``(G, 3)`` int64, the voxel of its position),
``grasp_position`` (``(G, 3)`` float32, world metres: VGN's grasp origin, the centre of
the palm's face, ``−palm_front`` behind the TCP along the approach, so that a grasp lies
in front of the surface it grasps, where the input shows that surface; format 1 held
the TCP), ``grasp_quat`` (``(G, 4)`` float32, grasp
orientation ``x, y, z, w`` in the world's (= the grid's) axes), ``grasp_width``
(``(G,)`` float32, opening in metres; the gripper's widest for a negative),
``grasp_label`` (``(G,)`` uint8, 1 success, 0 failure), ``scene_seed``, ``scene_index``,
``k`` (``(S,)`` int64; ``k = −1``: the circle, always for ``tsdf``), and the counts
``scenes`` and ``dropped``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.data.scenes import capture_random_views, run_config, split_models
from heapgrasp.data.shards import DatasetSpec, ShardedConfig, generate, run_scenes, write_shard
from heapgrasp.data.shards import read_manifest as _read_manifest

__all__ = [
    "CIRCLE",
    "FORMAT",
    "GraspDataConfig",
    "Scene",
    "draw_scene",
    "generate",
    "grasp_records",
    "grid_surface",
    "observed_surface",
    "read_manifest",
    "scene_sample",
    "shard_samples",
    "surface_grasps",
    "write_shard",
]

F32 = npt.NDArray[np.float32]

FORMAT = "heapgrasp-grasp-data"
VERSION = 2
INPUTS = ("occupancy", "tsdf")
"""The network inputs a dataset can hold (:attr:`GraspDataConfig.input`)."""
CIRCLE = 0.5
"""Share of the scenes whose ``occupancy`` is captured along no-vp's circle (the others:
Algorithm 1's random view waypoints)."""
MEAN_EXTRA_OBJECTS = 4.0
"""VGN's objects per scene: Poisson(4) + 1."""


def _settings() -> dict[str, Any]:
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.perception.depth import DepthPerception

    run = RunConfig()
    names = (
        "resolution",
        "cube_size",
        "lam",
        "roof_radius",
        "U",
        "V",
        "radius",
        "theta_max",
        "fps",
        "ideal_depth",
    )
    return {
        **{name: getattr(run, name) for name in names},
        "circle": CIRCLE,
        "tsdf_truncation": DepthPerception.truncation,
        "labeller": _labeller_digest(),
    }


def _labeller_digest() -> str:
    """What labels the grasps: a digest of :mod:`heapgrasp.sim.grasp_labels` and the
    compiled core (shards of another labeller do not join a dataset)."""
    from heapgrasp import _core
    from heapgrasp.sim import grasp_labels

    digest = hashlib.sha256()
    for path in (grasp_labels.__file__, _core.__file__):
        digest.update(Path(str(path)).read_bytes())
    return digest.hexdigest()[:16]


SPEC = DatasetSpec(FORMAT, VERSION, "grasp dataset", _settings, {"grasps": "grasp_label"})
"""What the manifest says of the grasp dataset."""


@dataclass(frozen=True)
class GraspDataConfig(ShardedConfig):
    """What :func:`generate` makes. The defaults are VGN's scheme with Table I's values."""

    shard_size: int = 25
    """Scenes per shard file."""
    max_objects: int = 5
    """The most objects in a scene (N_ob, Table I): VGN's Poisson(4) + 1 capped here."""
    L: int = 3
    """View waypoints (Table I): ``k ~ U{1..L}`` (Algorithm 1), and no-vp's and VGN's
    circle of ``L`` waypoints."""
    input: str = "occupancy"
    """The network input the samples hold: ``occupancy`` (``Ŝ≥λ``, HEAPGrasp and no-vp)
    or ``tsdf`` (the VGN baseline)."""
    points: int = 600
    """Surface points per scene. VGN samples 120 and executes each in physics; our labels
    cost ~0.1 ms a point (``docs/benchmarks.md``), so a scene gives 5 times VGN's
    grasps for the same capture."""
    yaws: int = 6
    """Yaws per point, in [0, π) (VGN)."""
    gripper: str = "panda"
    """The hand the grasps are labelled for (:data:`heapgrasp.geometry.gripper.GRIPPERS`):
    ``panda`` (VGN's, the simulated hand's convex collision meshes) or ``robotiq-2f140``
    (the real robot's, its :class:`~heapgrasp.geometry.gripper.GripperGeometry` boxes):
    its opening, finger depth and collision shape."""

    spec: ClassVar[DatasetSpec] = SPEC

    def __post_init__(self) -> None:
        super().__post_init__()
        self.positive("max_objects", "L", "points", "yaws")
        if self.input not in INPUTS:
            raise ValueError(f"input must be one of {INPUTS}, got {self.input!r}")
        from heapgrasp.geometry.gripper import gripper_named

        gripper_named(self.gripper)

    def run_shard(self, shard: int) -> dict[str, Any]:
        """Arrays of ``shard`` (:func:`shard_samples`)."""
        return shard_samples(self, shard)


# --------------------------------------------------------------------------- one scene


class _Recorder:
    """A grasp planner that keeps the grid the loop feeds it and plans nothing."""

    name = "recorder"
    sigma = 1.0
    epsilon = 0.8
    opens_fully = False
    needs_hull_check = False

    def __init__(self, input_kind: str) -> None:
        self.input_kind = input_kind
        self.grids: list[F32] = []

    def predict(self, grid: F32, frame: Any) -> Any:
        from heapgrasp.planning.volumes import GraspVolumes

        self.grids.append(np.array(grid, dtype=np.float32, copy=True))
        r = frame.resolution
        zero = np.zeros((r, r, r), np.float32)
        return GraspVolumes(frame, zero, np.zeros((r, r, r, 4), np.float32), zero)

    @property
    def grid(self) -> F32:
        """The grid of the one call."""
        if len(self.grids) != 1:
            raise RuntimeError(f"the loop planned grasps {len(self.grids)} times, not once")
        return self.grids[0]


@dataclass(frozen=True)
class Scene:
    """What scene ``index`` of a dataset is (:func:`draw_scene`)."""

    index: int
    world_seed: int
    """The world's seed (``SimWorld.reset``), the pipelines' and the sample's ``scene_seed``."""
    start: str
    """``p⁰``: ``side`` or ``above``."""
    k: int
    """Algorithm 1's random view waypoints; −1: no-vp's circle."""
    models: tuple[Any, ...]
    layout: Literal["pile", "packed"]
    category: str

    def run_config(self, config: GraspDataConfig, method: str) -> Any:
        """The loop's settings of ``method`` in this scene."""
        return run_config(config.split, self.start, config.L, method)

    @property
    def silhouette_method(self) -> str:
        """The loop method whose captures give ``occupancy``."""
        return "no-vp" if self.k < 0 else "heapgrasp"

    def world(self, library: Any, config: GraspDataConfig) -> Any:
        """The scene's world, settled (close it, or use it as a context manager): as
        :func:`heapgrasp.sim.build.scene_world` builds a run's, with these models."""
        from heapgrasp.sim.optics import DepthModel
        from heapgrasp.sim.world import SimWorld, WorldConfig

        run = self.run_config(config, "vgn")
        world = SimWorld(
            library,
            config=WorldConfig(cube_size=run.cube_size),
            depth_model=DepthModel(ideal=run.ideal_depth),
            seed=self.world_seed,
        )
        world.reset(
            layout=self.layout, category=self.category, seed=self.world_seed, models=self.models
        )
        return world


def draw_scene(
    config: GraspDataConfig, index: int, library: Any
) -> tuple[Scene, np.random.Generator]:
    """Scene ``index`` and the generator its captures and labels draw from next."""
    rng = np.random.default_rng(np.random.SeedSequence([config.root_seed, index]))
    world_seed = int(rng.integers(2**31))
    start = "side" if rng.random() < 0.5 else "above"
    k = -1 if rng.random() < CIRCLE else int(rng.integers(1, config.L + 1))
    pool = split_models(library, config.split)
    n_ob = min(int(rng.poisson(MEAN_EXTRA_OBJECTS)) + 1, config.max_objects, len(pool))
    models = tuple(pool[i] for i in rng.choice(len(pool), size=n_ob, replace=False))
    layout: Literal["pile", "packed"] = "pile" if rng.random() < 0.5 else "packed"
    category = ("transparent", "opaque", "specular", "mixed")[int(rng.integers(4))]
    return Scene(index, world_seed, start, k, models, layout, category), rng


def scene_sample(config: GraspDataConfig, index: int, library: Any = None) -> dict[str, Any] | None:
    """Runs scene ``index``; its sample, or None when dropped."""
    from heapgrasp.geometry.gripper import gripper_named
    from heapgrasp.sim.build import object_library, sim_pipeline

    if library is None:
        library = object_library(run_config(config.split, "side", config.L))
    scene, rng = draw_scene(config, index, library)
    recorder = _Recorder(config.input)
    with scene.world(library, config) as world:
        if not world.objects:
            return None
        seed = scene.world_seed
        if config.input == "occupancy":
            silhouettes = scene.run_config(config, scene.silhouette_method)
            pipeline = sim_pipeline(silhouettes, world, seed=seed, grasp_planner=recorder)
            if scene.k < 0:
                pipeline.plan()
            else:
                capture_random_views(pipeline, rng, scene.k)
                pipeline.grasp_candidates()
        else:
            depth = scene.run_config(config, "vgn")
            pipeline = sim_pipeline(depth, world, seed=seed, grasp_planner=recorder)
            pipeline.plan()
        frame = pipeline.frame
        grasps = surface_grasps(
            world,
            rng,
            recorder.grid,
            config.input,
            frame,
            points=config.points,
            yaws=config.yaws,
            gripper=config.gripper,
        )
    record = grasp_records(grasps, frame, gripper_named(config.gripper), rng, balance=True)
    if record is None:
        return None
    return {
        config.input: recorder.grid,
        "origin": np.asarray(frame.origin, dtype=np.float64),
        "voxel_size": np.float64(frame.voxel_size),
        **record,
        "scene_seed": np.int64(scene.world_seed),
        "scene_index": np.int64(index),
        "k": np.int64(scene.k if config.input == "occupancy" else -1),
    }


def grasp_records(
    grasps: Mapping[str, Any],
    frame: Any,
    hand: Any,
    rng: np.random.Generator | None,
    *,
    balance: bool,
) -> dict[str, Any] | None:
    """A sample's per-grasp arrays (``grasp_voxel``, ``grasp_position``, ``grasp_quat``,
    ``grasp_width``, ``grasp_label``) from labelled TCP poses (``pose`` ``(N, 4, 4)``,
    ``quat``, ``width``, ``label``, as :func:`heapgrasp.sim.grasp_labels.label_samples`
    returns them), for ``hand`` (a
    :class:`~heapgrasp.geometry.gripper.GripperGeometry`).

    Each grasp is held at VGN's grasp origin, the centre of the palm's face (in front of
    the surface grasped); one whose origin lies outside ``frame``'s grid is dropped. A
    failure's width is the widest opening. ``balance``: every positive and as many
    negatives drawn from ``rng`` (all where there are fewer), and None when there is no
    positive; else every grasp in the grid, and None when there is none."""
    pose = np.asarray(grasps["pose"], dtype=np.float64).reshape(-1, 4, 4)
    palm = pose[:, :3, 3] + pose[:, :3, 2] * hand.palm_front
    idx = frame.index(palm)
    inside = ((idx >= 0) & (idx < frame.resolution)).all(axis=1)
    label = np.asarray(grasps["label"], dtype=np.uint8)
    width = np.where(label == 1, np.asarray(grasps["width"]), hand.max_opening)
    if balance:
        positives = np.flatnonzero(inside & (label == 1))
        if len(positives) == 0:
            return None
        negatives = np.flatnonzero(inside & (label == 0))
        n_neg = min(len(negatives), len(positives))
        assert rng is not None, "balancing draws negatives"
        keep = np.sort(np.concatenate([positives, rng.choice(negatives, n_neg, replace=False)]))
    else:
        keep = np.flatnonzero(inside)
        if len(keep) == 0:
            return None
    return {
        "grasp_voxel": idx[keep],
        "grasp_position": palm[keep].astype(np.float32),
        "grasp_quat": np.asarray(grasps["quat"])[keep].astype(np.float32),
        "grasp_width": width[keep].astype(np.float32),
        "grasp_label": label[keep].astype(np.uint8),
    }


def surface_grasps(
    world: Any,
    rng: np.random.Generator,
    grid: F32,
    input_kind: str,
    frame: Any,
    *,
    points: int,
    yaws: int,
    gripper: str,
) -> dict[str, Any]:
    """VGN's grasps of the scene at ``points`` points of the surface ``grid`` shows
    (:func:`observed_surface`), ``yaws`` yaws each for the hand named ``gripper``,
    labelled on ``world``'s exact geometry and reduced to one per point, as
    :func:`heapgrasp.sim.grasp_labels.label_samples` returns them: ``pose`` ``(N, 4,
    4)`` (TCP), ``quat`` ``(N, 4)`` (x, y, z, w), ``width`` ``(N,)`` (the widest opening
    for a failure), ``label`` ``(N,)`` (1 success, 0 failure), …"""
    import dataclasses

    from heapgrasp.geometry.gripper import PANDA_HAND, gripper_named
    from heapgrasp.sim import grasp_labels

    hand = gripper_named(gripper)
    where, normals = observed_surface(grid, input_kind, frame, rng, points)
    samples = grasp_labels.grasps_at(
        where, normals, np.full(len(where), -1, np.int64), rng, yaws, gripper=hand
    )
    # The Panda is labelled with its convex collision meshes; another hand with its boxes.
    parts = None if hand == PANDA_HAND else dataclasses.asdict(hand)
    return dict(grasp_labels.label_samples(world, samples, hand=parts))


MIN_HEIGHT = 0.005
"""Observed surface points lower than this above the grid's floor (the table) are left
out, as VGN crops its cloud 5 mm above the table."""


def grid_surface(
    grid: F32, input_kind: str, frame: Any
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The surface ``grid`` shows, where VGN's grasp points may lie, and its outward unit
    normals, ``(P, 3)`` each (world).

    The surface is a zero crossing (:func:`heapgrasp.perception.depth.tsdf_surface`) of
    the TSDF for ``input_kind = "tsdf"``, and for ``"occupancy"`` of ``0.5 −`` the
    occupancy smoothed by a one-voxel Gaussian (the hull's boundary, phantom parts
    included, with smooth normals). Points lower than :data:`MIN_HEIGHT` above the
    table, or whose normal points more than slightly down (``n_z <=``
    :data:`heapgrasp.sim.grasp_labels.MIN_NORMAL_Z`), are left out, as on the true
    surfaces."""
    from scipy import ndimage

    from heapgrasp.perception.depth import tsdf_surface
    from heapgrasp.sim.grasp_labels import MIN_NORMAL_Z

    if input_kind == "tsdf":
        points, normals = tsdf_surface(grid, frame)
    else:
        smooth = ndimage.gaussian_filter((np.asarray(grid) > 0).astype(np.float64), 1.0)
        field = (0.5 - smooth).astype(np.float32)
        points, normals = tsdf_surface(field, frame, np.ones_like(field))
    keep = (points[:, 2] >= frame.origin[2] + MIN_HEIGHT) & (normals[:, 2] > MIN_NORMAL_Z)
    return points[keep], normals[keep]


def observed_surface(
    grid: F32, input_kind: str, frame: Any, rng: np.random.Generator, count: int
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """``count`` points drawn uniformly, with replacement, from :func:`grid_surface` and
    their normals, ``(P, 3)`` each (world; ``P`` is 0 where the grid shows no surface):
    VGN's grasp points, sampled on what the camera reconstructed rather than on the
    true meshes, so that a label's approach follows what the network sees."""
    points, normals = grid_surface(grid, input_kind, frame)
    if len(points) == 0 or count == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    pick = rng.choice(len(points), size=count, replace=True)
    return points[pick], normals[pick]


# --------------------------------------------------------------------------- shards

_PER_SCENE = {
    "origin": np.float64,
    "voxel_size": np.float64,
    "scene_seed": np.int64,
    "scene_index": np.int64,
    "k": np.int64,
}
_PER_GRASP = {
    "grasp_voxel": (np.int64, (3,)),
    "grasp_position": (np.float32, (3,)),
    "grasp_quat": (np.float32, (4,)),
    "grasp_width": (np.float32, ()),
    "grasp_label": (np.uint8, ()),
}


def shard_samples(config: GraspDataConfig, shard: int) -> dict[str, Any]:
    """Arrays of ``shard`` (every scene of it run in this process)."""
    from heapgrasp.loop.config import RunConfig

    samples, scenes = run_scenes(config, shard, scene_sample)
    r = RunConfig().resolution
    shapes = {config.input: (r, r, r), "origin": (3,)}
    data: dict[str, Any] = {}
    for key, dtype in {config.input: np.float32, **_PER_SCENE}.items():
        empty = np.zeros((0, *shapes.get(key, ())), dtype)
        data[key] = np.stack([s[key] for s in samples]).astype(dtype) if samples else empty
    counts = [len(s["grasp_label"]) for s in samples]
    data["grasp_scene"] = np.repeat(np.arange(len(samples), dtype=np.int64), counts)
    for key, (dtype, shape) in _PER_GRASP.items():
        parts = [s[key] for s in samples]
        data[key] = np.concatenate(parts).astype(dtype) if parts else np.zeros((0, *shape), dtype)
    data["scenes"] = np.int64(len(scenes))
    data["dropped"] = np.int64(len(scenes) - len(samples))
    return data


def read_manifest(out: Path) -> dict[str, Any]:
    """The dataset's ``manifest.json``; ValueError naming the file when it is not one."""
    return _read_manifest(out, SPEC)
