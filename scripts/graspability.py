"""How graspable the objects of fresh scenes are before anything is taken, and how that
compares with what a finished run left behind.

For ``--scenes`` scenes from ``--seed`` (the defaults of ``heapgrasp run``: test split,
5-object piles, the four scene groups in turn as ``bench sim`` draws them), every object
of the settled scene is tried on its true mesh as
:func:`heapgrasp.sim.leftovers.describe_leftovers` tries a leftover (VGN's sampler,
the exact labeller on the whole scene). With ``--run DIR`` (a finished ``heapgrasp run``
or ``bench sim`` method folder on the same seeds), prints the same figures for the
objects that run left on the table.

    python scripts/graspability.py --scenes 80 --seed 60000 --run $OUT/d/heapgrasp
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from heapgrasp.bench.sim import scene_groups
from heapgrasp.loop.config import RunConfig
from heapgrasp.sim.build import scene_world
from heapgrasp.sim.leftovers import describe_leftovers


def _describe(name: str, objs: list[dict[str, Any]]) -> str:
    if not objs:
        return f"{name}: none"
    frac = np.array([o["grasps_held"] / max(o["grasps_tried"], 1) for o in objs])
    graspable = sum(bool(o["graspable"]) for o in objs)
    lying = sum(not o["upright"] for o in objs)
    q = np.percentile(100 * frac, [25, 50, 75])
    return (
        f"{name}: {len(objs)} objects, {graspable} graspable, {lying} lying; sampled grasps "
        f"that hold: quartiles {q[0]:.2f} / {q[1]:.2f} / {q[2]:.2f} %; "
        f"below 1 %: {int((frac < 0.01).sum())}"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scenes", type=int, default=40)
    ap.add_argument("--seed", type=int, default=60000)
    ap.add_argument("--run", type=Path, help="a finished run's folder on the same seeds")
    args = ap.parse_args()
    config = RunConfig(seed=args.seed, scenes=args.scenes)
    groups = scene_groups(args.scenes)
    start: list[dict[str, Any]] = []
    for i in range(args.scenes):
        seed = args.seed + i
        with scene_world(config, seed, groups[i]) as world:
            start.extend(describe_leftovers(world, np.random.default_rng(seed)))
    print(_describe("at the start", start))
    if args.run is not None:
        records = [
            json.loads(line)
            for line in (args.run / "scenes.jsonl").read_text().splitlines()
            if line.strip()
        ]
        left = [o for r in records for o in r.get("leftovers", [])]
        print(_describe(f"left by {args.run}", left))
    return 0


if __name__ == "__main__":
    sys.exit(main())
