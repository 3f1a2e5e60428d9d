"""What the grasp planner had where a run stopped on "no candidate".

Runs ``--scenes`` scenes of ``heapgrasp run``'s defaults (``--set`` applies) from
``--seed`` (the four scene groups in turn). Wherever a phase ends without a candidate,
every candidate of the analytic planner on that phase's final grid down to
``--epsilon`` (at most ``--max`` of them, best analytic score first) is scored by the
critic without its threshold and executed in the simulator from a saved physics state
(restored after each), so each is labelled by what it would have done. Prints one JSON
line per candidate (scene, phase, analytic score, critic probability, outcome) to
``--out``, then a summary: how many of those phases held a grasp that would have held,
and how the outcomes spread over the critic's probability.

    python scripts/no_candidate_probe.py --scenes 40 --seed 90000 --out probe.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb
from heapgrasp.loop.config import RunConfig, parse_sets
from heapgrasp.loop.protocol import PlanResult, run_clutter_removal
from heapgrasp.perception.silhouette import SilhouettePerception
from heapgrasp.planning.volumes import select_candidates
from heapgrasp.sim.build import make_body, scene_world, sim_pipeline
from heapgrasp.sim.gripper import MAX_OPENING, Grasp, execute_grasp

GROUPS = ("transparent", "opaque", "specular", "mixed")


def probe_scene(
    config: RunConfig,
    index: int,
    epsilon: float,
    most: int,
    probe_planner: Any = None,
    fine_check: bool = False,
) -> list[dict[str, Any]]:
    """``probe_planner``: plans the probed grids in place of the loop's planner (the loop
    itself runs as configured)."""
    seed = config.seed + index
    rows: list[dict[str, Any]] = []
    with scene_world(config, seed, GROUPS[index % 4]) as world:
        body = make_body(config, world)
        pipeline = sim_pipeline(config, world, seed=seed, body=body)
        perception = pipeline.perception
        assert isinstance(perception, SilhouettePerception)
        plan_phase = pipeline.plan
        phase = 0

        def plan() -> PlanResult:
            nonlocal phase
            result = plan_phase()
            phase += 1
            if result.grasp is not None:
                return result
            grid = perception.grasp_input()
            planner = probe_planner or pipeline.grasp_planner
            volumes = planner.predict(grid, pipeline.frame)
            cands = select_candidates(
                volumes,
                epsilon=epsilon,
                sigma=float(getattr(planner, "sigma", 1.0)),
                nms_window=config.nms_window,
                max_width=MAX_OPENING,
            )[:most]
            analytic = {c.index: c.score for c in cands}
            critic = pipeline.critic
            probs: dict[Any, float] = {}
            if critic is not None and cands:
                threshold = critic.threshold
                critic.threshold = 0.0
                try:
                    rescored = critic.rescore(
                        cands,
                        grid,
                        perception.grid.high_confidence(config.lam),
                        pipeline.frame,
                        perception.camera_positions(),
                    )
                finally:
                    critic.threshold = threshold
                probs = {c.index: c.score for c in rescored}
            fine: dict[Any, dict[str, bool]] = {}
            if fine_check:
                from heapgrasp.planning.hull_check import HullCheck

                for c in cands:
                    centre = c.pose[:3, 3] - 0.03 * c.pose[:3, 2]
                    row = {}
                    for name, radius in (("fine", perception.roof_radius), ("fine_raw", 0.0)):
                        keep_radius = perception.roof_radius
                        perception.roof_radius = radius
                        try:
                            occ, frame = perception.local_input(centre)
                        finally:
                            perception.roof_radius = keep_radius
                        check = HullCheck(occ > 0, frame, gripper=pipeline.robot.gripper.geometry)
                        row[name] = not bool(check(c.pose[None])[0])
                    fine[c.index] = row
            state = pb.saveState(physicsClientId=world.client)
            for c in cands:
                width = min(c.width + 0.01, MAX_OPENING)
                outcome = execute_grasp(body, Grasp(c.pose, width))
                rows.append(
                    {
                        "scene": index,
                        "seed": seed,
                        "phase": phase - 1,
                        "score": analytic[c.index],
                        "p": probs.get(c.index),
                        "z": float(c.pose[2, 3]),
                        "tilt_deg": float(np.degrees(np.arccos(-c.pose[2, 2]))),
                        "outcome": outcome.outcome.value,
                        "left": len(world.objects),
                        "width": float(c.width),
                        **fine.get(c.index, {}),
                    }
                )
                pb.restoreState(state, physicsClientId=world.client)
                world.sync()
                body.park()
            pb.removeState(state, physicsClientId=world.client)
            if not cands:
                rows.append({"scene": index, "seed": seed, "phase": phase - 1, "score": None})
            return result

        run_clutter_removal(
            pipeline.robot,
            plan,
            truth=pipeline.truth,
            max_attempts=config.max_attempts,
            on_outcome=pipeline.record_outcome,
        )
    return rows


def summarise(rows: list[dict[str, Any]]) -> str:
    phases: dict[tuple[int, int], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        phases[(r["scene"], r["phase"])].append(r)
    tried = [r for r in rows if r.get("score") is not None]
    held_any = sum(any(r.get("outcome") == "success" for r in v) for v in phases.values())
    lines = [
        f"no-candidate phases: {len(phases)}; with a candidate >= epsilon: "
        f"{sum(any(r.get('score') is not None for r in v) for v in phases.values())}; "
        f"with one that would have held: {held_any}"
    ]
    for lo, hi in ((0.0, 0.2), (0.2, 0.4), (0.4, 0.5), (0.5, 0.6), (0.6, 0.7), (0.7, 1.01)):
        sel = [r for r in tried if r["p"] is not None and lo <= r["p"] < hi]
        ok = sum(r["outcome"] == "success" for r in sel)
        lines.append(f"critic p in [{lo:.1f}, {hi:.1f}): {ok}/{len(sel)} held")
    for lo, hi in ((0.0, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 1.01)):
        sel = [r for r in tried if lo <= r["score"] < hi]
        ok = sum(r["outcome"] == "success" for r in sel)
        lines.append(f"analytic score in [{lo:.1f}, {hi:.1f}): {ok}/{len(sel)} held")
    # the loop would take the best few by the critic: the top one per phase
    top = [
        max((r for r in v if r.get("p") is not None), key=lambda r: r["p"], default=None)
        for v in phases.values()
    ]
    top = [t for t in top if t is not None]
    ok = sum(t["outcome"] == "success" for t in top)
    lines.append(f"the critic's top candidate per phase: {ok}/{len(top)} held")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--seed", type=int, default=90000)
    ap.add_argument("--epsilon", type=float, default=0.02)
    ap.add_argument("--max", type=int, default=12)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument(
        "--max-opening",
        type=float,
        help="probe with an analytic planner that takes the hand to open this wide (m): "
        "0.0875 for the Panda's 0.08 m is its width rule on voxel centres instead of faces",
    )
    ap.add_argument(
        "--fine",
        action="store_true",
        help="also check each candidate's hand against the phase's silhouettes carved "
        "finer around it (2.5 mm voxels), roofs trimmed and not",
    )
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    config = RunConfig(seed=args.seed).replace(parse_sets(args.set), source="--set")
    rows: list[dict[str, Any]] = []
    planner = None
    if args.max_opening is not None:
        from heapgrasp.geometry.gripper import PANDA_HAND
        from heapgrasp.planning.antipodal import AntipodalPlanner

        planner = AntipodalPlanner(max_opening=args.max_opening, gripper=PANDA_HAND)
    with args.out.open("w") as f:
        for i in range(args.scenes):
            got = probe_scene(config, i, args.epsilon, args.max, planner, args.fine)
            rows.extend(got)
            for r in got:
                f.write(json.dumps(r) + "\n")
            f.flush()
            print(f"scene {i}: {len(got)} rows", file=sys.stderr)
    print(summarise(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
