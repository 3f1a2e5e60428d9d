"""``heapgrasp robot init|check|board|calibrate|run|replay``: the real robot.

Nothing moves without ``--execute``: ``run`` and ``calibrate`` default to a dry run that
checks every motion and sends none (``docs/real_robot.md``). ``--sim`` rehearses
``check``, ``calibrate`` and ``run`` against the simulator behind the same drivers
(:mod:`heapgrasp.sim.rehearsal`): nothing is contacted, no host need be set. ``replay``
plans a recorded run's phases again from its frames, with settings changed.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, TypeAlias

from heapgrasp.loop.config import parse_sets

__all__ = ["ROBOT_TOML", "add_parser", "add_replay"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"

#: ``heapgrasp robot init``'s template: every table, the defaults, what each key means.
ROBOT_TOML = """\
# heapgrasp robot configuration (docs/real_robot.md lists every key).
# Frames: the workspace ("world") frame is the scene cube's minimum corner on the table,
# z up; `heapgrasp robot calibrate` measures it with the ChArUco board and writes
# [calibration] below.

[arm]                       # UR e-Series over RTDE (remote-control mode on the pendant)
host = ""                   # your UR controller's address: set it before `robot check`
tcp = [0.0, 0.0, 0.2, 0.0, 0.0, 0.0]   # TCP in the flange frame [m, rotation vector]
park = [0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0]   # joints [rad], out of the view
servo_rate = 125.0          # Hz at which camera paths are streamed (servoL)
contact_force = 25.0        # N: an approach stops above this TCP force
travel_height = 0.25        # m above the table for moves to a pre-grasp pose

[workspace]                 # the TCP and the camera never leave this box [m, world]
min = [-0.25, -0.55, -0.01]
max = [0.55, 0.55, 0.75]
bin = [0.15, -0.3, 0.25]    # TCP position over the bin where objects are released

[limits]                    # caps checked before any command is sent
tool_speed = 0.25           # m/s
tool_acceleration = 1.2     # m/s^2
tool_rotation_speed = 3.0   # rad/s
joint_speed = 1.0           # rad/s
joint_acceleration = 1.4    # rad/s^2

[camera]                    # Intel RealSense colour stream
width = 320
height = 240
fps = 30
depth = false               # only the vgn baseline needs depth

[gripper]                   # Robotiq 2F-140 over the Robotiq URCap socket
port = 63352
speed = 255
force = 100

[networks]                  # ONNX files; relative paths are relative to this file
segmentation = ""           # `heapgrasp seg train` writes one; required for a run
view = ""                   # empty: the shipped view network
grasp = ""                  # empty: the shipped grasp network (grasp_planner = "network")

[method]                    # any `heapgrasp run` setting (docs/running.md)
method = "heapgrasp"
view_planner = "network"
grasp_planner = "antipodal"
"""


def _robot_error(exc: Exception) -> int:
    from heapgrasp.robot.errors import RobotConfigError

    print(f"heapgrasp: error: {exc}", file=sys.stderr)
    # a refused input (the file, a setting, an argument) exits 2; a device's failure 1
    return 2 if isinstance(exc, RobotConfigError | ValueError) else 1


#: Objects a rehearsal places where ``--objects`` is not given.
REHEARSAL_OBJECTS = 5


def _rehearsal(args: argparse.Namespace, *, board: bool = False) -> Any:
    """The simulator's rig for ``--sim`` (:class:`heapgrasp.sim.rehearsal.Rehearsal`), or None
    without it. Raises what reading ``robot.toml`` raises."""
    if not getattr(args, "sim", False):
        return None
    from heapgrasp.real.stages import load
    from heapgrasp.sim.rehearsal import Rehearsal

    if board:
        from heapgrasp.robot.calibration import require_opencv

        require_opencv()  # before the simulator is built: one line naming the extra
    robot, cfg = load(args.config, simulated=True)
    objects = getattr(args, "objects", None) or REHEARSAL_OBJECTS
    seed = getattr(args, "seed", 0)
    rig = Rehearsal(robot, cfg, seed=seed, objects=objects, board=board)
    what = (
        "the ChArUco board on the table"
        if board
        else f"{len(rig.placed)} objects (seed {seed}"
        + (
            f"; {objects - len(rig.placed)} fell off the table)"
            if len(rig.placed) < objects
            else ")"
        )
    )
    print(
        f"rehearsal: a simulated UR5e, RealSense and gripper (the simulator's hand) with {what}; "
        "no device is contacted",
        file=sys.stderr,
    )
    return rig


def _init(args: argparse.Namespace) -> int:
    path = Path(args.path)
    if path.exists() and not args.force:
        print(f"heapgrasp: error: {path} exists (pass --force to overwrite)", file=sys.stderr)
        return 2
    path.write_text(ROBOT_TOML)
    print(
        f"wrote {path}: set [arm] host, then `heapgrasp robot check --config {path}`; "
        f"or rehearse first, without a robot: `heapgrasp robot check --config {path} --sim`"
    )
    return 0


def _check(args: argparse.Namespace) -> int:
    from heapgrasp.real.check import check
    from heapgrasp.robot.errors import RobotError

    try:
        rig = _rehearsal(args)
        try:
            items = check(args.config, drivers=None if rig is None else rig.drivers())
        finally:
            if rig is not None:
                rig.close()
    except RobotError as exc:
        return _robot_error(exc)
    width = max(len(i["item"]) for i in items)
    for i in items:
        mark = "ok  " if i["ok"] else "FAIL"
        print(f"{mark} {i['item']:<{width}}  {i['detail']}")
    if args.json:
        Path(args.json).write_text(json.dumps(items, indent=2))
    return 0 if all(i["ok"] for i in items) else 1


def _run(args: argparse.Namespace) -> int:
    from heapgrasp.real import session
    from heapgrasp.robot.errors import RobotError

    if args.objects is not None and args.objects < 1:
        print(
            f"heapgrasp: error: --objects must be at least 1, got {args.objects}", file=sys.stderr
        )
        return 2
    rig = None
    try:
        rig = _rehearsal(args)
        drivers = None if rig is None else rig.drivers()
        if not args.execute:
            result = session.dry_run(args.config, args.out, drivers=drivers, viz=not args.no_viz)
            _print_dry_run(result, Path(args.out))
            return 0 if not result["refused"] else 1
        if rig is not None:
            args.objects = len(rig.placed)
        elif args.objects is None:
            print(
                "heapgrasp: error: --execute needs --objects N (how many objects you placed)",
                file=sys.stderr,
            )
            return 2
        if rig is None:
            print(
                f"heapgrasp: executing on the robot ({args.config}); the arm will move. "
                "Keep the emergency stop at hand.",
                file=sys.stderr,
            )
        record = session.execute(
            args.config, args.out, objects=args.objects, resume=args.resume, drivers=drivers
        )
    except RobotError as exc:
        out = Path(args.out)
        if out.is_dir() and any(out.iterdir()):
            _page(out)
            print(f"heapgrasp: the run's records and frames are kept in {out}", file=sys.stderr)
        else:
            print(f"heapgrasp: nothing was written to {out}", file=sys.stderr)
        return _robot_error(exc)
    finally:
        if rig is not None:
            rig.close()
    if record.get("frames_set_aside"):
        print(
            f"heapgrasp: frames of an earlier run that recorded nothing (killed?) were kept "
            f"as {Path(args.out) / record['frames_set_aside']}",
            file=sys.stderr,
        )
    phases = record.get("phases", [])
    ok = sum(1 for p in phases if p.get("outcome") == "success")
    written = _page(Path(args.out))
    print(
        f"run {record['scene']}: {ok} of {len(phases)} grasps succeeded, stopped: "
        f"{record.get('stop_reason')}; results in {Path(args.out) / 'results.json'}"
        + (f"; summary: {', '.join(map(str, written))}" if written else "")
    )
    truth = record.get("rehearsal")
    if truth:
        print(
            f"the simulator: {truth['objects_removed']} of {truth['objects_placed']} objects "
            f"in the bin, {truth['objects_left']} left; try "
            f"`heapgrasp robot replay {args.out}` and `heapgrasp show {args.out}`"
        )
    return 0


def _page(out: Path) -> list[Path]:
    """``OUT/summary.md`` and ``OUT/summary.png`` from ``OUT/results.json``, as
    ``heapgrasp run`` writes them (the runs so far); none where there is no summary."""
    from heapgrasp.plots import write_run_page
    from heapgrasp.results.summary import format_summary

    try:
        summary = json.loads((out / "results.json").read_text())
    except (OSError, ValueError):
        return []
    return write_run_page(summary, format_summary(summary), out)


def _print_dry_run(result: dict[str, Any], out: Path) -> None:
    print(f"dry run: {result['motion_commands_sent']} motion commands sent (none expected)")
    for c in result["checks"]:
        mark = "ok     " if c["ok"] else "SKIPPED" if c["motion"] == "path" else "REFUSED"
        where = c.get("end") or c.get("position")
        at = "" if where is None else f" -> {[round(x, 3) for x in where]}"
        print(f"  {mark} {c['motion']:<8}{at} {c['detail']}")
    g = result["grasp"]
    if result.get("stopped"):
        print(f"  the phase could not start: {result['stopped']}")
    elif g is None:
        print("  no grasp candidate from this view")
    else:
        pos = [round(r[3], 3) for r in g["pose"][:3]]
        print(f"  grasp at {pos} m, width {g['width']:.3f} m")
    if result.get("skipped_views"):
        print(
            f"  {len(result['skipped_views'])} view path(s) SKIPPED: the loop plans without "
            "them (too many, and move the arm's base or widen [workspace])"
        )
    if result["refused"]:
        print(f"  {len(result['refused'])} motion(s) REFUSED: a run would stop there")
    print(f"wrote {out / 'dry_run.json'}" + (f" and {result['rerun']}" if result["rerun"] else ""))
    if result["rerun"]:
        print(f"view it: rerun {result['rerun']}")


def _calibrate(args: argparse.Namespace) -> int:
    from heapgrasp.real.calibrate import calibrate_robot, read_taught, rehearse
    from heapgrasp.robot.errors import RobotError

    try:
        if args.synthetic:
            report = rehearse(Path(args.out), poses=args.poses, seed=args.seed)
            print(
                f"rehearsal on rendered images: {report['detected']} of {report['images']} "
                f"boards found; method {report['result']['method']}; extrinsic recovered to "
                f"{report['recovery_error_mm']:.2f} mm, {report['recovery_error_deg']:.3f}°"
            )
            return 0
        if args.config is None:
            print("heapgrasp: error: --config is required (or --synthetic)", file=sys.stderr)
            return 2
        taught = read_taught(args.taught) if args.taught else None
        rig = _rehearsal(args, board=True)
        try:
            report = calibrate_robot(
                args.config,
                args.out,
                poses=args.poses,
                execute=args.execute,
                seed=args.seed,
                taught=taught,
                drivers=None if rig is None else rig.drivers(),
            )
        finally:
            if rig is not None:
                rig.close()
    except (RobotError, ValueError) as exc:
        return _robot_error(exc)
    bad = [c for c in report["checks"] if not c["ok"]]
    print(f"{report['poses']} poses, {len(bad)} refused")
    for c in bad:
        print(f"  pose {c['pose']}: {c['detail']}")
    if not args.execute:
        print("dry run: nothing moved; pass --execute to visit the poses and calibrate")
        return 0 if not bad else 1
    res = report["result"]
    mean = sum(res["residuals_mm"]) / len(res["residuals_mm"])
    print(
        f"method {res['method']}: residuals mean {mean:.2f} mm; written to "
        f"{report['written']} (previous file: {report['backup']})"
    )
    return 0


#: The print resolutions ``robot board`` accepts: past 2400 dpi the image of the 28 × 20 cm
#: board is gigabytes (1,000,000 dpi ran OpenCV out of memory).
BOARD_DPI = (72, 2400)
#: The image formats ``robot board`` writes (OpenCV's writers).
BOARD_FORMATS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def _dpi(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    lo, hi = BOARD_DPI
    if not lo <= value <= hi:
        raise argparse.ArgumentTypeError(f"must be in [{lo}, {hi}], got {value}")
    return value


def _image_path(text: str) -> Path:
    path = Path(text)
    if path.suffix.lower() not in BOARD_FORMATS:
        raise argparse.ArgumentTypeError(
            f"{text!r}: the board is written as {', '.join(BOARD_FORMATS)}; "
            f"not {path.suffix or 'a file without an extension'}"
        )
    return path


def _board(args: argparse.Namespace) -> int:
    from heapgrasp.robot.calibration import CharucoBoard

    try:
        import cv2
    except ImportError:
        print(
            "heapgrasp: error: writing the board needs OpenCV: pip install 'heapgrasp[robot]'",
            file=sys.stderr,
        )
        return 2
    board = CharucoBoard()
    per_square = round(board.square / 0.0254 * args.dpi)
    image = board.image(pixels_per_square=per_square, margin=per_square // 2)
    if not cv2.imwrite(str(args.path), image):
        print(f"heapgrasp: error: cannot write {args.path}", file=sys.stderr)
        return 1
    w, h = board.size
    print(
        f"wrote {args.path}: {board.squares_x}x{board.squares_y} squares of {board.square * 100:g} "
        f"cm ({w * 100:g} x {h * 100:g} cm, {board.dictionary}); print it at {args.dpi} dpi, "
        "100 % scale, then measure a square: it must be 4.0 cm"
    )
    return 0


def _replay(args: argparse.Namespace) -> int:
    from heapgrasp.real.replay import replay
    from heapgrasp.robot.errors import RobotError

    try:
        result = replay(args.run_dir, parse_sets(args.set or []), out=args.out)
    except RobotError as exc:
        return _robot_error(exc)
    changes = result["changes"] or "no changes"
    print(f"replayed {result['phases_replayed']} phases of {args.run_dir} ({changes})")
    for r in result["phases"]:
        moved = r["grasp_moved_m"]
        change = (
            "no grasp"
            if r["replayed_grasp"] is None
            else (
                "same grasp"
                if moved is not None and moved <= 0.01
                else f"grasp moved {moved:.3f} m"
                if moved is not None
                else "new grasp"
            )
        )
        print(
            f"  run {r['scene']} phase {r['phase']}: recorded {r['recorded_outcome']}, "
            f"replayed: {change} ({r['frames_used']} frames)"
        )
    return 0


def _sim_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--sim",
        action="store_true",
        help="rehearse without hardware: the simulator stands in for the arm, the camera "
        "and the gripper behind the same drivers (docs/real_robot.md, 'Rehearse without a "
        "robot'); no host needed, nothing is contacted",
    )


def add_parser(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Adds ``heapgrasp robot`` to the CLI."""
    p = subparsers.add_parser(
        "robot",
        help="the real robot: UR e-Series + RealSense + Robotiq 2F-140 (no ROS)",
        description="HEAPGrasp on a real arm (docs/real_robot.md). Start with `robot init`, "
        "then `robot check`, `robot board` and `robot calibrate`, a dry `robot run`, and "
        "`robot run --execute`; `robot replay` plans a recorded run again. Add --sim to "
        "check, calibrate and run to rehearse all of it against the simulator first.",
    )
    sub = p.add_subparsers(dest="robot_command", metavar="COMMAND", required=True)

    init = sub.add_parser("init", help="write a commented robot.toml to edit")
    init.add_argument("path", nargs="?", default="robot.toml", help="where (default robot.toml)")
    init.add_argument("--force", action="store_true", help="overwrite an existing file")
    init.set_defaults(func=_init)

    chk = sub.add_parser(
        "check",
        help="connect to each device and report what it sees (no motion)",
        description="Reports, one line per item, the settings, the calibration, the "
        "segmentation network, the camera (one frame, the frame rate), the gripper (its "
        "registers, not activated) and the arm (modes, TCP, inside the box). Exits 1 if "
        "any item fails.",
    )
    chk.add_argument("--config", required=True, help="robot.toml")
    chk.add_argument("--json", metavar="FILE", help="also write the report as JSON")
    _sim_arguments(chk)
    chk.set_defaults(func=_check)

    run = sub.add_parser(
        "run",
        help="HEAPGrasp on the robot: a dry run, or the clutter removal with --execute",
        description="Without --execute (the default): plans the first phase from where the "
        "arm stands, checks every motion it would make (workspace box, speed caps, reach) "
        "and moves nothing; writes OUT/dry_run.json, the frames and a Rerun recording. "
        "With --execute: runs the clutter-removal protocol (HEAPGrasp §VI-C) and writes "
        "OUT/config.json, OUT/scenes.jsonl, OUT/results.json and every frame, as the "
        "simulator's runs; a protective stop, a lost device or Ctrl-C stops the arm and "
        "keeps what was recorded.",
    )
    run.add_argument("--config", required=True, help="robot.toml")
    run.add_argument("--out", default="robot-run", help="output directory (default robot-run)")
    run.add_argument("--execute", action="store_true", help="move the robot (default: dry run)")
    run.add_argument(
        "--objects",
        type=int,
        help="with --execute: how many objects you placed (with --sim: how many the "
        f"simulator places, default {REHEARSAL_OBJECTS})",
    )
    run.add_argument("--resume", action="store_true", help="add this run to OUT's runs")
    run.add_argument("--no-viz", action="store_true", help="dry run: no Rerun recording")
    _sim_arguments(run)
    run.add_argument("--seed", type=int, default=0, help="with --sim: the scene's seed (default 0)")
    run.set_defaults(func=_run)

    cal = sub.add_parser(
        "calibrate",
        help="hand-eye calibration with a ChArUco board (dry by default)",
        description="Lay the ChArUco board (7x5 squares of 4 cm, DICT_5X5_100) where the "
        "scene will be and jog the arm so the camera sees it from ~0.4 m. Generates --poses "
        "arm poses around it and checks them; with --execute visits each, detects the "
        "board, runs cv2.calibrateHandEye (every method; the best kept) and writes "
        "[calibration] into robot.toml (the old file kept as robot.toml.bak). --synthetic "
        "rehearses it on rendered board images, without hardware.",
    )
    cal.add_argument("--config", help="robot.toml")
    cal.add_argument("--out", default="calibration", help="report directory")
    cal.add_argument("--poses", type=int, default=15, help="arm poses (default 15)")
    cal.add_argument("--execute", action="store_true", help="move the arm and calibrate")
    cal.add_argument("--synthetic", action="store_true", help="rehearse on rendered images")
    _sim_arguments(cal)
    cal.add_argument("--seed", type=int, default=0, help="seed of the generated poses")
    cal.add_argument(
        "--taught",
        metavar="FILE",
        help="visit these TCP poses instead of generated ones: a JSON list of [x, y, z, "
        "rx, ry, rz] in the base frame, as the pendant shows them (m, rotation vector)",
    )
    cal.set_defaults(func=_calibrate)

    brd = sub.add_parser(
        "board",
        help="write the ChArUco calibration board as a PNG to print",
        description="Writes the board `robot calibrate` looks for (7x5 squares of 4 cm, "
        "3 cm markers, DICT_5X5_100) at the given print resolution.",
    )
    brd.add_argument(
        "path",
        nargs="?",
        type=_image_path,
        default="charuco_board.png",
        help="output image (.png, .jpg, .bmp or .tif; default charuco_board.png)",
    )
    brd.add_argument(
        "--dpi",
        type=_dpi,
        default=300,
        help=f"print resolution, {BOARD_DPI[0]} to {BOARD_DPI[1]} (default 300)",
    )
    brd.set_defaults(func=_board)
    add_replay(sub)
    return p


def add_replay(sub: SubParsers, name: str = "replay") -> argparse.ArgumentParser:
    """Adds ``robot replay`` (under ``name``)."""
    p = sub.add_parser(
        name,
        help="rerun perception and planning on a recorded robot run",
        description="Plans every recorded phase of a `robot run --execute` directory again "
        "from its saved frames, with the run's settings changed by --set, and reports per "
        "phase which grasp the robot would have taken and how far it is from the one it "
        "executed. Writes RUN_DIR/replay.json (or --out).",
    )
    p.add_argument("run_dir", help="a `heapgrasp robot run --execute` output directory")
    p.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="change a setting (repeatable)"
    )
    p.add_argument("--out", help="where to write the result (default RUN_DIR/replay.json)")
    p.set_defaults(func=_replay)
    return p
