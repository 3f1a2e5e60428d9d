#!/usr/bin/env python3
"""Kill soak (issues 36 and 56): a command killed with SIGKILL at random moments and
resumed each time must end with the same output as one never interrupted, and leave
nothing running.

    python scripts/kill_soak.py --scenes 30 --workers 2 --kills 50 --out /tmp/soak
    python scripts/kill_soak.py --target data-grasps --scenes 40 --kills 20 --out /tmp/soak-data
    python scripts/kill_soak.py --target viewsphere --kill parent --kills 20 --out /tmp/soak-vs

``--target``: ``run`` (``heapgrasp run``; resumed with ``--resume``), ``data-grasps``
(``heapgrasp grasps data``, one scene per shard; resumed by running it again) or
``viewsphere`` (``heapgrasp viewsphere bench`` on two stand-in objects; resumed by
running it again).

1. runs the command uninterrupted into ``OUT/reference``;
2. starts the same command in ``OUT/killed`` and kills it with SIGKILL after a random
   delay, ``--kills`` times, resuming each time. ``--kill group`` kills its whole process
   group; ``--kill parent`` the parent alone, then waits up to 10 s for its pool's workers
   to end by themselves and counts those still running (``left_running``; then killed).
   With ``--torn P`` (``run``) a kill is followed, with probability P, by a torn
   half-record appended to ``scenes.jsonl``, as a kill in the middle of a write leaves it;
3. resumes once more to the end and compares the output with the reference's: every
   scene record and ``results.json`` (``run``), every shard and the manifest byte for byte
   (``data-grasps``), every pose's record and ``results.json`` (``viewsphere``) — timings
   aside (wall clock and measured compute time).

Prints one JSON summary line (and writes it to ``OUT/soak.json``); exits 1 on any
difference or on a process left running. Everything it writes stays under ``OUT``.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

#: Keys whose values are measured times, not results: they differ between two runs.
TIMINGS = {
    "wall_time_s",
    "compute_time_s",
    "execution_time_s",
    "final_planning_s",
    "grasp_planning_s",
    "view_planning_s",
    "latency_s",
    "planning_latency_per_waypoint_s",
    "grasp_planning_per_call_s",
    "wall_time_per_scene_s",
    "leftover_analysis_s",
    "seconds",
    "decisions_s",
    "mean_seconds",
    "mean_decision_s",
    "max_decision_s",
}

#: ``--target viewsphere``'s objects and policies (two stand-ins: seconds per pose).
VIEWSPHERE = ("prism_6x6x6,handle", "random,brick,bfs")


def without_timings(value: Any) -> Any:
    """``value`` with every :data:`TIMINGS` key dropped, recursively."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k not in TIMINGS}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def records(out: Path) -> dict[int, Any]:
    """The scene records of a run, keyed by scene (every line must parse)."""
    lines = (out / "scenes.jsonl").read_text().splitlines()
    found = [json.loads(line) for line in lines if line.strip()]
    keyed = {int(r["scene"]): without_timings(r) for r in found}
    if len(keyed) != len(found):
        raise SystemExit(f"{out}: a scene recorded twice")
    return keyed


def command(args: argparse.Namespace, out: Path, *, resume: bool) -> list[str]:
    """The command of ``--target`` into ``out`` (its resume where it has one)."""
    base = [sys.executable, "-m", "heapgrasp"]
    if args.target == "data-grasps":
        return [
            *base,
            "grasps",
            "data",
            str(out),
            "--scenes",
            str(args.scenes),
            "--shard-size",
            "1",
            "--seed",
            str(args.seed),
            "--workers",
            str(args.workers),
            "--quiet",
        ]
    if args.target == "viewsphere":
        objects, policies = VIEWSPHERE
        return [
            *base,
            "viewsphere",
            "bench",
            "--objects",
            objects,
            "--policies",
            policies,
            "--poses",
            str(args.scenes),
            "--workers",
            str(args.workers),
            "--no-figures",
            "--quiet",
            "--out",
            str(out),
        ]
    argv = [*base, "run", "--out", str(out), "--quiet"]
    if resume:
        return [*argv, "--resume"]
    return [
        *argv,
        "--method",
        args.method,
        "--scenes",
        str(args.scenes),
        "--objects",
        str(args.objects),
        "--seed",
        str(args.seed),
        "--workers",
        str(args.workers),
    ]


def compare(args: argparse.Namespace, ours: Path, theirs: Path) -> dict[str, Any]:
    """How the killed command's output compares with the reference's."""
    if args.target == "data-grasps":
        names = sorted(p.name for p in theirs.iterdir())
        mine = sorted(p.name for p in ours.iterdir())
        differing = [
            n for n in names if n not in mine or _content(ours / n) != _content(theirs / n)
        ]
        extra = [n for n in mine if n not in names]
        return {
            "units": len([n for n in mine if n.startswith("shard-")]),
            "differing": differing + extra,
            "results_equal": not differing and not extra,
        }
    if args.target == "viewsphere":
        a, b = _pose_records(ours), _pose_records(theirs)
        differing = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        results_equal = without_timings(
            json.loads((ours / "results.json").read_text())
        ) == without_timings(json.loads((theirs / "results.json").read_text()))
        return {"units": len(a), "differing": differing, "results_equal": results_equal}
    mine_records, their_records = records(ours), records(theirs)
    differing_scenes = sorted(
        s
        for s in set(mine_records) | set(their_records)
        if mine_records.get(s) != their_records.get(s)
    )
    results_equal = without_timings(
        json.loads((ours / "results.json").read_text())
    ) == without_timings(json.loads((theirs / "results.json").read_text()))
    return {
        "units": len(mine_records),
        "differing": differing_scenes,
        "results_equal": results_equal,
    }


#: A dataset manifest's provenance: the command (its output folder differs) and how long
#: the last invocation took.
PROVENANCE = {"command", "seconds_this_run"}


def _content(path: Path) -> Any:
    """A shard's bytes; a manifest's content without its provenance."""
    if not path.is_file():
        return None
    if path.suffix == ".json":
        data = json.loads(path.read_text())
        return {k: v for k, v in data.items() if k not in PROVENANCE}
    return path.read_bytes()


def _pose_records(out: Path) -> dict[str, Any]:
    """``viewsphere bench``'s records, keyed by object and pose (every line must parse,
    and none may repeat)."""
    found: dict[str, Any] = {}
    for path in sorted((out / "records").glob("*.jsonl")):
        for line in path.read_text().splitlines():
            if not line.strip():
                continue
            record = json.loads(line)
            key = f"{path.stem}/{record['pose']}"
            if key in found:
                raise SystemExit(f"{path}: pose {record['pose']} recorded twice")
            found[key] = without_timings(record)
    return found


def _left_running(pgid: int, wait: float = 10.0) -> int:
    """Processes of group ``pgid`` still alive after ``wait`` s (then killed)."""
    deadline = time.time() + wait
    while time.time() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return 0
        time.sleep(0.2)
    found = subprocess.run(["pgrep", "-g", str(pgid)], capture_output=True, text=True)
    alive = len(found.stdout.split())
    try:
        os.killpg(pgid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    return alive


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="working directory (created)")
    p.add_argument("--scenes", type=int, default=30)
    p.add_argument("--objects", type=int, default=5)
    p.add_argument("--method", default="no-vp")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0, help="seed of scene 0")
    p.add_argument("--kills", type=int, default=50)
    p.add_argument("--max-wait", type=float, default=8.0, help="longest delay before a kill (s)")
    p.add_argument("--torn", type=float, default=0.3, help="chance of a torn write after a kill")
    p.add_argument("--rng", type=int, default=0, help="seed of the kill times")
    p.add_argument(
        "--target",
        choices=("run", "data-grasps", "viewsphere"),
        default="run",
        help="the command killed (default run); --scenes: its scenes or poses",
    )
    p.add_argument(
        "--kill",
        choices=("group", "parent"),
        default="group",
        help="kill the process group, or the parent alone (its workers must end by themselves)",
    )
    args = p.parse_args(argv)
    rng = random.Random(args.rng)
    args.out.mkdir(parents=True, exist_ok=True)
    reference, killed = args.out / "reference", args.out / "killed"
    if not reference.exists():
        subprocess.run(command(args, reference, resume=False), check=True)
    started = time.time()
    kills = torn = left_running = 0
    finished_early = False
    for k in range(args.kills):
        resume = (killed / "config.json").exists()  # (run: the others resume by themselves)
        proc = subprocess.Popen(
            command(args, killed, resume=resume),
            start_new_session=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            proc.wait(timeout=rng.uniform(0.2, args.max_wait))
            finished_early = True  # the run ended before its kill
            break
        except subprocess.TimeoutExpired:
            if args.kill == "group":
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
            else:
                proc.kill()
                proc.wait()
                left_running += _left_running(proc.pid)
            kills += 1
        if args.target == "run" and rng.random() < args.torn and (killed / "scenes.jsonl").exists():
            with (killed / "scenes.jsonl").open("a") as fh:
                fh.write('{"scene": 0, "phases": [{"outcome": "succ')  # cut mid-record
            torn += 1
        print(f"kill {k + 1}", file=sys.stderr)
    last = subprocess.run(command(args, killed, resume=True), capture_output=True, text=True)
    result = compare(args, killed, reference)
    summary = {
        "target": args.target,
        "kill": args.kill,
        "scenes": args.scenes,
        "workers": args.workers,
        "kills": kills,
        "torn_writes": torn,
        "finished_before_a_kill": finished_early,
        "final_resume_exit": last.returncode,
        "scenes_recorded": result["units"],
        "scenes_differing": result["differing"],
        "results_equal": result["results_equal"],
        "left_running": left_running,
        "soak_wall_s": round(time.time() - started, 1),
    }
    (args.out / "soak.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))
    expected = args.scenes * 2 if args.target == "viewsphere" else args.scenes
    ok = (
        last.returncode == 0
        and not result["differing"]
        and result["results_equal"]
        and result["units"] == expected
        and left_running == 0
    )
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
