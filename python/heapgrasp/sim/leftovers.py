"""Why a scene ended with objects on the table: every leftover object described, and
tried on its true mesh.

:func:`describe_leftovers` runs once a clutter-removal run has stopped, on the world as
it is then. For each object still in the scene it records what it is (model name,
optical category, size), how it lies (upright or lying, by the tilt of its model's z
axis, which every procedural model has standing), where it lies (how far its nearest
vertex is from the scene cube's side border, and how far the nearest other object is)
and whether the simulated hand could have taken it at all: VGN's grasp sampler
(:func:`heapgrasp.sim.grasp_labels.sample_grasps`) on that object alone, each grasp
labelled by the exact labeller on the whole scene (:func:`~heapgrasp.sim.grasp_labels.labeller`:
a grasp that collides with a neighbour or takes two objects fails). An object with at
least one grasp that holds it is *graspable*: the planner could have removed it.

``removal ceiling`` of a run = (objects removed + graspable leftovers) / objects — what a
planner that always found such a grasp would have removed, had the scene not changed.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from heapgrasp.sim.bullet import pb
from heapgrasp.sim.grasp_labels import REASONS, labeller, sample_grasps
from heapgrasp.sim.world import SimWorld

__all__ = [
    "NEIGHBOUR_RANGE",
    "SAMPLE_POINTS",
    "SAMPLE_YAWS",
    "UPRIGHT_TILT_DEG",
    "describe_leftovers",
]

#: An object whose model z axis is within this angle of the world's z stands upright.
UPRIGHT_TILT_DEG = 25.0
#: Surface points sampled on each leftover (VGN's sampler), and yaws tried at each.
SAMPLE_POINTS = 256
SAMPLE_YAWS = 8
#: Neighbours farther than this (m) are not looked for (``neighbour_m`` is then None).
NEIGHBOUR_RANGE = 0.10


def _neighbour_distance(world: SimWorld, object_id: int) -> float | None:
    """Distance (m) from ``object_id`` to the nearest other object (PyBullet's closest
    points between their collision shapes; 0 or less: touching); None beyond
    :data:`NEIGHBOUR_RANGE`."""
    body = world.objects[object_id].body
    best: float | None = None
    for oid, other in world.objects.items():
        if oid == object_id:
            continue
        points = pb.getClosestPoints(
            body, other.body, distance=NEIGHBOUR_RANGE, physicsClientId=world.client
        )
        for p in points:
            d = float(p[8])
            best = d if best is None else min(best, d)
    return best


def describe_leftovers(
    world: SimWorld,
    rng: np.random.Generator,
    *,
    points: int = SAMPLE_POINTS,
    yaws: int = SAMPLE_YAWS,
) -> list[dict[str, Any]]:
    """One record per object left in ``world`` (see the module docstring), sorted by id:
    ``object_id``, ``name``, ``category``, ``extents_m`` (the model's box), ``tilt_deg``
    and ``upright``, ``border_m`` (nearest vertex to the cube's side border; negative:
    it sticks out), ``neighbour_m`` (None: none within :data:`NEIGHBOUR_RANGE`),
    ``grasps_tried`` and ``grasps_held`` (of ``points × yaws`` sampled grasps, those the
    labeller says hold this object), ``graspable`` (any held) and ``failures`` (the
    labeller's reasons for the rest, by name)."""
    if not world.objects:
        return []
    world.sync()
    label = labeller(world)
    size = world.config.cube_size
    out: list[dict[str, Any]] = []
    for oid in sorted(world.objects):
        obj = world.objects[oid]
        pose = world.object_pose(oid)
        verts = world.object_vertices(oid) @ pose[:3, :3].T + pose[:3, 3]
        xy = verts[:, :2]
        border = float(np.min(np.minimum(xy, size - xy)))
        tilt = float(np.degrees(np.arccos(np.clip(pose[2, 2], -1.0, 1.0))))
        samples = sample_grasps(world, rng, points, yaws, objects={oid})
        tried = len(samples.points) * yaws
        held_count = 0
        failures: Counter[str] = Counter()
        if tried:
            ok, _width, held, reason = label.label(samples.flat(), threads=1)
            mine = ok & (held == oid)
            held_count = int(mine.sum())
            failures = Counter(REASONS[int(r)] for r in reason[~mine])
            # a grasp that holds another object is a failure for this one
            failures.pop("success", None)
            other = int((ok & (held != oid)).sum())
            if other:
                failures["another-object"] = other
        out.append(
            {
                "object_id": oid,
                "name": obj.model.name,
                "category": obj.category.value,
                "extents_m": [float(e) for e in obj.model.extents],
                "tilt_deg": tilt,
                "upright": tilt <= UPRIGHT_TILT_DEG,
                "border_m": border,
                "neighbour_m": _neighbour_distance(world, oid),
                "grasps_tried": tried,
                "grasps_held": held_count,
                "graspable": held_count > 0,
                "failures": dict(sorted(failures.items())),
            }
        )
    return out
