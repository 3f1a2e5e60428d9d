"""Grasps checked against the silhouette hull: what a grasp network's pose cannot do.

Carving keeps every voxel that every view's silhouette covers, so inside the volume the
views saw the hull ``Ŝ≥λ`` contains the objects (HEAPGrasp eq. 10). Two facts follow
for a parallel-jaw grasp executed as VGN executes it (pre-grasp, straight approach along
the TCP's z, close):

- a hand whose approach is clear of the hull and the table is clear of the objects;
- fingers that close on nothing of the hull close on nothing.

A grasp network (:mod:`heapgrasp.planning.grasp_network`) regresses one orientation per
voxel, and most of its grasps that failed in the closed loop ran the fingers or the palm
into an object (``docs/experiments.md``, "The grasp network"). :class:`HullCheck`
rejects the poses whose hand meets the hull or whose fingers close on none of it, with
the exact-geometry labeller of the Rust core (:class:`heapgrasp.GraspLabeller`, issue 38
§1) run on the hull instead of true meshes: the occupied voxels as a few boxes
(:func:`hull_boxes`). Carving keeps a voxel when its centre projects inside every
silhouette (:mod:`heapgrasp.perception.silhouette`), so an object may reach up to half a
voxel beyond the boxes: the hand must stay that far from them.

A pose it rejects for touching the hull may have been clear of the object itself (the
hull is larger: roofs, the volume between objects no view saw into); a pose it keeps may
still fail for contacts outside the friction cone, which it does not judge on voxel
faces, or close on phantom volume.

The VGN baseline's TSDF network is checked the same way against what the depth
measured: the TSDF's observed shells (``weight > 0`` and ``value <= 0``,
:func:`heapgrasp.perception.depth.tsdf_occupancy`, the grid the analytic planner plans
on there). They hold the surfaces the cameras saw, not the objects' insides, so a
finger may pass through an unseen back; the fused views of the circle see most sides.

The analytic planner (:mod:`heapgrasp.planning.antipodal`) makes the same collision
check on its own lattice; :func:`~heapgrasp.planning.volumes.select_candidates` applies
this one to a network's candidates (its ``reject`` argument).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from heapgrasp import GraspLabeller
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry

__all__ = ["HullCheck", "hull_boxes"]

F64 = npt.NDArray[np.float64]

#: Boxes per labeller object (:class:`heapgrasp.GraspLabeller` takes at most 4096 pieces
#: per object); a hull with more runs is split over several objects.
_PIECES_PER_OBJECT = 4096

# :data:`heapgrasp.GraspLabeller.reasons` codes that reject a grasp.
_COLLISION = 1
_EMPTY = 2


def _merge_runs(boxes: npt.NDArray[np.int64], axis: int) -> npt.NDArray[np.int64]:
    """Boxes ``(lo_x, lo_y, lo_z, hi_x, hi_y, hi_z)`` (voxel indices, ``hi`` exclusive)
    that are one voxel thick along ``axis`` and touch along it with the same extent on
    the other axes, merged into one."""
    others = [a for a in range(3) if a != axis]
    keys = [boxes[:, axis]] + [boxes[:, c] for a in others for c in (a, a + 3)]
    order = np.lexsort(keys)  # by the other extents, then along the axis (the last key first)
    b = boxes[order]
    same = np.ones(len(b), dtype=bool)
    same[0] = False
    for a in others:
        same[1:] &= (b[1:, a] == b[:-1, a]) & (b[1:, a + 3] == b[:-1, a + 3])
    same[1:] &= b[1:, axis] == b[:-1, axis + 3]
    first = np.flatnonzero(~same)
    out = b[first].copy()
    out[:, axis + 3] = np.maximum.reduceat(b[:, axis + 3], first)
    return out


def hull_boxes(occupied: npt.ArrayLike, frame: GridFrame) -> list[F64]:
    """Occupied voxels as few boxes whose union they are: the runs along z of each
    ``(x, y)`` column, runs of equal extent in neighbouring columns merged along y, then
    those along x; each box as its ``(8, 3)`` world corners."""
    occ = np.asarray(occupied, dtype=bool)
    r = frame.resolution
    if occ.shape != (r, r, r):
        raise ValueError(f"occupied must have shape {(r, r, r)}, got {occ.shape}")
    if not occ.any():
        return []
    padded = np.zeros((r, r, r + 2), dtype=np.int8)
    padded[:, :, 1:-1] = occ
    step = np.diff(padded, axis=2)
    starts = np.argwhere(step == 1)  # sorted by (x, y, z): runs pair up in order
    stops = np.argwhere(step == -1)[:, 2]
    boxes = np.column_stack([starts, starts[:, :2] + 1, stops]).astype(np.int64)
    boxes = _merge_runs(_merge_runs(boxes, 1), 0)
    v = frame.voxel_size
    origin = np.asarray(frame.origin, dtype=np.float64)
    lo = origin + boxes[:, :3].astype(np.float64) * v
    hi = origin + boxes[:, 3:].astype(np.float64) * v
    corner = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=bool)
    return list(np.ascontiguousarray(np.where(corner[None], hi[:, None, :], lo[:, None, :])))


class HullCheck:
    """Rejects grasps whose hand meets the hull or closes on none of it (module doc).

    Parameters
    ----------
    occupied
        ``(R, R, R)`` bool: the hull (the grid the planner was given, ``> 0``).
    frame
        Where the grid lies.
    gripper
        The hand, as boxes (:class:`~heapgrasp.geometry.gripper.GripperGeometry`).
    table_z
        Height of the table top (m); the hand must stay above it.
    pregrasp_distance
        How far back along the approach the hand starts (m).
    """

    def __init__(
        self,
        occupied: npt.ArrayLike,
        frame: GridFrame,
        *,
        gripper: GripperGeometry = PANDA_HAND,
        table_z: float = 0.0,
        pregrasp_distance: float = 0.05,
    ) -> None:
        self.labeller = GraspLabeller(
            dataclasses.asdict(gripper),
            table_z=table_z,
            friction=1.0,  # contact normals on voxel faces are not judged
            pregrasp_distance=pregrasp_distance,
            hand_margin=0.0,
            object_margin=frame.voxel_size / 2,  # carving tests voxel centres
            min_width=0.0,
        )
        boxes = hull_boxes(occupied, frame)
        for k in range(0, len(boxes), _PIECES_PER_OBJECT):
            self.labeller.add_object(k, np.eye(4), boxes[k : k + _PIECES_PER_OBJECT])
        self.boxes = len(boxes)

    def __call__(self, tcp2world: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """``(N,)`` True where the grasp at TCP pose ``tcp2world[i]`` (``(N, 4, 4)``, z
        the approach, fingers closing along y) is rejected."""
        poses = np.ascontiguousarray(tcp2world, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise ValueError(f"tcp2world must be (N, 4, 4), got {poses.shape}")
        if len(poses) == 0:
            return np.zeros(0, dtype=bool)
        reason = np.asarray(self.labeller.label(poses)[3])
        return np.isin(reason, (_COLLISION, _EMPTY))

    def __repr__(self) -> str:
        return f"HullCheck(boxes={self.boxes})"
