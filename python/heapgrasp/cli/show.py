"""``heapgrasp show RUN_DIR``: a finished run's scene replayed and recorded for Rerun.

Runs are deterministic: the scene is run again from the run's ``config.json`` with a
recorder attached (:mod:`heapgrasp.viz.recorder`), and the replay's outcomes are checked
against the recorded ones.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from heapgrasp.loop.config import ConfigError

__all__ = ["add_parser", "show_command"]


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Adds ``heapgrasp show`` to the CLI."""
    p = subparsers.add_parser(
        "show",
        help="record a finished run's scene for the Rerun viewer (a 3-D view of every phase)",
        description="Replay one scene of a finished run (heapgrasp run or bench sim's "
        "OUT/METHOD) and record every phase with rerun-sdk: the occupancy grid and its "
        "high-confidence voxels frame by frame, the images and masks, the camera path and "
        "view waypoints, the candidate, target and executed grasps with their outcomes, "
        "on the timelines phase, frame and time. Writes RUN_DIR/viz/scene-NNN.rrd (open it "
        "with `rerun FILE`), or serves it to a browser with --web. Needs rerun-sdk: "
        "pip install 'heapgrasp[viz]'.",
        epilog="example: heapgrasp run --out runs/r && heapgrasp show runs/r --web",
    )
    p.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a run's output directory")
    p.add_argument("--scene", type=int, default=0, help="scene index in the run (default 0)")
    p.add_argument("--out", type=Path, help="the .rrd file (default RUN_DIR/viz/scene-NNN.rrd)")
    p.add_argument("--web", action="store_true", help="open the recording in a browser viewer")
    p.set_defaults(func=show_command)
    return p


def _fail(message: str) -> int:
    print(f"heapgrasp show: {message}", file=sys.stderr)
    return 2


def show_command(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp show``; returns the exit status."""
    from heapgrasp.loop.records import CONFIG_FILE, RecordError, RunDir
    from heapgrasp.run import run_scene
    from heapgrasp.viz.recorder import import_rerun

    run_dir: Path = args.run_dir
    rundir = RunDir(run_dir)
    try:
        config = rundir.read_config()
    except ConfigError as exc:
        return _fail(f"{exc} (a run written by another heapgrasp version cannot be replayed)")
    if config is None:
        return _fail(f"{run_dir} holds no run ({CONFIG_FILE} not found)")
    if not 0 <= args.scene < config.scenes:
        return _fail(f"--scene {args.scene}: the run has scenes 0 to {config.scenes - 1}")
    try:
        import_rerun()
    except ImportError as exc:
        return _fail(str(exc))
    try:
        recorded = {int(r["scene"]): r for r in rundir.records()}.get(args.scene)
    except RecordError as exc:
        return _fail(str(exc))
    category = None if recorded is None else recorded.get("category")
    out: Path = args.out or run_dir / "viz" / f"scene-{args.scene:03d}.rrd"
    print(
        f"heapgrasp show: running scene {args.scene} (seed {config.seed + args.scene}) of "
        f"{run_dir} again with a recorder, rendering RGB frames for it: about half a minute "
        "for a 5-object scene …",
        file=sys.stderr,
        flush=True,
    )
    t0 = time.perf_counter()
    replay = run_scene(config, args.scene, category=category, record=out)
    print(f"heapgrasp show: done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    outcomes = [p["outcome"] for p in replay["phases"]]
    print(f"scene {args.scene}: {len(outcomes)} phase(s), outcomes {outcomes}")
    if recorded is not None and "phases" in recorded:
        before = [p["outcome"] for p in recorded["phases"]]
        if before != outcomes:
            print(
                f"heapgrasp show: warning: the run recorded {before}; this version replays "
                "the scene differently",
                file=sys.stderr,
            )
    print(f"recording: {out}")
    if args.web:
        print("serving it to a browser (Ctrl-C to stop)")
        return subprocess.call([sys.executable, "-m", "rerun", "--web-viewer", str(out)])
    print(
        f"open it with: rerun {out}  (the `rerun` viewer comes with rerun-sdk, which "
        "pip install 'heapgrasp[viz]' installs; or heapgrasp show --web for a browser)"
    )
    return 0
