"""Every carving kernel this CPU can run gives the same counts (``HEAPGRASP_KERNEL``), and a
request it cannot honour is named in a warning, not silently ignored.

The Rust property tests compare the levels voxel by voxel on random cases; this runs the
package as a user would, one process per level, on a carved scene."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

#: Carves 30 silhouettes of a sphere into a 40³ grid; prints the level and the counts'
#: sums and the voxels whose counts differ from `visible >= 1` (a compact fingerprint).
_CARVE = """
import json, numpy as np, warnings
warnings.simplefilter("always")
import heapgrasp
from heapgrasp import OccupancyGrid, PinholeCamera, MeshScene
import trimesh
cam = PinholeCamera(320, 240, 270.0, 270.0, 159.5, 119.5)
grid = OccupancyGrid((0.0, 0.0, 0.0), 0.3, 40)
sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.08)
scene = MeshScene()
pose0 = np.eye(4); pose0[:3, 3] = 0.15
scene.add_mesh(np.asarray(sphere.vertices, dtype=np.float64),
               np.asarray(sphere.faces, dtype=np.int64), pose0)
poses, masks = [], []
for k in range(30):
    a = 2 * np.pi * k / 30
    eye = np.array([0.15 + 0.4 * np.cos(a), 0.15 + 0.4 * np.sin(a), 0.35])
    z = np.array([0.15, 0.15, 0.1]) - eye; z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0]); x /= np.linalg.norm(x); y = np.cross(z, x)
    pose = np.eye(4); pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, eye
    poses.append(pose)
    masks.append(scene.render_mask(cam, pose))
grid.integrate_many(np.stack(masks), cam, np.stack(poses))
seg, vis = (c.reshape(-1) for c in grid.counts())
print(json.dumps({"level": heapgrasp.kernel_level(), "seg": seg.tolist(), "vis": vis.tolist()}))
"""


def _carve(level: str) -> tuple[dict[str, object], str]:
    env = {**os.environ, "HEAPGRASP_KERNEL": level}
    env.pop("HEAPGRASP_NO_SIMD", None)
    done = subprocess.run(
        [sys.executable, "-c", _CARVE], capture_output=True, text=True, env=env, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.splitlines()[-1]), done.stderr


def test_every_level_this_cpu_runs_carves_the_same_counts() -> None:
    baseline, _ = _carve("baseline")
    assert baseline["level"] == "baseline"
    assert sum(baseline["seg"]) > 1000 and sum(baseline["vis"]) > sum(baseline["seg"])
    ran = ["baseline"]
    for level in ("avx2", "avx512"):
        result, warned = _carve(level)
        if result["level"] != level:  # the CPU lacks it: said so
            assert f"HEAPGRASP_KERNEL={level}: this CPU cannot run" in warned
            continue
        ran.append(level)
        seg = [a != b for a, b in zip(result["seg"], baseline["seg"], strict=True)]
        vis = [a != b for a, b in zip(result["vis"], baseline["vis"], strict=True)]
        # f32 rounding may move a voxel centre lying on a pixel border to its neighbour
        # (the property tests bound where); on a scene a handful at most
        assert sum(seg) + sum(vis) <= 5, (level, sum(seg), sum(vis))
    print("kernel levels compared:", ran)


@pytest.mark.parametrize(
    ("value", "says"),
    [("avx9000", 'HEAPGRASP_KERNEL="avx9000" is not one of avx512, avx2, baseline')],
)
def test_an_unknown_kernel_request_is_named(value: str, says: str) -> None:
    env = {**os.environ, "HEAPGRASP_KERNEL": value}
    code = "import warnings; warnings.simplefilter('always'); import heapgrasp"
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert done.returncode == 0
    assert says in done.stderr and "using the" in done.stderr
