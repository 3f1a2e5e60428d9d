"""Shared fixtures for the heapgrasp test suite."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

import heapgrasp as hg
import reference as ref

if TYPE_CHECKING:
    from heapgrasp.sim.object_model import ObjectModel

GRID_ORIGIN = (-0.15, -0.15, 0.0)
GRID_SIZE = 0.30


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture
def camera() -> hg.PinholeCamera:
    """A small 40x30 camera with a non-centred principal point."""
    return hg.PinholeCamera(40, 30, 45.0, 47.0, 19.3, 14.6)


@pytest.fixture
def grid() -> hg.OccupancyGrid:
    return hg.OccupancyGrid(GRID_ORIGIN, GRID_SIZE, 12)


def ring_poses(
    n: int,
    radius: float = 0.7,
    height: float = 0.35,
    target=(0.0, 0.0, 0.15),
    jitter: float = 0.0,
    seed: int = 0,
) -> np.ndarray:
    """cam2world poses on a ring around ``target``; jitter breaks symmetries."""
    g = np.random.default_rng(seed)
    poses = []
    for k in range(n):
        ang = 2 * np.pi * k / n + 0.1 + jitter * g.uniform(-1, 1)
        eye = np.array([radius * np.cos(ang), radius * np.sin(ang), height])
        eye = eye + jitter * g.normal(size=3) * 0.05
        tgt = np.asarray(target) + jitter * g.normal(size=3) * 0.02
        poses.append(ref.look_at(eye, tgt))
    return np.ascontiguousarray(np.stack(poses))


@pytest.fixture
def poses() -> np.ndarray:
    return ring_poses(6, jitter=1.0, seed=7)


@pytest.fixture
def box_scene():
    """Two boxes at generic poses; returns (scene, list of (id, V, F, obj2world))."""
    g = np.random.default_rng(99)
    scene = hg.MeshScene()
    meshes = []
    for half, centre in [
        ((0.05, 0.035, 0.06), (0.03, -0.02, 0.07)),
        ((0.03, 0.045, 0.025), (-0.06, 0.05, 0.05)),
    ]:
        v, f = ref.box_mesh(half)
        pose = ref.pose_from(ref.random_rotation(g), centre)
        mid = scene.add_mesh(v, f, pose)
        meshes.append((mid, v, f, pose))
    return scene, meshes


def box_model(
    tmp: Path, extents: tuple[float, float, float] = (0.05, 0.05, 0.05), name: str = "box"
) -> ObjectModel:
    """A user box of ``extents`` (m) named ``test/NAME``, its mesh written to
    ``tmp/NAME.obj``."""
    import trimesh
    from heapgrasp.sim.object_model import ObjectModel

    path = tmp / f"{name}.obj"
    trimesh.creation.box(extents=extents).export(path)
    return ObjectModel(
        name=f"test/{name}",
        source="user",
        visual_mesh=path,
        collision_meshes=(path,),
        mass=0.1,
        split="test",
        extents=extents,
    )


class RejectEveryGrasp:
    """A grasp check (``HullCheck``'s signature) that rejects every pose: patched over
    the loop's checks, it must leave the loop no candidate."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        pass

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        return np.ones(len(poses), dtype=bool)
