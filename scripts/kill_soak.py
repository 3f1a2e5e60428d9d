#!/usr/bin/env python3
"""Kill soak (issue 36): a run killed with SIGKILL at random moments and resumed each
time must end with the same records and results as a run never interrupted.

    python scripts/kill_soak.py --scenes 30 --workers 2 --kills 50 --out /tmp/soak

1. runs ``heapgrasp run`` uninterrupted into ``OUT/reference``;
2. starts the same run in ``OUT/killed``, kills its whole process group with SIGKILL after
   a random delay, ``--kills`` times, resuming (``--resume --out``) each time; with
   ``--torn P`` a kill is followed, with probability P, by a torn half-record appended to
   ``scenes.jsonl``, as a kill in the middle of a record's write leaves it;
3. resumes once more to the end and compares every scene record and ``results.json``
   with the reference's, timings aside (wall clock and measured compute time).

Prints one JSON summary line (and writes it to ``OUT/soak.json``); exits 1 on any
difference. Everything it writes stays under ``OUT``.
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
}


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
    argv = [sys.executable, "-m", "heapgrasp", "run", "--out", str(out), "--quiet"]
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
    args = p.parse_args(argv)
    rng = random.Random(args.rng)
    args.out.mkdir(parents=True, exist_ok=True)
    reference, killed = args.out / "reference", args.out / "killed"
    if not (reference / "results.json").exists():
        subprocess.run(command(args, reference, resume=False), check=True)
    started = time.time()
    kills = torn = 0
    finished_early = False
    for k in range(args.kills):
        resume = (killed / "config.json").exists()
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
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            kills += 1
        if rng.random() < args.torn and (killed / "scenes.jsonl").exists():
            with (killed / "scenes.jsonl").open("a") as fh:
                fh.write('{"scene": 0, "phases": [{"outcome": "succ')  # cut mid-record
            torn += 1
        print(f"kill {k + 1}: {len(records_or_none(killed))} scenes recorded", file=sys.stderr)
    last = subprocess.run(command(args, killed, resume=True), capture_output=True, text=True)
    ours, theirs = records(killed), records(reference)
    differing = sorted(s for s in set(ours) | set(theirs) if ours.get(s) != theirs.get(s))
    results_equal = without_timings(
        json.loads((killed / "results.json").read_text())
    ) == without_timings(json.loads((reference / "results.json").read_text()))
    summary = {
        "scenes": args.scenes,
        "workers": args.workers,
        "kills": kills,
        "torn_writes": torn,
        "finished_before_a_kill": finished_early,
        "final_resume_exit": last.returncode,
        "scenes_recorded": len(ours),
        "scenes_differing": differing,
        "results_equal": results_equal,
        "soak_wall_s": round(time.time() - started, 1),
    }
    (args.out / "soak.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary))
    ok = last.returncode == 0 and not differing and results_equal and len(ours) == args.scenes
    return 0 if ok else 1


def records_or_none(out: Path) -> dict[int, Any]:
    """Scenes recorded so far (a torn last line ignored), for progress only."""
    path = out / "scenes.jsonl"
    if not path.exists():
        return {}
    found: dict[int, Any] = {}
    for line in path.read_text().splitlines():
        try:
            found[int(json.loads(line)["scene"])] = True
        except (ValueError, KeyError, TypeError):
            pass
    return found


if __name__ == "__main__":
    raise SystemExit(main())
