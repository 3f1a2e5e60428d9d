"""Training data for the grasp critic: grasp candidates on measured hulls, each tried in
the simulator.

For every scene (seed ``seed + i``, objects of the **train** split, so none of the
benchmark's test objects; ``split = "test"`` makes files for measuring only) a phase
of ``method`` runs as it does in ``heapgrasp run`` (HEAPGrasp's oracle views or no-vp's
circle, the antipodal planner, Table I parameters), from the start above the scene for
even scenes and from the default start for odd ones. On the phase's final grid every
candidate of :func:`~heapgrasp.planning.volumes.select_candidates` at a low threshold
(``epsilon``, up to ``max_candidates``) is executed with VGN's protocol
(:func:`~heapgrasp.sim.gripper.execute_grasp`) from a saved physics state, which is
restored after each try, so each candidate is labelled by what it would have done. An
object one of them picked is then removed, and the next phase starts, up to
``max_phases`` phases.

Each scene is written as ``OUT/scene_SEED.npz`` (scenes already there are skipped, so
an interrupted run continues): per phase the planner's input grid, the untrimmed
high-confidence grid ``Ŝ≥λ`` and the camera positions of its frames; per candidate the
phase, TCP pose, width, score and outcome (:class:`~heapgrasp.sim.gripper.GraspOutcome`
value); and the names of the scene's objects.
"""

from __future__ import annotations

import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.loop.config import RunConfig

__all__ = ["CriticDataConfig", "generate", "load_dataset", "scene_data"]

F64 = npt.NDArray[np.float64]

TOP_START = {"start": "above"}
"""The start above the scene of ``docs/benchmarks.md`` (even scenes)."""

OWN_FIELDS = frozenset({"method", "split", "objects", "seed", "scenes", "grasp_critic", *TOP_START})
"""RunConfig fields that :class:`CriticDataConfig` sets from its own options."""


@dataclass(frozen=True)
class CriticDataConfig:
    """What :func:`generate` runs."""

    scenes: int = 100
    seed: int = 1000
    epsilon: float = 0.2
    max_candidates: int = 12
    max_phases: int = 4
    objects: int = 5
    method: str = "heapgrasp"
    """``heapgrasp`` (oracle views) or ``no-vp`` (the circle): whose hulls to sample."""
    critic: str = "none"
    """The critic that steers the phases' views (``RunConfig.grasp_critic``: ``none``,
    ``default`` or a file): with a critic, HEAPGrasp's targets of eq. 16, and so its
    views, are the ones it makes when deployed with it. The labelled candidates are the
    planner's own either way."""
    object_seeds: tuple[int, ...] = ()
    """Seeds of :func:`~heapgrasp.sim.procedural.generate_procedural` whose objects join the
    benchmark library's train split in the scenes, all of them (``test_fraction = 0``).
    Any seed but 0 makes objects that share no mesh with the benchmark's, so the critic
    sees more shapes without seeing a test object."""
    split: Literal["train", "test"] = "train"
    """Objects of the benchmark library's ``train`` split, or ``test`` to *measure* a
    critic on the benchmark's own objects (``heapgrasp critic eval``): files of the test
    split record it, and :func:`load_dataset` refuses them for training."""
    overrides: tuple[tuple[str, Any], ...] = ()
    """Other :class:`~heapgrasp.loop.config.RunConfig` fields of the phases, as ``(key,
    value)`` pairs (``--set KEY=VALUE``), e.g. ``target_radius = 0``: the files
    then measure how often *any* candidate holds on that setting's hulls. The fields
    this data sets itself (:data:`OWN_FIELDS`) cannot be overridden."""

    def __post_init__(self) -> None:
        if self.method not in ("heapgrasp", "no-vp"):
            raise ValueError(f"method must be 'heapgrasp' or 'no-vp', got {self.method!r}")
        if self.scenes < 1:
            raise ValueError(f"scenes must be >= 1, got {self.scenes}")
        if not 0.0 <= self.epsilon <= 1.0:
            raise ValueError(f"epsilon must be in [0, 1], got {self.epsilon}")
        if self.max_candidates < 1:
            raise ValueError(f"max_candidates must be >= 1, got {self.max_candidates}")
        if self.max_phases < 1:
            raise ValueError(f"max_phases must be >= 1, got {self.max_phases}")
        if self.objects < 1:
            raise ValueError(f"objects must be >= 1, got {self.objects}")
        if self.split not in ("train", "test"):
            raise ValueError(f"split must be 'train' or 'test', got {self.split!r}")
        if self.split == "test" and self.object_seeds:
            raise ValueError("object_seeds add training objects; they do not go with split='test'")
        for s in self.object_seeds:
            if isinstance(s, bool) or not isinstance(s, int) or s < 1:
                raise ValueError(
                    f"object_seeds must be ints >= 1 (0 is the benchmark's own), got {s!r}"
                )
        if len(set(self.object_seeds)) != len(self.object_seeds):
            raise ValueError(f"object_seeds has a seed twice: {self.object_seeds}")
        own = sorted({k for k, _ in self.overrides} & OWN_FIELDS)
        if own:
            raise ValueError(
                f"overrides: {', '.join(own)} set by the critic data's own options, not --set"
            )
        if self.critic == "auto":
            raise ValueError("critic must be 'none', 'default' or a file path, got 'auto'")
        if self.critic not in ("none", "default") and not Path(self.critic).is_file():
            raise FileNotFoundError(f"grasp critic file not found: {self.critic}")
        self.run_config(0)  # a bad override raises ConfigError naming it, before any scene

    def run_config(self, index: int) -> RunConfig:
        """The pipeline's configuration for scene ``index``."""
        start = TOP_START if index % 2 == 0 else {}
        config = RunConfig(
            method=self.method,
            split=self.split,
            objects=self.objects,
            seed=self.seed,
            grasp_critic=self.critic,
            # the phases as the critic's data has always sampled them: one look each
            look_again=0,
            fine_width=False,
            **start,  # type: ignore[arg-type]
        )
        return config.replace(dict(self.overrides), source="critic data --set")


def scene_data(config: CriticDataConfig, index: int) -> dict[str, Any]:
    """Runs scene ``index`` and returns its arrays (see the module docstring)."""
    from heapgrasp.perception.silhouette import SilhouettePerception
    from heapgrasp.planning.volumes import select_candidates
    from heapgrasp.sim.build import make_body, object_library, scene_world, sim_pipeline
    from heapgrasp.sim.bullet import pb
    from heapgrasp.sim.gripper import MAX_OPENING, Grasp, GraspOutcome, execute_grasp
    from heapgrasp.sim.procedural import generate_procedural

    run_config = config.run_config(index)
    seed = config.seed + index
    categories = ("transparent", "opaque", "specular", "mixed")
    inputs, highs, cameras = [], [], []
    rows: list[dict[str, Any]] = []
    library = object_library(run_config)
    for object_seed in config.object_seeds:
        library.add(
            generate_procedural(
                library.cache_dir, count_per_kind=16, seed=object_seed, test_fraction=0.0
            )
        )
    with scene_world(run_config, seed, categories[index % 4], library=library) as world:
        names = [o.model.name for o in world.objects.values()]
        body = make_body(run_config, world)
        pipeline = sim_pipeline(run_config, world, seed=seed, body=body)
        perception = pipeline.perception
        if not isinstance(perception, SilhouettePerception):
            raise TypeError("the critic's data needs a silhouette method")
        for phase in range(config.max_phases):
            if not world.objects:
                break
            pipeline.plan()
            grid = perception.grasp_input()
            volumes = pipeline.grasp_planner.predict(grid, pipeline.frame)
            sigma = pipeline.grasp_planner.sigma
            candidates = select_candidates(
                volumes, epsilon=config.epsilon, sigma=sigma, nms_window=run_config.nms_window
            )[: config.max_candidates]
            if not candidates:
                break
            inputs.append(grid > 0.5)
            highs.append(perception.grid.high_confidence(run_config.lam) > 0.5)
            cameras.append(np.stack([v.cam2world[:3, 3] for v in perception.views]))
            state = pb.saveState(physicsClientId=world.client)
            picked: int | None = None
            for c in candidates:
                result = execute_grasp(body, Grasp(c.pose, min(c.width, MAX_OPENING)))
                rows.append(
                    {
                        "phase": phase,
                        "pose": c.pose,
                        "width": c.width,
                        "score": c.score,
                        "outcome": result.outcome.value,
                    }
                )
                if result.outcome == GraspOutcome.SUCCESS and picked is None:
                    picked = result.object_id
                pb.restoreState(state, physicsClientId=world.client)
                world.sync()
                body.park()
            pb.removeState(state, physicsClientId=world.client)
            if picked is None or picked not in world.objects:
                break
            world.remove(picked)
            world.step(0.5)
            world.sync()
    n_cams = [len(c) for c in cameras]
    return {
        "seed": np.int64(seed),
        "start": np.str_("top" if index % 2 == 0 else "default"),
        "method": np.str_(config.method),
        "critic": np.str_(config.critic),
        "object_seeds": np.asarray(config.object_seeds, dtype=np.int64),
        "split": np.str_(config.split),
        "overrides": np.str_(json.dumps(dict(config.overrides), sort_keys=True)),
        "objects": np.asarray(names, dtype=np.str_),
        "grasp_input": np.stack(inputs) if inputs else np.zeros((0, 0, 0, 0), bool),
        "high": np.stack(highs) if highs else np.zeros((0, 0, 0, 0), bool),
        "camera_positions": np.concatenate(cameras) if cameras else np.zeros((0, 3)),
        "camera_counts": np.asarray(n_cams, dtype=np.int64),
        "phase": np.asarray([r["phase"] for r in rows], dtype=np.int64),
        "pose": np.asarray([r["pose"] for r in rows], dtype=np.float64).reshape(-1, 4, 4),
        "width": np.asarray([r["width"] for r in rows], dtype=np.float64),
        "score": np.asarray([r["score"] for r in rows], dtype=np.float64),
        "outcome": np.asarray([r["outcome"] for r in rows], dtype=np.str_),
    }


def _one(args: tuple[CriticDataConfig, int, str]) -> str:
    config, index, out = args
    path = Path(out) / f"scene_{config.seed + index:06d}.npz"
    data = scene_data(config, index)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **data)
    os.replace(tmp, path)
    return str(path)


def _init_worker() -> None:
    from heapgrasp.loop.workers import init_worker

    init_worker()  # one core each, and dying with the parent


def generate(config: CriticDataConfig, out: Path, *, workers: int = 1) -> list[Path]:
    """Writes ``OUT/scene_SEED.npz`` for every scene not yet there; returns all paths."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    out.mkdir(parents=True, exist_ok=True)
    todo = [
        i for i in range(config.scenes) if not (out / f"scene_{config.seed + i:06d}.npz").exists()
    ]
    jobs = [(config, i, str(out)) for i in todo]
    bar = tqdm(
        total=config.scenes, initial=config.scenes - len(todo), unit="scene", file=sys.stderr
    )
    if workers <= 1:
        for job in jobs:
            _one(job)
            bar.update()
    else:
        with ProcessPoolExecutor(workers, initializer=_init_worker) as pool:
            for _ in pool.map(_one, jobs):
                bar.update()
    bar.close()
    return [out / f"scene_{config.seed + i:06d}.npz" for i in range(config.scenes)]


def load_dataset(paths: list[Path], *, training: bool = False) -> list[dict[str, Any]]:
    """Reads scene files written by :func:`generate`.

    With ``training``, a file of the test split (``CriticDataConfig.split``) raises
    ValueError naming it: those scenes hold the benchmark's objects.
    """
    scenes = []
    for p in paths:
        with np.load(p) as data:
            scene = {k: data[k] for k in data.files}
        if training and str(scene.get("split", "train")) != "train":
            raise ValueError(
                f"{p} holds test-split objects (critic data --split test): it is for "
                "'heapgrasp critic eval', not for training"
            )
        scenes.append(scene)
    return scenes
