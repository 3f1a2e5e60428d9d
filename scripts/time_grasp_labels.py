"""The exact-geometry grasp labeller on simulated scenes: grasps labelled per second
(docs/benchmarks.md, "Grasp labeller").

``--scenes`` scenes of 5 objects of the default object library (pile and packed in
turn), VGN's 120 points × 6 yaws each (:func:`heapgrasp.sim.grasp_labels.sample_grasps`);
``labeller(world).label`` timed on 1 and 2 threads (the mean of ``--repeat`` calls), and
the whole of :func:`~heapgrasp.sim.grasp_labels.label_scene` (building the labeller,
sampling, labelling, VGN's reduction) once per scene.

Run: ``.venv/bin/python scripts/time_grasp_labels.py``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from heapgrasp.sim import grasp_labels as gl
from heapgrasp.sim.objects import ObjectLibrary
from heapgrasp.sim.world import SimWorld


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=int, default=10)
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    library = ObjectLibrary.default()
    grasps, pieces = 0, []
    label = {1: 0.0, 2: 0.0}
    build = scene = 0.0
    outcomes = np.zeros(len(gl.REASONS), dtype=np.int64)
    for seed in range(args.scenes):
        with SimWorld(library, seed=seed) as world:
            world.reset(layout="pile" if seed % 2 else "packed", n_objects=5, seed=seed)
            t = time.perf_counter()
            labeller = gl.labeller(world)
            build += time.perf_counter() - t
            pieces.append(labeller.piece_count)
            rng = np.random.default_rng(seed)
            poses = gl.sample_grasps(world, rng, 120, 6).flat()
            grasps += len(poses)
            for threads in label:
                t = time.perf_counter()
                for _ in range(args.repeat):
                    reason = labeller.label(poses, threads=threads)[3]
                label[threads] += (time.perf_counter() - t) / args.repeat
            outcomes += np.bincount(reason, minlength=len(gl.REASONS))
            t = time.perf_counter()
            gl.label_scene(world, rng, points=120, yaws=6)
            scene += time.perf_counter() - t
    print(f"{grasps} grasps over {args.scenes} scenes, {np.mean(pieces):.1f} pieces a scene")
    print("verdicts:", dict(zip(gl.REASONS, outcomes.tolist(), strict=True)))
    for threads, seconds in label.items():
        print(f"label, {threads} thread(s): {grasps / seconds:,.0f} grasps/s")
    print(f"labeller(world): {1000 * build / args.scenes:.1f} ms a scene")
    print(
        f"label_scene: {1000 * scene / args.scenes:.1f} ms a scene "
        f"({grasps / scene:,.0f} grasps/s, sampling and reduction included)"
    )


if __name__ == "__main__":
    main()
