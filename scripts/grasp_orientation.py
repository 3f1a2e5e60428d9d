#!/usr/bin/env python3
"""How well a grasp network's orientation matches its labels (issue 38 diagnostics).

For the successful grasps of a grasp dataset (``heapgrasp grasps data``), the angle
between the network's orientation at the grasp's voxel and the label's, split into the
**approach axis** (the TCP's z: where the hand comes from) and the **closing axis** (its
y, folded over the finger swap). The same angle for a network that always approaches
straight down is printed beside it, as the floor a network has to beat, and the angle between
each label's approach and the inward normal the input shows at its voxel (the gradient
of the grid smoothed by a 1-voxel Gaussian: up the occupancy, down the TSDF), which says
how far the labels' orientation can be read off the input at all. ``grasps train``
reports the whole rotation angle only; a network whose approach is off collides where
its quality says it grasps::

    python scripts/grasp_orientation.py models/grasp-network/grasp_network.onnx \\
        runs/grasps/test --scenes 60
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
from heapgrasp.inference import OnnxNetwork
from heapgrasp.training.grasp_data import GraspDataError, load_grasp_dataset
from scipy import ndimage
from scipy.spatial.transform import Rotation


def _angles(a: np.ndarray, b: np.ndarray, folded: bool) -> np.ndarray:
    cos = np.einsum("ij,ij->i", a, b)
    if folded:
        cos = np.abs(cos)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _stats(deg: np.ndarray) -> dict[str, float]:
    return {
        "mean": round(float(deg.mean()), 1),
        "median": round(float(np.median(deg)), 1),
        "p90": round(float(np.percentile(deg, 90)), 1),
        "over_30_deg": round(float((deg > 30).mean()), 3),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("network", help="the grasp network's ONNX file")
    p.add_argument("data", help="a grasp dataset directory (heapgrasp grasps data)")
    p.add_argument("--scenes", type=int, default=60, help="first N scenes (default 60)")
    args = p.parse_args(argv)
    if args.scenes < 1:
        p.error(f"--scenes must be >= 1, got {args.scenes}")
    try:
        net = OnnxNetwork(args.network, kind="grasp-network")
        data = load_grasp_dataset(args.data, input_kind=net.hparams.get("input_kind"))
    except (OSError, GraspDataError, ValueError) as err:
        print(f"grasp_orientation: error: {err}", file=sys.stderr)
        return 2
    label_z, label_y, net_z, net_y, inward = [], [], [], [], []
    sign = -1.0 if data.input_kind == "tsdf" else 1.0
    for s in range(min(args.scenes, len(data))):
        rows = slice(int(data.offsets[s]), int(data.offsets[s + 1]))
        ok = data.label[rows] == 1
        if not ok.any():
            continue
        _, rotation, _ = net.run(data.grids[s][None, None])
        i, j, k = data.voxel[rows][ok].T
        predicted = Rotation.from_quat(rotation[0][:, i, j, k].T).as_matrix()
        label = Rotation.from_quat(data.quat[rows][ok]).as_matrix()
        label_z.append(label[:, :, 2])
        label_y.append(label[:, :, 1])
        net_z.append(predicted[:, :, 2])
        net_y.append(predicted[:, :, 1])
        smooth = ndimage.gaussian_filter(data.grids[s].astype(np.float64), 1.0)
        inward.append(sign * np.stack([g[i, j, k] for g in np.gradient(smooth)], axis=1))
    lz, ly = np.concatenate(label_z), np.concatenate(label_y)
    nz, ny = np.concatenate(net_z), np.concatenate(net_y)
    down = np.broadcast_to([0.0, 0.0, -1.0], lz.shape)
    normal = np.concatenate(inward)
    length = np.linalg.norm(normal, axis=1)
    shown = length > 1e-6
    out = {
        "network": args.network,
        "data": args.data,
        "scenes": min(args.scenes, len(data)),
        "positives": len(lz),
        "approach_error_deg": _stats(_angles(nz, lz, folded=False)),
        "closing_axis_error_deg": _stats(_angles(ny, ly, folded=True)),
        "straight_down_approach_error_deg": _stats(_angles(down, lz, folded=False)),
        # the label's approach against the inward normal of the input at its voxel, where
        # the input has a gradient there (the fraction of the positives that do)
        "label_approach_to_input_normal_deg": _stats(
            _angles(normal[shown] / length[shown, None], lz[shown], folded=False)
        ),
        "positives_with_input_normal": round(float(shown.mean()), 3),
        "label_side_grasps": round(float((np.abs(lz[:, 2]) < 0.3).mean()), 3),
    }
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
