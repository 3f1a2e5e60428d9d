"""Scenes of axis-aligned or yawed boxes for the silhouette tests."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import trimesh
from heapgrasp import MeshScene

Box = tuple[tuple[float, float, float], tuple[float, float, float]]


def box_scene(boxes: Sequence[Box], yaws: Sequence[float] | None = None) -> MeshScene:
    """A :class:`MeshScene` of boxes ``(centre, extents)``, each turned about z by its
    entry of ``yaws`` (radians; none turned when omitted)."""
    scene = MeshScene()
    for i, (centre, extents) in enumerate(boxes):
        mesh = trimesh.creation.box(extents=extents)
        pose = np.eye(4)
        if yaws is not None:
            c, s = math.cos(yaws[i]), math.sin(yaws[i])
            pose[:2, :2] = [[c, -s], [s, c]]
        pose[:3, 3] = centre
        scene.add_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), pose)
    return scene
