"""``heapgrasp bench world``: speed of the simulated world.

Measures, on one seeded pile scene (5 objects, mixed categories) seen from a ring of
cameras:

* frames/s of the ground-truth silhouettes and labels from the Rust core
  (:meth:`heapgrasp.MeshScene.render_labels` at the simulator's poses);
* frames/s of a full core capture (labels, ideal depth with the table plane, the
  transparent-free background, and the sensor model);
* frames/s of PyBullet's TinyRenderer (RGB + segmentation), the alternative source;
* seconds (wall clock) and simulated seconds of grasp phases: ground-truth top-down
  grasps of upright procedural boxes and cylinders (packed) with the free-flying hand,
  placing successes in the bin.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np

__all__ = ["run"]


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark and prints a Markdown table; returns the exit status."""
    from heapgrasp.geometry.camera import CameraSpec
    from heapgrasp.geometry.motion import ViewSphere, circle_waypoints
    from heapgrasp.loop.protocol import PlanResult, run_clutter_removal
    from heapgrasp.sim.gripper import PandaHand
    from heapgrasp.sim.objects import ObjectLibrary
    from heapgrasp.sim.robot import SimRobot
    from heapgrasp.sim.truth import SimTruth, top_down_grasp
    from heapgrasp.sim.world import SimWorld

    if args.frames < 1 or args.phases < 0:
        print("heapgrasp bench world: --frames must be >= 1, --phases >= 0", file=sys.stderr)
        return 2
    cam = CameraSpec.continuous() if args.camera == "continuous" else CameraSpec.still()
    sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), 0.30, radius=0.5)
    poses = circle_waypoints(sphere, L=args.frames, theta=math.radians(45))
    results: dict[str, Any] = {"camera": f"{cam.width}x{cam.height}", "frames": args.frames}
    with SimWorld(ObjectLibrary.default(), seed=args.seed) as world:
        world.reset(layout="pile", n_objects=5, category="mixed", seed=args.seed)
        results["objects"] = len(world.objects)
        results["triangles"] = world.object_scene.triangle_count

        def rate(fn: Any) -> float:
            fn(poses[0])  # warm-up
            t0 = time.perf_counter()
            for pose in poses:
                fn(pose)
            return len(poses) / (time.perf_counter() - t0)

        results["core_masks_fps"] = rate(lambda p: world.capture(p, cam, depth=False))
        results["core_capture_fps"] = rate(lambda p: world.capture(p, cam, depth=True))
        results["pybullet_tiny_fps"] = rate(lambda p: world.render_rgb(p, cam))

        # Grasp phases on upright procedural boxes and cylinders (graspable top-down).
        upright = [
            m
            for m in world.library.models(source="procedural")
            if any(k in m.name for k in ("box", "cylinder"))
        ][:4]
        world.reset(layout="packed", n_objects=len(upright), seed=args.seed, models=upright)
        hand = PandaHand(world)
        count = 0

        def plan() -> PlanResult:
            nonlocal count
            count += 1
            if count > args.phases or not world.objects:
                return PlanResult(None)
            oid = min(world.objects)
            return PlanResult(top_down_grasp(world, oid), np.zeros((1, 3)), 0.0, target_object=oid)

        t0 = time.perf_counter()
        sim0 = hand.time
        phases, reason = run_clutter_removal(
            SimRobot(hand), plan, truth=SimTruth(world, hand), max_attempts=args.phases
        )
        wall = time.perf_counter() - t0
        done = [p for p in phases if p.attempted]
        results["phases"] = len(done)
        results["phase_wall_s"] = wall / max(1, len(done))
        results["phase_simulated_s"] = (hand.time - sim0) / max(1, len(done))
        results["phase_outcomes"] = [p.outcome for p in done]
        results["stop"] = reason.value
    print(f"| measure | value ({results['camera']}, {results['triangles']} triangles) |")
    print("|---|--:|")
    print(f"| ground-truth masks + labels (Rust core) | {results['core_masks_fps']:.0f} frames/s |")
    print(
        f"| full capture: labels, depth, background, sensor model | "
        f"{results['core_capture_fps']:.0f} frames/s |"
    )
    tiny = results["pybullet_tiny_fps"]
    print(f"| PyBullet TinyRenderer RGB + segmentation | {tiny:.1f} frames/s |")
    print(
        f"| grasp phase (grasp + place), wall clock | {results['phase_wall_s']:.2f} s "
        f"({results['phases']} phases: {', '.join(results['phase_outcomes'])}) |"
    )
    print(f"| grasp phase, simulated time | {results['phase_simulated_s']:.2f} s |")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2))
    return 0
