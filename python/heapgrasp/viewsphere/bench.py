"""``heapgrasp viewsphere bench``: the active-vision grasp benchmark of Natarajan et al.
(§4.1, §5.1).

Each object stands at the table's centre in ``--poses`` poses (the protocol's yaws,
:func:`~heapgrasp.viewsphere.protocol.protocol_yaws`); from each pose every policy
runs one episode from the start view (azimuth π, polar π/7): a move of 20° at a time
on the viewsphere until the fused views yield a grasp (Natarajan et al. §3.3) or 6 moves were
made. A pose without a grasp after them counts 6 steps. The policies:

* ``random``: a uniformly random direction each move (seeded per pose);
* ``brick``: always north-east;
* ``heuristic-2d``, ``heuristic-3d``: Natarajan et al.'s Algorithms 1 and 2
  (:mod:`heapgrasp.viewsphere.heuristics`);
* ``information-gain``: the comparison of §4.2.3, which flies between 34 fixed
  viewpoints; its steps are viewpoints, and ``travelled_steps`` its path in 20° steps;
* ``pca-lr``, ``pca-lda``, ``dqn``: Natarajan et al.'s learned policies (§4.3), trained on the
  training shapes only (:mod:`heapgrasp.viewsphere.learned`), from the shipped
  files or ``--weights MODEL=FILE``;
* ``imitation`` (beyond the paper): a perceptron imitating breadth-first search's
  optimal first moves on the training shapes and procedural objects
  (:func:`heapgrasp.viewsphere.training.train_mlp`), from its shipped file or
  ``--weights imitation=FILE``;
* ``heapgrasp-net``, ``heapgrasp-oracle``: HEAPGrasp's eq. 14 on a grid carved from the
  views' silhouettes (no depth), scored by the shipped view network or, privileged, by
  the exact oracle reading the true meshes
  (:mod:`heapgrasp.viewsphere.heapgrasp_views`); ``oracle_agreement`` records, per
  decision of the network, whether the oracle chose alike;
* ``bfs``: breadth-first search, the fewest moves that reach a set of views yielding a
  grasp (each distinct set of views synthesised once; at most ``bfs_max_sets`` sets,
  past which the pose counts as not found and is marked incomplete).

Unless ``--no-execute``, the grasp an episode found is also executed by the
free-flying Panda hand in PyBullet on the object (lift and shake): the physical success
the paper did not measure.

Writes in ``--out``:

* ``results.json``: ``{"policies": {POLICY: {"objects": {OBJECT: {"success_at_step":
  [7 fractions, steps 0..6], "mean_steps", "executed_success", "poses": [...]}}}}}``,
  the settings, each object's class, how each object rests (``placements``: the
  protocol object it stands for, how it was placed, whether that is the protocol's
  resting pose) and the errors;
* ``records/OBJECT.jsonl``: one line per finished pose (what a rerun resumes from);
* ``table.md``: success at each step per object and policy, mean steps, the class;
  each policy's success over BFS's per class at steps 1 and 3 (Fig. 11), decision
  times, and information gain vs the 3D heuristic (Table 1);
* ``fig10_success.png``: success vs step per object, all policies (the paper's Fig. 10);
* ``fig11_bfs_ratio.png``: policy / BFS success per class at steps 1 and 3 (Fig. 11);
* ``difficulty.png``: random's share of BFS's success at step 2 per object, with the
  class thresholds (≤ 0.40 hard, ≤ 0.80 medium, else easy).

Rerunning with the same ``--out`` and settings continues where a run stopped (poses
already recorded are not run again); other settings are refused.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from datetime import datetime
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from heapgrasp.loop.config import parse_sets
from heapgrasp.results.pages import write_summary
from heapgrasp.results.records import write_json
from heapgrasp.viewsphere.episode import LEARNED, PoseTask, run_pose
from heapgrasp.viewsphere.grasps import ViewsphereConfig
from heapgrasp.viewsphere.report import figures, markdown_table, summarize

__all__ = ["command", "run_bench"]


def _read_records(path: Path) -> dict[int, dict[str, Any]]:
    """A records file's poses (the last line of a pose wins; a torn last line, from a
    run that was killed while writing, is cut off the file)."""
    out: dict[int, dict[str, Any]] = {}
    if not path.is_file():
        return out
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        # cut the torn line off, or the next record appended would join it and be lost
        keep = data.rfind(b"\n") + 1
        with path.open("r+b") as f:
            f.truncate(keep)
        print(f"heapgrasp: cut a torn last record off {path}", file=sys.stderr)
        data = data[:keep]
    for line in data.decode().splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        out[int(rec["pose"])] = rec
    return out


def _objects(
    args: argparse.Namespace, config: ViewsphereConfig
) -> tuple[list[Any], dict[str, str]]:
    """The benchmark's objects and the errors of those that cannot be used."""
    from heapgrasp.sim.object_model import default_cache_dir
    from heapgrasp.viewsphere.objects import stand_ins, user_objects

    errors: dict[str, str] = {}
    if args.object_dir is not None:
        objects = user_objects(
            args.object_dir,
            default_cache_dir(),
            on_bad=lambda name, problem: errors.__setitem__(name, problem),
        )
        if args.objects is not None:
            wanted = set(args.objects)
            missing = wanted - {o.protocol for o in objects}
            objects = [o for o in objects if o.protocol in wanted]
            for name in sorted(missing):
                errors[name] = f"no object of {args.object_dir} is {name}"
    else:
        objects = stand_ins(args.objects)
    usable = []
    for obj in objects:
        try:
            obj.check_size(config.object_half_xy, config.object_max_height)
        except ValueError as exc:
            errors[obj.name] = str(exc)
            continue
        usable.append(obj)
    return usable, errors


def _placement_record(obj: Any) -> dict[str, Any]:
    """How an object rests, for results.json: the protocol object it stands for, how it
    was placed and whether that is the protocol's resting pose."""
    return {"protocol": obj.protocol, "placement": obj.placement, "exact": obj.exact}


def _settings(args: argparse.Namespace, config: ViewsphereConfig) -> dict[str, Any]:
    from heapgrasp.viewsphere.objects import TEST_OBJECTS

    return {
        "policies": list(args.policies),
        "objects": (
            "object-dir"
            if args.object_dir is not None and args.objects is None
            else list(args.objects if args.objects is not None else TEST_OBJECTS)
        ),
        "object_dir": args.object_dir,
        "poses": args.poses,
        "seed": args.seed,
        "sensor": args.sensor,
        "perception": args.perception,
        "execute": args.execute,
        "config": config.to_dict(),
        "weights": {
            model: {"path": path, "sha256": _sha256(path)} for model, path in args.weights_files
        },
    }


def _sha256(path: str) -> str:
    import hashlib

    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def resolve_weights(policies: Sequence[str], given: Sequence[str]) -> tuple[tuple[str, str], ...]:
    """The files of the learned ``policies``: ``given`` ``MODEL=FILE`` entries, else the
    shipped ones. ValueError naming a bad entry, a missing file or a learned policy
    without one; each file is opened and checked."""
    from heapgrasp.inference import OnnxNetwork
    from heapgrasp.viewsphere.learned import shipped_policy

    chosen: dict[str, str] = {}
    for entry in given:
        model, sep, path = entry.partition("=")
        if not sep or model not in LEARNED or not path:
            raise ValueError(
                f"--weights wants MODEL=FILE with MODEL among {', '.join(LEARNED)}; got {entry!r}"
            )
        chosen[model] = str(Path(path).expanduser().absolute())
    out = []
    for model in (p for p in policies if p in LEARNED):
        if model not in chosen:
            shipped = shipped_policy(model)
            if shipped is None:
                raise ValueError(
                    f"no {model} policy ships with this install: train one (heapgrasp viewsphere "
                    f"train --kind {model}) and pass --weights {model}=FILE"
                )
            chosen[model] = str(shipped)
        network = OnnxNetwork(chosen[model], kind="viewsphere-policy", threads=1)
        if network.hparams.get("model") != model:
            raise ValueError(
                f"{chosen[model]} holds a {network.hparams.get('model')} policy, not {model}"
            )
        out.append((model, chosen[model]))
    return tuple(out)


def _tasks(
    objects: Sequence[Any], args: argparse.Namespace, config: ViewsphereConfig, out: Path
) -> tuple[list[PoseTask], dict[str, dict[int, dict[str, Any]]]]:
    from heapgrasp.viewsphere.protocol import protocol_yaws

    done: dict[str, dict[int, dict[str, Any]]] = {}
    tasks = []
    for obj in objects:
        done[obj.name] = _read_records(out / "records" / f"{obj.name}.jsonl")
        yaws = protocol_yaws(obj.yaw_range, args.poses)
        for i, yaw in enumerate(yaws):
            if i in done[obj.name]:
                continue
            tasks.append(
                PoseTask(
                    obj.name,
                    obj.meshes,
                    i,
                    round(float(np.degrees(yaw)), 6),
                    tuple(args.policies),
                    config.to_dict(),
                    args.seed,
                    args.sensor,
                    args.execute,
                    tuple(args.weights_files),
                    args.perception,
                )
            )
    return tasks, done


def _init_worker() -> None:
    from heapgrasp.loop.workers import init_worker

    init_worker(int(os.environ.get("HEAPGRASP_NUM_THREADS", "1")))


def _safe_pose(task: PoseTask) -> dict[str, Any]:
    """:func:`run_pose`, an exception recorded in the pose's record."""
    try:
        return run_pose(task)
    except Exception as exc:  # one pose's failure must not lose the others
        return {"pose": task.pose, "yaw_deg": task.yaw_deg, "error": f"{type(exc).__name__}: {exc}"}


def _execute(
    tasks: Sequence[PoseTask],
    finish: Callable[[PoseTask, dict[str, Any]], None],
    *,
    workers: int,
    ray_address: str | None,
) -> None:
    """Runs the tasks here, on a process pool or on Ray; ``finish`` gets each result.
    A worker that dies (a native crash) breaks the pool: its unfinished tasks run again
    in a new pool, and a task that breaks two pools is recorded as failed."""
    if ray_address is not None:
        _execute_ray(tasks, finish, ray_address)
        return
    if workers == 1:
        for t in tasks:
            finish(t, _safe_pose(t))
        return
    crashes: dict[tuple[str, int], int] = {}
    pending = list(tasks)
    while pending:
        retry: list[PoseTask] = []
        ctx = get_context("spawn")
        with ProcessPoolExecutor(
            min(workers, len(pending)), mp_context=ctx, initializer=_init_worker
        ) as pool:
            futures: dict[Future[dict[str, Any]], PoseTask] = {
                pool.submit(_safe_pose, t): t for t in pending
            }
            remaining = set(futures)
            while remaining:
                finished, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for fut in finished:
                    t = futures[fut]
                    try:
                        finish(t, fut.result())
                    except BrokenProcessPool:
                        key = (t.object_name, t.pose)
                        crashes[key] = crashes.get(key, 0) + 1
                        if crashes[key] >= 2:
                            finish(
                                t,
                                {
                                    "pose": t.pose,
                                    "yaw_deg": t.yaw_deg,
                                    "error": "the worker process died (a native crash)",
                                },
                            )
                        else:
                            retry.append(t)
        pending = retry


def _execute_ray(
    tasks: Sequence[PoseTask],
    finish: Callable[[PoseTask, dict[str, Any]], None],
    address: str,
) -> None:
    from heapgrasp.data.shards import ray_map

    for k, result, error in ray_map(_safe_pose, [(t,) for t in tasks], address):
        t = tasks[k]
        if error is not None:
            result = {"pose": t.pose, "yaw_deg": t.yaw_deg, "error": f"{error}"}
        finish(t, result)


def run_bench(args: argparse.Namespace) -> dict[str, Any]:
    """Runs (or continues) the benchmark in ``args.out``; returns ``results.json``."""
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    config = ViewsphereConfig.from_dict({**ViewsphereConfig().to_dict(), **parse_sets(args.set)})
    args.weights_files = resolve_weights(args.policies, args.weights)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / "records").mkdir(exist_ok=True)
    settings = _settings(args, config)
    settings_file = out / "settings.json"
    if settings_file.is_file():
        before = json.loads(settings_file.read_text())
        if before != json.loads(json.dumps(settings)):
            changed = sorted(k for k in settings if before.get(k) != settings[k])
            raise ValueError(
                f"{out} holds a run with other settings ({', '.join(changed)}); "
                "rerun with those settings to continue it, or choose another --out"
            )
    write_json(settings_file, settings)
    objects, errors = _objects(args, config)
    for name, problem in errors.items():
        print(f"heapgrasp: skipping object {name}: {problem}", file=sys.stderr)
    placements = {obj.name: _placement_record(obj) for obj in objects}
    if args.object_dir is not None and not args.quiet:
        for obj in objects:
            warn = "" if obj.exact else "warning: "
            print(f"heapgrasp: {warn}{obj.name} rests in {obj.placement}", file=sys.stderr)
    tasks, done = _tasks(objects, args, config, out)
    records = {name: dict(poses) for name, poses in done.items()}
    total = sum(args.poses for _ in objects)
    if tasks and not args.quiet:
        print(_duration_note(len(tasks), len(args.policies), args.workers), file=sys.stderr)
    bar = tqdm(
        total=total,
        initial=total - len(tasks),
        unit="pose",
        desc="viewsphere",
        disable=args.quiet,
        file=sys.stderr,
    )
    pose_errors: dict[str, list[str]] = {}
    last_write = [0.0]

    def write_results() -> dict[str, Any]:
        good = {
            name: [r for r in recs.values() if "error" not in r] for name, recs in records.items()
        }
        errs = dict(errors)
        for name, msgs in pose_errors.items():
            errs[name] = f"{len(msgs)} pose(s) failed; first: {msgs[0]}"
        results = summarize(settings, good, errs)
        results["placements"] = placements
        write_json(out / "results.json", results)
        return results

    def finish(task: PoseTask, record: dict[str, Any]) -> None:
        if "error" in record:
            pose_errors.setdefault(task.object_name, []).append(
                f"pose {task.pose}: {record['error']}"
            )
        else:
            with (out / "records" / f"{task.object_name}.jsonl").open("a") as f:
                f.write(json.dumps(record) + "\n")
            records[task.object_name][task.pose] = record
        bar.update(1)
        if time.monotonic() - last_write[0] > 30.0:
            write_results()
            last_write[0] = time.monotonic()

    try:
        _execute(tasks, finish, workers=args.workers, ray_address=args.ray)
    finally:
        bar.close()
        results = write_results()
        (out / "table.md").write_text(markdown_table(results))
    if not args.no_figures:
        figures(results, out)
    write_summary(
        out,
        markdown_table(results),
        [
            ("fig10_success.png", "success against steps per object (the paper's Fig. 10)"),
            ("fig11_bfs_ratio.png", "policy / BFS success per class (Fig. 11)"),
            ("difficulty.png", "each object's difficulty"),
        ],
    )
    return results


#: CPU seconds one pose took for one policy in the full protocol's run (12 objects × 100
#: poses × 11 policies in 43 min on 2 workers: docs/benchmarks.md).
SECONDS_PER_POSE_POLICY = 43 * 60 * 2 / (12 * 100 * 11)


def _duration_note(poses: int, policies: int, workers: int) -> str:
    """What a run is about to do and roughly how long it takes (from the full protocol's
    measured rate, :data:`SECONDS_PER_POSE_POLICY`)."""
    minutes = poses * policies * SECONDS_PER_POSE_POLICY / max(1, min(workers, poses)) / 60
    about = f"about {minutes:.0f} min" if minutes >= 1 else "under a minute"
    return (
        f"heapgrasp viewsphere bench: {poses} object pose(s) × {policies} policies to run, "
        f"{about} on {workers} worker(s) (the full protocol, 12 objects × 100 poses × "
        "11 policies, took 43 min on 2 cores; --poses and --policies run less)"
    )


def command(args: argparse.Namespace) -> int:
    """``heapgrasp viewsphere bench`` (its options: :func:`heapgrasp.cli.viewsphere.add_bench`)."""
    if args.poses > 100:
        print(
            f"heapgrasp: error: --poses must be at most 100 (the protocol's lists), got "
            f"{args.poses}",
            file=sys.stderr,
        )
        return 2
    if args.out is None:
        args.out = Path("runs") / f"bench-viewsphere-{datetime.now():%Y%m%d-%H%M%S}"
    from heapgrasp.results.records import RunDir, RunLockedError

    try:
        # one writer per --out: a second run with the same settings would redo the work
        rundir = RunDir(args.out).lock()
    except RunLockedError as exc:
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    try:
        results = run_bench(args)
    except (ImportError, ValueError, FileNotFoundError) as exc:  # refused: a missing extra,
        print(f"heapgrasp: error: {exc}", file=sys.stderr)  # other settings, a bad file
        return 2
    finally:
        rundir.unlock()
    print(markdown_table(results))
    print(f"results: {args.out / 'results.json'}", file=sys.stderr)
    return 1 if results["errors"] else 0
