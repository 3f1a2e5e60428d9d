"""Writes held-out validation objects for the viewsphere's learned policies: procedural
meshes (box, cylinder, bottle, bowl, cup) of a generator seed no dataset uses, as OBJ
files in one folder, for ``heapgrasp viewsphere bench --object-dir`` (each object rests
in its most stable pose, yaws over 0-359 degrees).

Select a policy by what the episodes do on these, never on the benchmark's test objects:

    python scripts/viewsphere_val_objects.py runs/vs-val-objects --per-kind 4
    heapgrasp viewsphere bench --object-dir runs/vs-val-objects --poses 10 \\
        --policies imitation,heuristic-3d,bfs --no-execute --out runs/vs-val-bench
"""

from __future__ import annotations

import argparse
from pathlib import Path

from heapgrasp.sim.procedural import PROCEDURAL_KINDS, procedural_mesh
from heapgrasp.viewsphere.data import PROCEDURAL_SEED

#: The validation objects' generator seed (the datasets' is ``PROCEDURAL_SEED``, the
#: benchmark library's 0).
VAL_SEED = 2002


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path, help="folder to write the OBJ files in")
    p.add_argument("--per-kind", type=int, default=4, help="objects per kind (default 4)")
    p.add_argument("--seed", type=int, default=VAL_SEED, help=f"generator seed ({VAL_SEED})")
    args = p.parse_args()
    if args.seed == PROCEDURAL_SEED or args.seed == 0:
        p.error(f"--seed {args.seed} is a dataset's or the benchmark library's")
    if args.per_kind < 1:
        p.error(f"--per-kind must be >= 1, got {args.per_kind}")
    args.out.mkdir(parents=True, exist_ok=True)
    for kind in PROCEDURAL_KINDS:
        for i in range(args.per_kind):
            path = args.out / f"val_{kind}_{i:02d}.obj"
            procedural_mesh(kind, i, args.seed).export(path)
            print(path)


if __name__ == "__main__":
    main()
