#!/usr/bin/env python3
"""Rewrite a format-1 grasp dataset (``heapgrasp grasps data`` before the palm origin)
as format 2, without running its scenes again.

Format 1 stored each grasp at its TCP; format 2 stores VGN's grasp origin, the centre
of the palm's face, ``-palm_front`` (3.9 cm for the Panda hand) behind the TCP along the
grasp's approach (``heapgrasp.data.grasps``). Each grasp's position moves back along its
approach, its voxel is read again, and grasps whose origin leaves the grid are dropped
(the only difference from a dataset made as format 2: its balancing drew the negatives
among the grasps inside the grid by their origin). Grids, labels, orientations and
widths are copied as they are::

    python scripts/grasp_data_v1_to_v2.py OLD/train NEW/train

The first ``--shards N`` shards only, to make a smaller dataset of a larger one.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from heapgrasp.geometry.gripper import PANDA_HAND
from scipy.spatial.transform import Rotation


def convert(src: Path, dst: Path, shards: int | None = None) -> int:
    """Writes ``dst`` (format 2) from ``src`` (format 1); returns the grasps kept."""
    manifest = json.loads((src / "manifest.json").read_text())
    if manifest.get("format") != "heapgrasp-grasp-data" or manifest.get("version") != 1:
        raise ValueError(f"{src}: not a format-1 grasp dataset")
    if not manifest.get("complete"):
        raise ValueError(f"{src}: the dataset is not complete; finish it first")
    files = sorted(src.glob("shard-*.npz"))[:shards]
    dst.mkdir(parents=True, exist_ok=True)
    entries = {}
    for f in files:
        with np.load(f) as npz:
            d = {k: npz[k] for k in npz.files}
        grid = d["tsdf"] if "tsdf" in d else d["occupancy"]
        r = grid.shape[1]
        approach = Rotation.from_quat(d["grasp_quat"].astype(np.float64)).as_matrix()[:, :, 2]
        position = d["grasp_position"].astype(np.float64) + approach * PANDA_HAND.palm_front
        scene = d["grasp_scene"]
        voxel = np.floor((position - d["origin"][scene]) / d["voxel_size"][scene][:, None])
        voxel = voxel.astype(np.int64)
        keep = ((voxel >= 0) & (voxel < r)).all(axis=1)
        d["grasp_position"] = position[keep].astype(np.float32)
        d["grasp_voxel"] = voxel[keep]
        for key in ("grasp_scene", "grasp_quat", "grasp_width", "grasp_label"):
            d[key] = d[key][keep]
        tmp = dst / f"{f.stem}.tmp.npz"
        np.savez_compressed(tmp, **d)
        tmp.replace(dst / f.name)
        entry = dict(manifest["shards"][f.name])
        entry.update(grasps=int(keep.sum()), bytes=(dst / f.name).stat().st_size)
        entries[f.name] = entry
    manifest.update(
        version=2,
        shards=entries,
        samples=sum(e["samples"] for e in entries.values()),
        dropped=sum(e["dropped"] for e in entries.values()),
        grasps=sum(e["grasps"] for e in entries.values()),
        converted_from=str(src),
    )
    manifest["config"]["scenes"] = sum(e["scenes"] for e in entries.values())
    (dst / "manifest.json").write_text(json.dumps(manifest, indent=1))
    return int(manifest["grasps"])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("src", type=Path, help="format-1 dataset directory")
    p.add_argument("dst", type=Path, help="format-2 dataset directory (written)")
    p.add_argument("--shards", type=int, default=None, help="the first N shards only")
    args = p.parse_args(argv)
    if args.shards is not None and args.shards < 1:
        p.error(f"--shards must be >= 1, got {args.shards}")
    try:
        kept = convert(args.src, args.dst, args.shards)
    except (OSError, ValueError, KeyError) as err:
        print(f"grasp_data_v1_to_v2: error: {err}", file=sys.stderr)
        return 2
    print(f"{args.dst}: {kept} grasps")
    return 0


if __name__ == "__main__":
    sys.exit(main())
