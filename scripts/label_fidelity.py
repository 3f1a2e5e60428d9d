#!/usr/bin/env python3
"""How good is a cheaper view label? Eq. 14 with fewer silhouettes per hypothetical
trajectory, against the oracle's 10 (the labels of ``heapgrasp views data``).

For each scene of Algorithm 1 (:func:`heapgrasp.data.views.scene_sample`: the same
scene, waypoints and target for every variant, only the label differs) it reports, per
``frames_per_candidate``: the wall time per labelled sample, the Spearman rank
correlation with the 10-frame label, top-1 agreement (same argmax), and top-1 regret
(the 10-frame score at the variant's argmax below the 10-frame maximum)::

    python scripts/label_fidelity.py --scenes 150 --seed 77 --split val
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from heapgrasp.data.views import ViewDataConfig, scene_sample
from heapgrasp.loop.config import RunConfig
from heapgrasp.sim.build import object_library
from scipy.stats import spearmanr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=int, default=150)
    parser.add_argument("--seed", type=int, default=77)
    parser.add_argument("--split", default="val")
    parser.add_argument("--frames", default="10,5,3,2,1")
    args = parser.parse_args()
    variants = [int(f) for f in args.frames.split(",")]
    library = object_library(RunConfig())
    seconds: dict[int, list[float]] = {f: [] for f in variants}
    labels: dict[int, list[np.ndarray]] = {f: [] for f in variants}
    for i in range(args.scenes):
        got = {}
        for f in variants:
            config = ViewDataConfig(
                scenes=args.scenes, root_seed=args.seed, split=args.split, frames_per_candidate=f
            )
            t0 = time.perf_counter()
            sample = scene_sample(config, i, library)
            seconds[f].append(time.perf_counter() - t0)
            got[f] = None if sample is None else sample["scores"]
        if all(v is not None for v in got.values()):
            for f in variants:
                labels[f].append(got[f])  # type: ignore[arg-type]
    ref = np.stack(labels[10]).reshape(len(labels[10]), -1)
    report = {"scenes": args.scenes, "kept": len(ref), "variants": {}}
    for f in variants:
        lab = np.stack(labels[f]).reshape(len(ref), -1)
        rho = [spearmanr(a, b).statistic for a, b in zip(lab, ref, strict=True)]
        top = lab.argmax(axis=1)
        report["variants"][f] = {
            "seconds_per_sample_median": float(np.median(seconds[f])),
            "seconds_per_sample_mean": float(np.mean(seconds[f])),
            "spearman_median": float(np.nanmedian(rho)),
            "spearman_mean": float(np.nanmean(rho)),
            "top1_agreement": float(np.mean(top == ref.argmax(axis=1))),
            "top1_regret_mean": float(np.mean(ref.max(axis=1) - ref[np.arange(len(ref)), top])),
        }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
