"""What the TSDF network's checked grasps fail on, and what the contact check catches.

For first phases of seeded piles (the VGN baseline's circle of depth views), the
network's top-5 candidates through the loop's own selection *without* the contact check
(the collision check only) are labelled by the exact labeller on the true meshes, and
each is judged by :class:`heapgrasp.planning.surface_contacts.TsdfContactCheck`; prints
the table of (labeller's reason, rejected by the contact check). Training objects by
default: a development probe, not a benchmark (docs/experiments.md, "The VGN baseline's
network, checked").

    python scripts/contact_check_probe.py --seeds 97000 97016
"""

from __future__ import annotations

import argparse
import collections

import heapgrasp.loop.phase as phase
import numpy as np
from heapgrasp.loop.config import RunConfig
from heapgrasp.planning.surface_contacts import TsdfContactCheck
from heapgrasp.sim.build import scene_world, sim_pipeline
from heapgrasp.sim.grasp_labels import labeller


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs=2, default=(97000, 97016), metavar=("FROM", "TO"))
    ap.add_argument("--category", default="opaque")
    ap.add_argument("--split", default="train", choices=("train", "test"))
    ap.add_argument("--weights", default=None, help="TSDF network ONNX (default: the shipped one)")
    args = ap.parse_args()
    changes = {"method": "vgn", "split": args.split, "category": args.category}
    changes["grasp_planner"] = "network"
    if args.weights:
        changes["grasp_weights"] = args.weights
    config = RunConfig().replace(changes, source="probe")
    # The loop's selection with the collision check alone: the contact check judges after.
    phase.TsdfContactCheck = _KeepAll  # type: ignore[misc,assignment]
    table: collections.Counter[tuple[str, bool]] = collections.Counter()
    for seed in range(*args.seeds):
        with scene_world(config, seed, args.category) as world:
            pipeline = sim_pipeline(config, world, seed=seed)
            pipeline.plan()
            cands = pipeline.grasp_candidates()[:5]
            if not cands:
                print(seed, "no candidate")
                continue
            poses = np.ascontiguousarray(np.stack([c.pose for c in cands]), dtype=np.float64)
            label = labeller(world)
            names = label.reasons()
            reasons = [names[int(r)] for r in label.label(poses, threads=1)[3]]
            tsdf = pipeline.perception.tsdf  # type: ignore[union-attr]
            check = TsdfContactCheck(tsdf.values(), tsdf.weights(), pipeline.frame)
            rejected = [bool(v) for v in check(poses)]
            table.update(zip(reasons, rejected, strict=True))
            print(seed, list(zip(reasons, rejected, strict=True)), flush=True)
    print("\n| exact label | rejected by the contact check | grasps |\n|---|---|--:|")
    for (reason, rejected), n in sorted(table.items()):
        print(f"| {reason} | {'yes' if rejected else 'no'} | {n} |")


class _KeepAll:
    def __init__(self, *args: object, **kwargs: object) -> None:
        pass

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        return np.zeros(len(poses), dtype=bool)


if __name__ == "__main__":
    main()
