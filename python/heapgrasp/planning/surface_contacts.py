"""Antipodal contacts read off a TSDF: what the collision check of a regressed grasp
(:mod:`heapgrasp.planning.hull_check`) cannot judge on voxel faces.

A parallel-jaw grasp holds when each finger meets the surface where the surface's normal
lies inside the friction cone about the closing direction (the antipodal condition; the
exact labeller's ``not-antipodal``, :mod:`heapgrasp.sim.grasp_labels`). On the VGN
baseline's TSDF the surface's normal is the TSDF's gradient, which the depth measured; the
observed shells the collision check reads (:func:`heapgrasp.perception.depth.tsdf_occupancy`)
have only axis-aligned faces. Of the TSDF network's grasps that pass the collision check,
the ones that fail mostly fail here: on training-object piles, the exact labeller called
6 of the network's 28 top grasps ``not-antipodal`` and no other failure
(``docs/experiments.md``, "The VGN baseline's network, checked").

:class:`TsdfContactCheck` closes each finger's pad (a grid of lines across its width and
depth, along the closing direction) from the fully open hand onto the observed shells; a
finger's contact is the mean of its pad's points where it first meets them, its normal
the TSDF's gradient there (trilinear). A grasp is rejected when either contact's normal
points more than ``atan(friction)`` away from the finger it faces, or vanishes. A grasp
whose fingers meet nothing is left to the collision check.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.gripper import PANDA_HAND, GripperGeometry

__all__ = ["TsdfContactCheck"]

F64 = npt.NDArray[np.float64]

_ACROSS = (-0.4, 0.0, 0.4)
"""The pad's lines across the finger (x), as fractions of its width."""
_ALONG = 8
"""The pad's lines along the approach (z), from the finger's base to its tip."""


class TsdfContactCheck:
    """Rejects grasps whose fingers would meet the TSDF's surface outside the friction
    cone (module doc).

    Parameters
    ----------
    values, weights
        The TSDF (``(R, R, R)``; :meth:`heapgrasp.TSDFVolume.values`, ``weights``).
    frame
        Where the grid lies.
    gripper
        The hand: its fingers' pads and widest opening.
    friction
        Coulomb friction of the fingers on the objects (the cone's half-angle is
        ``atan(friction)``); the simulator's is 1.0.
    """

    def __init__(
        self,
        values: npt.ArrayLike,
        weights: npt.ArrayLike,
        frame: GridFrame,
        *,
        gripper: GripperGeometry = PANDA_HAND,
        friction: float = 1.0,
    ) -> None:
        v = np.asarray(values, dtype=np.float64)
        w = np.asarray(weights)
        r = frame.resolution
        if v.shape != (r, r, r) or w.shape != (r, r, r):
            raise ValueError(
                f"values and weights must be {(r, r, r)} for this frame, "
                f"got {v.shape} and {w.shape}"
            )
        if not (math.isfinite(friction) and friction > 0):
            raise ValueError(f"friction must be finite and > 0, got {friction}")
        self.frame = frame
        self.inside = ((w > 0) & (v <= 0)).astype(np.float64)
        self.gradient = np.stack(list(np.gradient(v)), axis=0)
        self.cos_cone = 1.0 / math.sqrt(1.0 + friction * friction)
        step = frame.voxel_size / 4
        half = gripper.max_opening / 2
        self.ys = np.arange(-half, half + 1e-12, step)
        xs = np.asarray(_ACROSS) * gripper.finger_width
        zs = np.linspace(gripper.finger_base, gripper.finger_tip, _ALONG)
        x, z, y = np.meshgrid(xs, zs, self.ys, indexing="ij")  # (across, along, Y)
        self.pad_shape = x.shape
        self.local = np.stack([x, y, z], axis=-1).reshape(-1, 3)

    def _voxels(self, world: F64) -> F64:
        """Voxel coordinates (continuous; voxel centres at integers) of world points."""
        return ((world - self.frame.origin) / self.frame.voxel_size - 0.5).T

    def __call__(self, tcp2world: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """``(N,)`` True where the grasp at TCP pose ``tcp2world[i]`` (``(N, 4, 4)``, z
        the approach, fingers closing along y) meets the surface outside the cone."""
        poses = np.asarray(tcp2world, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise ValueError(f"tcp2world must be (N, 4, 4), got {poses.shape}")
        n = len(poses)
        out = np.zeros(n, dtype=bool)
        if n == 0:
            return out
        rot, t = poses[:, :3, :3], poses[:, :3, 3]
        points = np.einsum("nij,pj->npi", rot, self.local) + t[:, None, :]
        occupied = ndimage.map_coordinates(
            self.inside, self._voxels(points.reshape(-1, 3)), order=1, mode="constant"
        )
        occ = (occupied >= 0.5).reshape((n, *self.pad_shape))
        hit = occ.any(axis=(1, 2))  # (N, Y): a pad line meets the shells at this y
        met = hit.any(axis=1)
        ny = len(self.ys)
        local = self.local.reshape((*self.pad_shape, 3))
        for side in (1, -1):
            # The finger on +y closes towards -y: its contact is the largest y met.
            j = ny - 1 - np.argmax(hit[:, ::-1], axis=1) if side > 0 else np.argmax(hit, axis=1)
            rows = occ[np.arange(n), :, :, j]  # (N, across, along)
            count = np.maximum(rows.sum(axis=(1, 2)), 1)
            mean_local = (
                np.einsum("nab,nabk->nk", rows, local[:, :, j].transpose(2, 0, 1, 3))
                / count[:, None]
            )
            contact = np.einsum("nij,nj->ni", rot, mean_local) + t
            at = self._voxels(contact)
            normal = np.stack(
                [ndimage.map_coordinates(g, at, order=1, mode="nearest") for g in self.gradient],
                axis=1,
            )
            norm = np.linalg.norm(normal, axis=1)
            facing = side * rot[:, :, 1]  # from the surface towards this finger
            cos = np.einsum("ni,ni->n", normal, facing) / np.maximum(norm, 1e-12)
            out |= met & ((norm < 1e-9) | (cos < self.cos_cone))
        return out

    def __repr__(self) -> str:
        return f"TsdfContactCheck(cos_cone={self.cos_cone:.3f})"
