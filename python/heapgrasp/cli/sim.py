"""``heapgrasp sim ...``: simulation commands.

``heapgrasp sim capture`` builds a seeded scene and captures frames on a circle around
it, writing ``frames.npz`` and ``scene.json`` (see :func:`capture_command`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

__all__ = ["add_parser", "capture_command"]


def add_parser(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Adds the ``sim`` command group to the ``heapgrasp`` CLI."""
    p = subparsers.add_parser(
        "sim",
        help="simulated scenes and cameras (PyBullet + exact ground truth)",
        description="Simulated scenes and cameras (PyBullet physics, exact ground truth "
        "from the Rust core).",
    )
    cmds = p.add_subparsers(dest="sim_command", metavar="COMMAND", title="commands", required=True)
    c = cmds.add_parser(
        "capture",
        help="build a scene and capture frames on a circle around it",
        description="Build a seeded scene (VGN's 0.30 m workspace on a table) and capture "
        "frames from cameras evenly spaced on a circle around it, looking at the cube "
        "centre. Writes OUT/frames.npz (rgb (N,H,W,3) uint8, depth (N,H,W) float32 in "
        "metres after the sensor model, 0 = missing; depth_ideal; masks (N,H,W) bool; "
        "labels (N,H,W) int32 object ids, 0 = background; cam2world (N,4,4); intrinsics "
        "[width, height, fx, fy, cx, cy]) and OUT/scene.json (objects with id, category, "
        "obj2world and the path of their mesh file in the object frame).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    c.add_argument("--layout", choices=("pile", "packed"), default="pile", help="scene layout")
    c.add_argument(
        "--category",
        choices=("transparent", "specular", "opaque", "mixed"),
        default="mixed",
        help="optical category of the objects (scene group of HEAPGrasp §VI-C)",
    )
    c.add_argument("--objects", type=int, default=5, help="number of objects to place")
    c.add_argument("--seed", type=int, default=0, help="seed of the scene and sensor noise")
    c.add_argument("--views", type=int, default=8, help="number of cameras on the circle")
    c.add_argument(
        "--radius",
        type=float,
        default=0.5,
        help="distance of the cameras from the bottom centre of the workspace (m)",
    )
    c.add_argument(
        "--elevation",
        type=float,
        default=45.0,
        help="polar angle of the cameras from the vertical (degrees)",
    )
    c.add_argument(
        "--camera",
        choices=("continuous", "still"),
        default="continuous",
        help="continuous = 320x240 (HEAPGrasp), still = VGN's 640x480, fx = fy = 540",
    )
    c.add_argument("--split", choices=("train", "test"), default="test", help="object subset")
    c.add_argument(
        "--user-objects",
        type=Path,
        default=None,
        help="directory of extra objects: subfolders NAME/model.urdf (YCB's layout) or "
        "OBJ/STL/PLY/URDF files, metres",
    )
    c.add_argument("--no-rgb", action="store_true", help="skip PyBullet RGB rendering (faster)")
    c.add_argument(
        "--ideal-depth", action="store_true", help="store ideal depth as 'depth' (no sensor model)"
    )
    c.add_argument("--gui", action="store_true", help="open the PyBullet GUI")
    c.add_argument("--out", type=Path, required=True, help="output directory")
    c.set_defaults(func=capture_command)
    return p


def capture_command(args: argparse.Namespace) -> int:
    """Runs ``heapgrasp sim capture``; returns the exit status."""
    from heapgrasp.geometry.camera import CameraSpec
    from heapgrasp.geometry.motion import ViewSphere, circle_waypoints
    from heapgrasp.sim.objects import ObjectLibrary
    from heapgrasp.sim.optics import DepthModel
    from heapgrasp.sim.world import SimWorld, WorldConfig

    if args.objects < 1:
        print(f"heapgrasp sim capture: --objects must be >= 1, got {args.objects}", file=sys.stderr)
        return 2
    if args.views < 1:
        print(f"heapgrasp sim capture: --views must be >= 1, got {args.views}", file=sys.stderr)
        return 2
    camera = CameraSpec.continuous() if args.camera == "continuous" else CameraSpec.still()
    library = ObjectLibrary.default()
    if args.user_objects is not None:
        library.add_user_directory(args.user_objects)
    config = WorldConfig()
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), config.cube_size, radius=args.radius)
    poses = circle_waypoints(sphere, L=args.views, theta=math.radians(args.elevation))
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    model = DepthModel(ideal=args.ideal_depth)
    with SimWorld(library, config=config, depth_model=model, gui=args.gui, seed=args.seed) as world:
        world.reset(
            layout=args.layout,
            n_objects=args.objects,
            category=args.category,
            seed=args.seed,
            split=args.split,
        )
        frames = [
            world.capture(pose, camera, rgb=not args.no_rgb)
            for pose in tqdm(poses, desc="capture", unit="view", file=sys.stderr)
        ]
        world.export_scene(out / "scene.json")
    arrays: dict[str, np.ndarray] = {
        "depth": np.stack([f.depth for f in frames if f.depth is not None]),
        "depth_ideal": np.stack([f.depth_ideal for f in frames if f.depth_ideal is not None]),
        "masks": np.stack([f.mask for f in frames]),
        "labels": np.stack([f.labels for f in frames]),
        "cam2world": np.stack([f.cam2world for f in frames]),
        "intrinsics": camera.intrinsics(),
    }
    if not args.no_rgb:
        arrays["rgb"] = np.stack([f.rgb for f in frames if f.rgb is not None])
    np.savez_compressed(out / "frames.npz", **arrays)  # type: ignore[arg-type]
    scene = json.loads((out / "scene.json").read_text())
    cats = [o["category"] for o in scene["objects"]]
    if len(scene["objects"]) < args.objects:
        print(
            f"heapgrasp sim capture: placed {len(scene['objects'])} of the {args.objects} "
            f"objects asked for; the others came to rest outside the {config.cube_size} m "
            "workspace cube and were removed (a pile drops some: --layout packed places them "
            "upright)",
            file=sys.stderr,
        )
    print(
        f"{len(frames)} frames of {camera.width}x{camera.height}, "
        f"{len(scene['objects'])} objects ({', '.join(sorted(set(cats)))}) -> {out}"
    )
    return 0
