"""``heapgrasp show RUN_DIR``: a finished run's scene replayed and recorded for Rerun.

Simulated runs are deterministic: the scene is run again from the run's ``config.json``
with a recorder attached (:mod:`heapgrasp.viz.recorder`), and the replay's outcomes are
checked against the recorded ones. A robot run (``robot run --execute``, on the arm or
rehearsed with ``--sim``) cannot be run again: its recorded frames are planned again
(:func:`heapgrasp.real.replay.replay`) with the recorder attached.
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
        "OUT/METHOD; or one run of a `robot run --execute` folder, planned again from its "
        "recorded frames) and record every phase with rerun-sdk: the occupancy grid and its "
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


def _open(args: argparse.Namespace, out: Path) -> int:
    print(f"recording: {out}")
    if args.web:
        print("serving it to a browser (Ctrl-C to stop)")
        return subprocess.call([sys.executable, "-m", "rerun", "--web-viewer", str(out)])
    print(
        f"open it with: rerun {out}  (the `rerun` viewer comes with rerun-sdk, which "
        "pip install 'heapgrasp[viz]' installs; or heapgrasp show --web for a browser)"
    )
    return 0


def _show_robot_run(args: argparse.Namespace, rundir: object) -> int:
    """``show`` on a robot run's folder: its recorded frames planned again, recorded."""
    from heapgrasp.geometry.grid import GridFrame
    from heapgrasp.real.replay import replay
    from heapgrasp.results.records import RecordError, RunDir
    from heapgrasp.robot.errors import RobotError
    from heapgrasp.viz.recorder import RerunRecorder, import_rerun

    assert isinstance(rundir, RunDir)
    config = rundir.read_config()
    assert config is not None
    try:
        scenes = sorted(int(r["scene"]) for r in rundir.records())
    except RecordError as exc:
        return _fail(str(exc))
    if args.scene not in scenes:
        held = ", ".join(map(str, scenes)) or "none"
        return _fail(f"--scene {args.scene}: the robot run holds runs {held}")
    try:
        import_rerun()
    except ImportError as exc:
        return _fail(str(exc))
    out: Path = args.out or rundir.path / "viz" / f"scene-{args.scene:03d}.rrd"
    out.parent.mkdir(parents=True, exist_ok=True)
    print(
        f"heapgrasp show: planning run {args.scene} of {rundir.path} again from its recorded "
        "frames, with a recorder …",
        file=sys.stderr,
        flush=True,
    )
    grid = GridFrame((0.0, 0.0, 0.0), config.cube_size, config.resolution)
    recorder = RerunRecorder(out, grid, config.lam, name=f"robot-run-{args.scene}")
    t0 = time.perf_counter()
    try:
        result = replay(
            rundir.path,
            out=out.with_suffix(".json"),
            observer=recorder,
            scenes=[args.scene],
        )
    except RobotError as exc:
        return _fail(str(exc))
    finally:
        recorder.close()
    print(f"heapgrasp show: done in {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    outcomes = [r["recorded_outcome"] for r in result["phases"]]
    print(f"run {args.scene}: {len(outcomes)} phase(s), recorded outcomes {outcomes}")
    return _open(args, out)


def show_command(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp show``; returns the exit status."""
    from heapgrasp.results.records import CONFIG_FILE, RecordError, RunDir
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
    if (run_dir / "robot.json").is_file():
        return _show_robot_run(args, rundir)
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
    return _open(args, out)
