"""Compares two policies episode by episode: two ``heapgrasp viewsphere bench --out``
folders (or one folder twice) on the same objects and poses, the steps each episode
took (6, the protocol's cap, when no grasp was found), and a two-sided sign test on the
episodes where they differ.

    python scripts/viewsphere_paired.py runs/vsval30-base3 dqn runs/vsval30-dqnP8 dqn

Prints the episodes in common, both mean steps, how many episodes the second took
fewer and more moves in, and the sign test's p-value. Episodes of only one run are left
out and counted.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

#: Steps counted for an episode without a grasp (the protocol's cap, as the bench's mean).
NOT_FOUND_STEPS = 6


def episode_steps(run: Path, policy: str) -> dict[tuple[str, int], int]:
    """Steps per (object, pose) of ``policy`` in the bench folder ``run``."""
    records = sorted((run / "records").glob("*.jsonl"))
    if not records:
        raise SystemExit(f"{run}: no records/*.jsonl (not a viewsphere bench --out folder?)")
    out: dict[tuple[str, int], int] = {}
    for path in records:
        for line in path.read_text().splitlines():
            if not line.strip():
                continue
            record = json.loads(line)
            episode = record.get("policies", {}).get(policy)
            if episode is None:
                continue
            steps = int(episode["steps"]) if episode["found"] else NOT_FOUND_STEPS
            out[(path.stem, int(record["pose"]))] = steps
    if not out:
        raise SystemExit(f"{run}: no episodes of policy {policy!r}")
    return out


def sign_test(fewer: int, more: int) -> float:
    """Two-sided exact sign test of ``fewer`` against ``more`` (ties left out)."""
    n = fewer + more
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(fewer, more) + 1)) / float(2**n)
    return min(1.0, 2.0 * tail)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run_a", type=Path, help="the first bench --out folder")
    p.add_argument("policy_a", help="its policy")
    p.add_argument("run_b", type=Path, help="the second bench --out folder")
    p.add_argument("policy_b", help="its policy")
    args = p.parse_args()
    a = episode_steps(args.run_a, args.policy_a)
    b = episode_steps(args.run_b, args.policy_b)
    common = sorted(set(a) & set(b))
    if not common:
        raise SystemExit("the two runs have no (object, pose) in common")
    fewer = sum(b[k] < a[k] for k in common)
    more = sum(b[k] > a[k] for k in common)
    mean_a = sum(a[k] for k in common) / len(common)
    mean_b = sum(b[k] for k in common) / len(common)
    print(f"episodes in common: {len(common)} (left out: {len(set(a) ^ set(b))})")
    print(f"mean steps: {args.policy_a} {mean_a:.2f}, {args.policy_b} {mean_b:.2f}")
    print(f"the second took fewer moves in {fewer}, more in {more}")
    print(f"two-sided sign test: p = {sign_test(fewer, more):.3g}")


if __name__ == "__main__":
    main()
