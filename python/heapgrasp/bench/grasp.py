"""``heapgrasp bench grasp``: the analytic antipodal grasp planner, one grasp per scene.

For ``--scenes`` seeded scenes (scene ``i`` has seed ``seed + i``, built as
:func:`heapgrasp.run.run_scene` builds it: the procedural object set, test split) the
benchmark carves a high-confidence occupancy grid ``Ŝ≥λ`` from ideal masks, plans
with :class:`~heapgrasp.planning.antipodal.AntipodalPlanner` and
:func:`~heapgrasp.planning.volumes.select_candidates`, and executes the top-scoring
candidate with the free-flying Panda hand (:func:`heapgrasp.sim.gripper.execute_grasp`):
one attempt per scene and grid. Grids (``--grids``):

``circle``
    The no-vp protocol (HEAPGrasp w/o VP): a capture at the initial pose p⁰ (0.5 m
    from the scene on its −y side), then
    once around the circle of L = 3 waypoints at θ = π/5 on the r = 0.33 m view sphere
    of the 0.30 m cube, capturing continuously along the ruckig-timed path
    (:meth:`heapgrasp.loop.phase.Pipeline.plan` of a ``no-vp`` run).
``dense``
    An upper bound for Shape from Silhouette: 129 still views, one from the top and
    8 rings of 16 views at polar angles up to 75° on a sphere of radius 0.5 m about the
    bottom centre of the cube (:func:`dense_waypoints`).

The world is reset before each grid, so every grid sees the same scene. Reported per
grid: scenes, scenes with a candidate, attempts, successes, the success rate
(successes / attempts), the outcome of every attempt, how many executed grasps were more
than 3 cm from every object (aimed at nothing), and the planner time (predict +
select). Writes ``OUT/results.json`` (command, machine, configuration, summary and
per-scene records) and ``OUT/table.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from heapgrasp.loop.config import ConfigError, RunConfig

if TYPE_CHECKING:
    from heapgrasp.geometry.motion import ViewSphere
    from heapgrasp.planning.antipodal import AntipodalPlanner
    from heapgrasp.sim.world import SimWorld

__all__ = [
    "DENSE_AZIMUTH",
    "DENSE_POLAR",
    "DENSE_RADIUS",
    "DENSE_THETA_MAX",
    "FAR_FROM_OBJECTS_M",
    "GRIDS",
    "GraspBenchConfig",
    "dense_waypoints",
    "markdown_table",
    "run",
    "run_bench",
    "summarize",
]

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]

GRIDS: tuple[str, ...] = ("circle", "dense")
"""Grid kinds, in the order they run and are reported."""

FAR_FROM_OBJECTS_M = 0.03
"""An executed grasp whose TCP is farther than this (m) from the surface of every object
aimed at nothing (the radius :meth:`heapgrasp.loop.phase.Pipeline._object_near` uses to
name a grasp's target)."""

DENSE_RADIUS = 0.5
"""Radius (m) of the ``dense`` view sphere: from there the 0.30 m cube stays in the
320×240 view, so every voxel is seen from most views."""
DENSE_POLAR = 8
"""Rings of the ``dense`` views (polar angles ``DENSE_THETA_MAX * k / DENSE_POLAR``,
``k = 1 .. DENSE_POLAR``)."""
DENSE_AZIMUTH = 16
"""Views per ring of the ``dense`` grid (every other ring turned by half a step)."""
DENSE_THETA_MAX = math.radians(75.0)
"""Polar angle (rad) of the lowest ``dense`` ring."""

NO_CANDIDATE = "no_candidate"
"""Outcome of a scene whose grid gave no candidate (nothing is executed)."""


@dataclass(frozen=True)
class GraspBenchConfig:
    """What ``heapgrasp bench grasp`` evaluates.

    Attributes
    ----------
    scenes : int
        Number of scenes; scene ``i`` has seed ``seed + i``.
    seed : int
        Seed of scene 0.
    layout : str
        ``"pile"`` or ``"packed"``.
    objects : int
        Objects placed per scene (some may fall outside the cube and be removed).
    category : str
        Scene group (``mixed``, ``opaque``, ``specular`` or ``transparent``); masks are
        ideal, so it has no optical effect, only on the scene's random draws.
    grids : tuple of str
        Grid kinds among :data:`GRIDS`.
    epsilon, sigma : float
        Threshold ε and Gaussian σ (voxels) of :func:`select_candidates`; the defaults
        are :class:`~heapgrasp.planning.antipodal.AntipodalPlanner`'s own.
    nms_window : int
        Non-maximum-suppression window of :func:`select_candidates`.
    roof_radius : float
        Disc radius (m) with which both grids' roofs are trimmed before planning
        (:func:`heapgrasp.perception.roofs.trim_roofs`, as the pipeline does); 0 plans on ``Ŝ≥λ``.
    """

    scenes: int = 30
    seed: int = 0
    layout: str = "pile"
    objects: int = 5
    category: str = "mixed"
    grids: tuple[str, ...] = GRIDS
    epsilon: float = 0.4
    sigma: float = 0.5
    nms_window: int = 4
    roof_radius: float = RunConfig.roof_radius

    def __post_init__(self) -> None:
        if not self.grids or any(g not in GRIDS for g in self.grids):
            raise ConfigError(f"grids: must be a non-empty subset of {GRIDS}; got {self.grids!r}")
        self.run_config()  # validates the rest (ConfigError naming the field)

    def run_config(self) -> RunConfig:
        """The ``no-vp`` :class:`RunConfig` of these scenes (Table I elsewhere)."""
        return RunConfig(
            method="no-vp",
            layout=self.layout,
            category=self.category,
            objects=self.objects,
            scenes=self.scenes,
            seed=self.seed,
            epsilon=self.epsilon,
            sigma=self.sigma,
            nms_window=self.nms_window,
            roof_radius=self.roof_radius,
            look_again=0,  # one circle: the grid this benchmark compares
        )


# --------------------------------------------------------------------------------------
# Grids
# --------------------------------------------------------------------------------------


def dense_waypoints(
    sphere: ViewSphere,
    *,
    n_polar: int = DENSE_POLAR,
    n_azimuth: int = DENSE_AZIMUTH,
    theta_max: float = DENSE_THETA_MAX,
) -> F64:
    """The ``dense`` views: the top of a view sphere and ``n_polar`` rings below it.

    Parameters
    ----------
    sphere : ViewSphere
        The view sphere (every view looks at ``sphere.target``), e.g.
        ``ViewSphere.for_cube(origin, size, radius=DENSE_RADIUS)``.
    n_polar, n_azimuth : int
        Rings at polar angles ``theta_max * k / n_polar`` (``k = 1 .. n_polar``) of
        ``n_azimuth`` evenly spaced views each; odd rings are turned by half a step.
    theta_max : float
        Polar angle of the lowest ring (rad), in ``(0, π/2)``.

    Returns
    -------
    numpy.ndarray, float64, shape (1 + n_polar * n_azimuth, 4, 4)
        ``cam2world`` poses (OpenCV axes), the top view first.
    """
    if n_polar < 1 or n_azimuth < 1:
        raise ValueError(f"n_polar, n_azimuth: must be >= 1, got {n_polar}, {n_azimuth}")
    if not 0.0 < theta_max < math.pi / 2:
        raise ValueError(f"theta_max: must be in (0, pi/2) rad, got {theta_max}")
    poses = [sphere.pose(0.0, 0.0)]
    step = 2.0 * math.pi / n_azimuth
    for k in range(1, n_polar + 1):
        theta = theta_max * k / n_polar
        turn = 0.5 * step * (k % 2)
        poses.extend(sphere.pose(turn + step * j, theta) for j in range(n_azimuth))
    return np.stack(poses)


# --------------------------------------------------------------------------------------
# One scene
# --------------------------------------------------------------------------------------


class _SurfaceDistance:
    """Distance from a point to the surface of the nearest object.

    Exact point-to-triangle distances on the objects' visual meshes (the ground truth the
    masks are rendered from). The nearest mesh *vertex*, which
    :meth:`heapgrasp.loop.phase.Pipeline._object_near` uses, over-estimates the distance
    near the large faces of coarse meshes (a box has eight vertices).
    """

    def __init__(self) -> None:
        self._triangles: dict[str, F64] = {}

    def _mesh(self, path: Path) -> F64:
        from heapgrasp.sim.mesh_files import load_mesh

        key = str(path)
        if key not in self._triangles:
            vertices, faces = load_mesh(path)
            self._triangles[key] = np.ascontiguousarray(vertices[faces], dtype=np.float64)
        return self._triangles[key]

    def nearest(self, world: SimWorld, point: F64) -> tuple[int | None, float]:
        """World id of the object nearest ``point`` (world frame, m) and the distance to
        its surface (m); ``(None, inf)`` without objects."""
        from trimesh.triangles import closest_point

        best, best_d = None, math.inf
        for oid, obj in world.objects.items():
            obj2world = world.object_pose(oid)
            local = obj2world[:3, :3].T @ (np.asarray(point, dtype=np.float64) - obj2world[:3, 3])
            triangles = self._mesh(obj.model.visual_mesh)
            closest = closest_point(  # type: ignore[no-untyped-call,unused-ignore]
                triangles, np.broadcast_to(local, (len(triangles), 3))
            )
            d = float(np.min(np.linalg.norm(closest - local, axis=1)))
            if d < best_d:
                best, best_d = oid, d
        return best, best_d


def _object_name(world: SimWorld, object_id: int | None) -> str | None:
    if object_id is None or object_id not in world.objects:
        return None
    return str(world.objects[object_id].model.name)


def _reset(world: SimWorld, config: RunConfig, seed: int) -> None:
    """Scene ``seed`` as :func:`heapgrasp.run.run_scene` builds it."""
    world.reset(
        layout=config.layout,  # type: ignore[arg-type]
        n_objects=config.objects,
        category=config.category,
        seed=seed,
        split=config.split,  # type: ignore[arg-type]
    )


def _evaluate(
    world: SimWorld,
    config: GraspBenchConfig,
    planner: AntipodalPlanner,
    kind: str,
    scene: int,
    surface: _SurfaceDistance,
) -> dict[str, Any]:
    """Carves grid ``kind`` of scene ``scene``, plans and executes its top candidate."""
    from heapgrasp.geometry.camera import CameraSpec
    from heapgrasp.geometry.grid import GridFrame
    from heapgrasp.geometry.motion import ViewSphere
    from heapgrasp.loop.phase import MEMORY_TOLERANCE, SILHOUETTE_VIEWS
    from heapgrasp.perception.segmenters import IdealSegmenter
    from heapgrasp.perception.silhouette import SilhouettePerception
    from heapgrasp.planning.volumes import select_candidates
    from heapgrasp.sim.build import make_body, sim_pipeline
    from heapgrasp.sim.gripper import Grasp, PandaHand, execute_grasp
    from heapgrasp.sim.robot import Robot
    from heapgrasp.sim.truth import SimTruth

    seed = config.seed + scene
    run_config = config.run_config()
    _reset(world, run_config, seed)
    objects = len(world.objects)
    origin = (0.0, 0.0, 0.0)
    frame = GridFrame(origin, run_config.cube_size, run_config.resolution)
    hand: Robot
    if kind == "circle":
        hand = make_body(run_config, world)
        pipeline = sim_pipeline(run_config, world, grasp_planner=planner, seed=seed, body=hand)
        # The no-vp phase up to the grasp; it also plans a grasp, which is discarded:
        # the planner is timed and run below, as for the dense grid.
        pipeline.plan()
        if not isinstance(pipeline.perception, SilhouettePerception):
            raise TypeError("the no-vp pipeline must carve silhouettes")
        perception = pipeline.perception
    elif kind == "dense":
        perception = SilhouettePerception(
            frame,
            IdealSegmenter(SimTruth(world)),
            lam=run_config.lam,
            roof_radius=run_config.roof_radius,
            silhouette_views=SILHOUETTE_VIEWS,
            memory_tolerance=MEMORY_TOLERANCE,
        )
        camera = CameraSpec.continuous()
        sphere = ViewSphere.for_cube(origin, run_config.cube_size, radius=DENSE_RADIUS)
        perception.update([world.capture(p, camera, depth=False) for p in dense_waypoints(sphere)])
        hand = PandaHand(world)
    else:
        raise ValueError(f"grid kind must be one of {GRIDS}, got {kind!r}")
    grid = perception.grasp_input()
    t0 = time.perf_counter()
    volumes = planner.predict(grid, frame)
    candidates = select_candidates(
        volumes, epsilon=config.epsilon, sigma=config.sigma, nms_window=config.nms_window
    )
    planner_ms = 1e3 * (time.perf_counter() - t0)
    record: dict[str, Any] = {
        "scene": scene,
        "seed": seed,
        "grid": kind,
        "objects": objects,
        "frames": perception.frames_seen,
        "occupied_voxels": int(np.count_nonzero(grid)),
        "quality_max": float(volumes.quality.max(initial=0.0)),
        "candidates": len(candidates),
        "planner_ms": planner_ms,
        "outcome": NO_CANDIDATE,
        "grasp": None,
    }
    if not candidates:
        return record
    best = candidates[0]  # best first
    target, distance = surface.nearest(world, best.position)
    approach = best.pose[:3, 2]
    result = execute_grasp(hand, Grasp(best.pose, best.width))
    record.update(
        outcome=result.outcome.value,
        grasp={
            "position": best.position.tolist(),
            "quaternion": best.quaternion.tolist(),
            "width": best.width,
            "score": best.score,
            "index": list(best.index),
            "tilt_deg": math.degrees(math.acos(float(np.clip(-approach[2], -1.0, 1.0)))),
            "nearest_object": _object_name(world, target),
            "nearest_object_distance_m": distance,
            "far_from_objects": distance > FAR_FROM_OBJECTS_M,
            "held_object": _object_name(world, result.object_id),
        },
    )
    return record


# --------------------------------------------------------------------------------------
# Summary and report
# --------------------------------------------------------------------------------------


def _ms_stats(values: Sequence[float]) -> dict[str, float | None]:
    if not values:
        return {"mean": None, "median": None, "max": None}
    return {
        "mean": float(statistics.fmean(values)),
        "median": float(statistics.median(values)),
        "max": float(max(values)),
    }


def summarize(
    records: Sequence[dict[str, Any]], grids: Sequence[str] = GRIDS
) -> dict[str, dict[str, Any]]:
    """Per grid kind: counts, success rate, outcomes and planner time.

    Parameters
    ----------
    records : sequence of dict
        Per-scene records (``grid``, ``outcome``, ``planner_ms``, ``grasp`` with
        ``far_from_objects``), or ``{"grid", "error"}`` for a scene that raised.
    grids : sequence of str
        Grid kinds to summarize, in order (each present even without records).

    Returns
    -------
    dict
        ``{grid: {"scenes", "errors", "scenes_with_candidate", "attempts", "successes",
        "success_rate", "outcomes", "far_from_objects", "planner_ms"}}``; ``scenes``
        counts the scenes evaluated without error, ``success_rate`` is successes /
        attempts (None without attempts), ``outcomes`` counts every
        :class:`~heapgrasp.sim.gripper.GraspOutcome` value, ``planner_ms`` holds the
        mean, median and max of predict + select over the scenes (ms).
    """
    from heapgrasp.sim.gripper import GraspOutcome

    out: dict[str, dict[str, Any]] = {}
    for kind in grids:
        mine = [r for r in records if r["grid"] == kind]
        done = [r for r in mine if "error" not in r]
        attempted = [r for r in done if r["outcome"] != NO_CANDIDATE]
        outcomes = {o.value: sum(r["outcome"] == o.value for r in attempted) for o in GraspOutcome}
        successes = outcomes[GraspOutcome.SUCCESS.value]
        out[kind] = {
            "scenes": len(done),
            "errors": len(mine) - len(done),
            "scenes_with_candidate": sum(r["candidates"] > 0 for r in done),
            "attempts": len(attempted),
            "successes": successes,
            "success_rate": successes / len(attempted) if attempted else None,
            "outcomes": outcomes,
            "far_from_objects": sum(bool(r["grasp"]["far_from_objects"]) for r in attempted),
            "planner_ms": _ms_stats([float(r["planner_ms"]) for r in done]),
        }
    return out


def _fmt(x: float | None, spec: str) -> str:
    return "–" if x is None else format(x, spec)


def markdown_table(summary: dict[str, dict[str, Any]], config: GraspBenchConfig) -> str:
    """The summary as a Markdown table under a one-line description of the run."""
    last = config.seed + config.scenes - 1
    lines = [
        f"# heapgrasp bench grasp — {config.scenes} scene{'s' * (config.scenes != 1)} × "
        f"{config.objects} objects "
        f"({config.layout}, {config.category}, seeds {config.seed}–{last})",
        "",
        f"AntipodalPlanner + select_candidates (ε = {config.epsilon:g}, σ = {config.sigma:g}, "
        f"NMS window {config.nms_window}) on grids with roofs trimmed at "
        f"{config.roof_radius:g} m; top candidate executed with the free-flying "
        "Panda hand, one attempt per scene.",
        "",
        "| Grid | Scenes | With candidate | Attempts | Successes | Success (%) "
        "| Outcomes | Far from objects (> 3 cm) | Planner mean (ms) | Planner median (ms) |",
        "|---|--:|--:|--:|--:|--:|---|--:|--:|--:|",
    ]
    for kind, s in summary.items():
        rate = s["success_rate"]
        outcomes = ", ".join(f"{k} {v}" for k, v in s["outcomes"].items() if v) or "–"
        lines.append(
            f"| {kind} | {s['scenes']} | {s['scenes_with_candidate']} | {s['attempts']} "
            f"| {s['successes']} | {_fmt(None if rate is None else 100 * rate, '.1f')} "
            f"| {outcomes} | {s['far_from_objects']} | {_fmt(s['planner_ms']['mean'], '.0f')} "
            f"| {_fmt(s['planner_ms']['median'], '.0f')} |"
        )
    errors = {k: s["errors"] for k, s in summary.items() if s["errors"]}
    if errors:
        lines += ["", f"Scenes that raised (not counted): {errors}"]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------
# Run
# --------------------------------------------------------------------------------------


def run_bench(
    config: GraspBenchConfig,
    *,
    progress: bool = True,
    on_record: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Evaluates every scene on every grid of ``config``; returns the records.

    Parameters
    ----------
    config : GraspBenchConfig
        Scenes, grids and post-processing.
    progress : bool
        Show a progress bar on stderr.
    on_record : callable, optional
        Called with each record as soon as it is made.

    Returns
    -------
    list of dict
        One record per scene and grid, scene-major: ``scene``, ``seed``, ``grid``,
        ``objects`` (in the scene), ``frames`` (carved), ``occupied_voxels`` (of
        ``Ŝ≥λ``), ``quality_max`` (largest raw grasp quality; 0 when the planner found no
        grasp at all), ``candidates``, ``planner_ms`` (predict + select), ``outcome`` (a
        :class:`~heapgrasp.sim.gripper.GraspOutcome` value or ``"no_candidate"``) and
        ``grasp`` (None without a candidate, else the executed candidate: pose, width,
        score, approach tilt from vertical, the nearest object, the distance of the TCP
        to its surface, ``far_from_objects`` and the object held after lifting). A scene
        that raises is recorded as ``{"scene", "seed", "grid", "error"}`` and the run
        goes on.
    """
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    from heapgrasp.planning.antipodal import AntipodalPlanner
    from heapgrasp.sim.build import object_library
    from heapgrasp.sim.gripper import GraspOutcome
    from heapgrasp.sim.world import SimWorld, WorldConfig

    run_config = config.run_config()
    planner = AntipodalPlanner()
    surface = _SurfaceDistance()
    records: list[dict[str, Any]] = []
    tally = {kind: [0, 0] for kind in config.grids}  # successes, attempts
    bar = tqdm(
        total=config.scenes * len(config.grids),
        desc="bench grasp",
        unit="grasp",
        disable=not progress,
        file=sys.stderr,
        dynamic_ncols=True,
    )
    try:
        with SimWorld(
            object_library(run_config),
            config=WorldConfig(cube_size=run_config.cube_size),
            seed=config.seed,
        ) as world:
            for scene in range(config.scenes):
                for kind in config.grids:
                    try:
                        record = _evaluate(world, config, planner, kind, scene, surface)
                    except Exception as exc:  # recorded, the run goes on
                        record = {
                            "scene": scene,
                            "seed": config.seed + scene,
                            "grid": kind,
                            "error": f"{type(exc).__name__}: {exc}",
                        }
                    records.append(record)
                    if on_record is not None:
                        on_record(record)
                    if record.get("outcome", NO_CANDIDATE) != NO_CANDIDATE:
                        tally[kind][1] += 1
                        tally[kind][0] += record["outcome"] == GraspOutcome.SUCCESS.value
                    bar.set_postfix_str(" ".join(f"{k} {s}/{a}" for k, (s, a) in tally.items()))
                    bar.update(1)
    finally:
        bar.close()
    return records


def run(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp bench grasp`` with parsed arguments.

    Returns
    -------
    int
        0, or 1 when a scene raised.
    """
    from heapgrasp.bench.carve import machine_info
    from heapgrasp.planning.antipodal import AntipodalPlanner

    defaults = AntipodalPlanner()
    config = GraspBenchConfig(
        scenes=args.scenes,
        seed=args.seed,
        layout=args.layout,
        objects=args.objects,
        category=args.category,
        grids=args.grids,
        epsilon=defaults.epsilon if args.epsilon is None else args.epsilon,
        sigma=defaults.sigma if args.sigma is None else args.sigma,
        roof_radius=args.roof_radius,
    )
    out: Path = args.out or Path("runs") / f"bench-grasp-{time.strftime('%Y%m%d-%H%M%S')}"
    out.mkdir(parents=True, exist_ok=True)
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    t0 = time.perf_counter()
    records = run_bench(config, progress=not args.quiet)
    wall = time.perf_counter() - t0
    summary = summarize(records, config.grids)
    table = markdown_table(summary, config)
    payload = {
        "benchmark": "grasp",
        "command": " ".join(["heapgrasp", *getattr(args, "argv", ["bench", "grasp"])]),
        "started": started,
        "wall_time_s": wall,
        "machine": machine_info(),
        "config": {
            **asdict(config),
            "planner": repr(defaults),
            "split": RunConfig().split,
            "object_set": RunConfig().object_set,
            "dense_views": {
                "radius_m": DENSE_RADIUS,
                "polar_rings": DENSE_POLAR,
                "azimuths": DENSE_AZIMUTH,
                "theta_max_deg": math.degrees(DENSE_THETA_MAX),
            },
            "far_from_objects_m": FAR_FROM_OBJECTS_M,
        },
        "summary": summary,
        "records": records,
    }
    (out / "results.json").write_text(json.dumps(payload, indent=2) + "\n")
    (out / "table.md").write_text(table)
    print(table)
    print(f"results: {out}")
    return 1 if any(s["errors"] for s in summary.values()) else 0
