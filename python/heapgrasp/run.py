"""Simulated pick-and-place runs: scenes → clutter removal → ``results.json``.

:func:`run` executes ``config.scenes`` seeded scenes (scene ``i`` uses seed
``config.seed + i``, so every method sees the same scenes) and writes, in the output
directory:

* ``config.json`` — the full :class:`~heapgrasp.loop.config.RunConfig`;
* ``scenes.jsonl`` — one JSON record per finished scene, keyed by its index, appended,
  flushed and synced as soon as the scene ends, so an interrupted run loses nothing
  (``resume=True`` skips the scenes already there);
* ``results.json`` — the aggregate (:func:`summarize`), rewritten after every scene;

and holds the directory's lock while it runs (:class:`~heapgrasp.results.records.RunDir`).

Scenes run in a process pool when ``workers > 1`` (each worker builds its own
PyBullet world); a scene that raises is recorded with its error and the run goes on.
"""

from __future__ import annotations

import sys
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.methods import method_of
from heapgrasp.results.records import (
    CONFIG_FILE,
    RESULTS_FILE,
    SCENES_FILE,
    RecordError,
    RunDir,
    RunLockedError,
    write_json,
)
from heapgrasp.results.summary import format_summary, summarize

__all__ = [
    "CONFIG_FILE",
    "REFUSED",
    "RESULTS_FILE",
    "SCENES_FILE",
    "RunExistsError",
    "format_summary",
    "load_records",
    "preflight",
    "run",
    "run_scene",
    "summarize",
]


class RunExistsError(ValueError):
    """The output directory already holds a run (and ``resume`` was not asked for)."""


#: What :func:`run` raises before any scene when it cannot start (the command line
#: exits 2 on them): a bad configuration, a missing optional dependency, records that
#: cannot be trusted, a run already there, a directory another process is writing.
REFUSED: tuple[type[Exception], ...] = (
    ConfigError,
    ImportError,
    RecordError,
    RunExistsError,
    RunLockedError,
)


def preflight(config: RunConfig, *, viz: bool = False) -> None:
    """Checks, once and before any scene, what a run needs: that its objects fit on the
    table, and the grasp planner, the view scorer, the critic and the segmentation
    network (loading their weights)
    — so that a count that cannot be placed, a missing optional dependency (PyTorch for
    the networks, rerun-sdk for ``viz``) or a bad weights file is one clear error, not a
    failed record per scene."""
    from heapgrasp.loop.stages import (
        make_critic,
        make_grasp_planner,
        make_segmenter,
        make_view_scorer,
    )
    from heapgrasp.sim.build import object_library, table_capacity

    library = object_library(config, on_skip=_warn)
    capacity = table_capacity(config, library)
    if config.objects > capacity:
        which = (
            f"the {config.split} split's objects"
            if config.object_dir is None
            else f"the objects of {config.object_dir}"
        )
        raise ConfigError(
            f"objects: {config.objects} cannot be placed: the {config.cube_size} m table holds "
            f"at most {capacity} of {which} side by side"
        )
    make_grasp_planner(config)
    make_view_scorer(config)
    make_critic(config)
    if method_of(config).rgb:  # the segmentation network: one error, not a failed scene each
        make_segmenter(config, None)
    if viz:
        from heapgrasp.viz.recorder import import_rerun

        import_rerun()


def _warn(message: str) -> None:
    print(f"heapgrasp: warning: {message}", file=sys.stderr)


def run_scene(
    config: RunConfig,
    index: int,
    *,
    category: str | None = None,
    gui: bool = False,
    record: Path | None = None,
) -> dict[str, Any]:
    """Runs scene ``index`` (seed ``config.seed + index``) to the end of the clutter-removal
    protocol and returns its record (phases with metrics, stop reason, timings). With
    ``record``, every phase is recorded there as a ``.rrd`` file (:mod:`heapgrasp.viz`),
    with RGB images rendered for it (the outcomes are the same)."""
    import numpy as np

    from heapgrasp.loop.protocol import run_clutter_removal
    from heapgrasp.sim.build import scene_world, sim_pipeline
    from heapgrasp.sim.leftovers import describe_leftovers

    t0 = time.perf_counter()
    seed = config.seed + index
    group = category or config.category
    with scene_world(config, seed, group, gui=gui) as world:
        scene = world.to_dict()
        total = len(world.objects)
        if total < config.objects:
            print(
                f"heapgrasp: scene {index} (seed {seed}): placed {total} of {config.objects} "
                "objects; the others fell off the table",
                file=sys.stderr,
            )
        recorder = None
        if record is not None:
            from heapgrasp.geometry.grid import GridFrame
            from heapgrasp.viz.recorder import RerunRecorder

            grid = GridFrame((0.0, 0.0, 0.0), config.cube_size, config.resolution)
            recorder = RerunRecorder(record, grid, config.lam, name=f"{config.method}-{seed}")
        pipeline = sim_pipeline(
            config, world, seed=seed, observer=recorder, rgb=recorder is not None
        )
        try:
            phases, reason = run_clutter_removal(
                pipeline.robot,
                pipeline.plan,
                truth=pipeline.truth,
                max_attempts=config.max_attempts,
                on_outcome=pipeline.record_outcome,
            )
        finally:
            if recorder is not None:
                recorder.close()
        wall = time.perf_counter() - t0  # the scene's run, without the analysis below
        # Every object left, and whether the hand could have taken it on its true mesh:
        # the scene ran whole, so a failure of the analysis is recorded, not the scene's.
        t1 = time.perf_counter()
        analysis: dict[str, Any] = {}
        try:
            analysis["leftovers"] = describe_leftovers(world, np.random.default_rng(seed))
        except Exception as exc:  # recorded beside the scene's outcome
            analysis["leftovers_error"] = f"{type(exc).__name__}: {exc}"
        analysis["leftover_analysis_s"] = time.perf_counter() - t1
    return {
        "scene": index,
        "seed": seed,
        "category": group,
        "objects_requested": config.objects,
        "objects_total": total,
        "stop_reason": reason.value,
        "phases": [p.to_dict() for p in phases],
        **analysis,
        "wall_time_s": wall,
        "world": scene,
    }


def _safe_scene(
    config: RunConfig, index: int, category: str | None, record: Path | None = None
) -> dict[str, Any]:
    try:
        return run_scene(config, index, category=category, record=record)
    except Exception as exc:  # recorded, the run goes on
        return {
            "scene": index,
            "seed": config.seed + index,
            "category": category or config.category,
            "error": f"{type(exc).__name__}: {exc}",
            "traceback": traceback.format_exc(limit=8),
        }


def _init_worker() -> None:
    # One core per scene: the pool provides the parallelism; a worker dies with the run.
    # The networks run with onnxruntime, whose threads follow HEAPGRASP_NUM_THREADS (set
    # by init_worker); nothing at run time imports PyTorch.
    from heapgrasp.loop.workers import init_worker

    init_worker()


def load_records(out: Path) -> list[dict[str, Any]]:
    """The scene records of run directory ``out`` (:meth:`RunDir.records`: strict, a torn
    last line ignored)."""
    return RunDir(out).records()


def _prepare(rundir: RunDir, config: RunConfig, resume: bool) -> list[dict[str, Any]]:
    """Checks ``rundir`` for a run of ``config`` and returns the finished records to keep
    (failed scenes run again). Raises what :data:`REFUSED` lists."""
    saved = rundir.read_config()
    if rundir.repair_tail():
        print(f"heapgrasp: cut a torn last record off {rundir.scenes_file}", file=sys.stderr)
    if resume and saved is not None and saved != config:
        raise ConfigError(
            f"--resume: the configuration differs from {rundir.config_file} "
            f"({saved.changes_to(config)})"
        )
    records = rundir.records(config.scenes if resume or saved is None else saved.scenes)
    if records and not resume:
        raise RunExistsError(
            f"{rundir.path} already holds {len(records)} finished scene(s); pass --resume "
            "to continue that run, or choose another --out"
        )
    if records and saved is None:
        raise ConfigError(
            f"--resume: {rundir.config_file} is missing, so the {len(records)} record(s) in "
            f"{rundir.scenes_file} cannot be matched to a configuration; start a new run "
            "in another --out"
        )
    kept = [r for r in records if "error" not in r]
    if len(kept) < len(records):  # failed scenes run again
        rundir.rewrite_records(kept)
    return kept


def run(
    config: RunConfig,
    out: Path | None = None,
    *,
    resume: bool = False,
    workers: int = 1,
    categories: Sequence[str] | None = None,
    progress: bool = True,
    gui: bool = False,
    viz: bool = False,
    on_scene: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Runs every scene of ``config`` and returns :func:`summarize` of all of them.

    Parameters
    ----------
    out
        Output directory (created); None keeps results in memory only.
    resume
        Continue a run in ``out``: finished scenes are kept and skipped.
    workers
        Scenes run in parallel in a process pool when > 1.
    categories
        Scene group of each scene (default ``config.category`` for all).
    viz
        Record every scene's phases to ``out/viz/scene-NNN.rrd`` (:mod:`heapgrasp.viz`).
    on_scene
        Called with each finished scene record.

    Raises
    ------
    ConfigError, ImportError, RecordError, RunExistsError, RunLockedError
        Before any scene (:data:`REFUSED`): what the run needs cannot be built
        (:func:`preflight`), or ``out`` holds records that cannot be trusted, another
        run, a different configuration to resume, or is being written by another process.
    """
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if categories is not None and len(categories) != config.scenes:
        raise ValueError(f"categories: need one per scene ({config.scenes}), got {len(categories)}")
    if gui and workers > 1:
        raise ValueError("gui: needs workers = 1")
    if viz and out is None:
        raise ValueError("viz: needs an output directory")
    preflight(config, viz=viz)
    records: list[dict[str, Any]] = []
    rundir = None if out is None else RunDir(out).lock()
    try:
        if rundir is not None:
            records = _prepare(rundir, config, resume)
            rundir.write_config(config)
        return _run_scenes(
            config,
            rundir,
            records,
            workers=workers,
            categories=categories,
            progress=progress,
            gui=gui,
            viz=viz,
            on_scene=on_scene,
        )
    finally:
        if rundir is not None:
            rundir.unlock()


def _run_scenes(
    config: RunConfig,
    rundir: RunDir | None,
    records: list[dict[str, Any]],
    *,
    workers: int,
    categories: Sequence[str] | None,
    progress: bool,
    gui: bool,
    viz: bool,
    on_scene: Callable[[dict[str, Any]], None] | None,
) -> dict[str, Any]:
    """:func:`run`'s scenes, on a prepared (and locked) run directory."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    out = None if rundir is None else rundir.path
    done = {int(r["scene"]) for r in records}
    pending = [i for i in range(config.scenes) if i not in done]

    def category_of(i: int) -> str | None:
        return None if categories is None else categories[i]

    def record_of(i: int) -> Path | None:
        return None if not viz or out is None else out / "viz" / f"scene-{i:03d}.rrd"

    bar = tqdm(
        total=config.scenes,
        initial=len(done),
        desc=config.method,
        unit="scene",
        disable=not progress,
        file=sys.stderr,
    )

    def finish(record: dict[str, Any]) -> None:
        records.append(record)
        if rundir is not None:
            rundir.append(record)
            write_json(rundir.results_file, summarize(config, records))
        if on_scene is not None:
            on_scene(record)
        ok = sum(p["outcome"] == "success" for r in records for p in r.get("phases", []))
        tried = sum(p["outcome"] != "no_candidate" for r in records for p in r.get("phases", []))
        bar.set_postfix_str(f"grasps {ok}/{tried}")
        bar.update(1)

    try:
        if workers == 1:
            for i in pending:
                if gui:
                    finish(
                        run_scene(config, i, category=category_of(i), gui=True, record=record_of(i))
                    )
                else:
                    finish(_safe_scene(config, i, category_of(i), record_of(i)))
        else:
            ctx = get_context("spawn")
            with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init_worker) as pool:
                futures: list[Future[dict[str, Any]]] = [
                    pool.submit(_safe_scene, config, i, category_of(i), record_of(i))
                    for i in pending
                ]
                from concurrent.futures import as_completed

                for fut in as_completed(futures):
                    finish(fut.result())
    finally:
        bar.close()
    summary = summarize(config, records)
    if rundir is not None:
        write_json(rundir.results_file, summary)
    return summary
