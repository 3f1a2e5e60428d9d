"""Grasp labels on the exact geometry of a simulated scene, and VGN's grasp sampler.

:func:`labeller` builds a :class:`heapgrasp.GraspLabeller` (the Rust core's
``grasp_label``) from a live :class:`~heapgrasp.sim.world.SimWorld`: every object's
convex collision pieces (the files PyBullet collides it as, each as its convex hull) at
the pose PyBullet has it now, the table's top, the Panda hand as PyBullet collides it
(:func:`panda_hand_parts`: the hulls of its collision meshes, fingers open), the
friction PyBullet uses between a finger and an object, and PyBullet's contact margins.
It labels a grasp as :func:`heapgrasp.sim.gripper.execute_grasp` would execute it with
the fingers fully open (VGN's data generation): collision-free pre-grasp pose and
approach, both fingers closing on one object, antipodal contacts within the friction
cone (codes in :data:`REASONS`), thousands of times faster than executing it.

:func:`sample_grasps` is VGN's grasp sampler (``generate_data.py`` of VGN): surface
points of the objects (area-weighted on their true meshes) whose outward normal has
``n_z > -0.1``; the grasp frame's z is the inward normal; ``yaws`` yaws evenly in
``[0, π)`` about it; the grasp depth ``u · finger_depth``, ``u ~ U[-0.1, 1.1]``.
VGN's TCP sits at the base of its fingers, so its depth is how far the surface point
lies in front of the palm (0: the palm on the surface, ``finger_depth``: the fingertips
on it); our TCP (``panda_grasptarget``) is ``finger_tip`` short of the fingertips, so the
TCP is placed at ``point + normal · (u · finger_depth + palm_front)``.
:func:`best_yaw` is VGN's reduction to one grasp per point, and :func:`label_scene` runs
the three on a world.

Frames: world (table top ``z = 0``); a TCP pose ``tcp2world`` has z the approach
direction and the fingers closing along y.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp import GraspLabeller
from heapgrasp.geometry.gripper import GRASP_DEPTH_RANGE, PANDA_HAND, GripperGeometry
from heapgrasp.robot.grasping import PREGRASP_DISTANCE
from heapgrasp.sim.bullet import pb
from heapgrasp.sim.hand import (
    FINGER_FRICTION,
    FINGER_JOINT_Z,
    MAX_OPENING,
    MIN_HELD_WIDTH,
    PANDA_MESHES,
    TCP_OFFSET,
)
from heapgrasp.sim.mesh_files import load_mesh
from heapgrasp.sim.world import SimWorld

__all__ = [
    "APPROACH_LAG",
    "BREAKING_FACTOR",
    "CONVEX_MARGIN",
    "MIN_NORMAL_Z",
    "REASONS",
    "GraspSamples",
    "best_yaw",
    "bullet_size",
    "grasps_at",
    "label_samples",
    "label_scene",
    "labeller",
    "panda_hand_parts",
    "sample_grasps",
    "table_top",
]

F64 = npt.NDArray[np.float64]

#: Names of the labeller's reason codes, indexed by code: ``success``, ``collision``
#: (the open hand touches something at the pre-grasp pose or on the approach),
#: ``empty`` (a finger closes on nothing), ``two-objects``, ``not-antipodal`` (a contact
#: normal outside the friction cone), ``narrow`` (closed below
#: :data:`~heapgrasp.sim.hand.MIN_HELD_WIDTH`).
REASONS: tuple[str, ...] = tuple(GraspLabeller.reasons())

#: PyBullet's collision margin around a convex mesh shape (the hand's links and the
#: objects' pieces), m. Measured: the hand reports a contact with an object from 2 mm
#: apart, with the table (a box shape, whose margin lies inside it) from 1 mm.
CONVEX_MARGIN = 0.001

#: Bullet's contact-breaking threshold as a fraction of a shape's size (its
#: ``gContactBreakingThreshold``): two shapes report a contact up to this fraction of the
#: smaller one's :func:`bullet_size` beyond their margins. Measured: the palm reports the
#: table from 2.6 to 3.6 mm (1 mm margin + 2.7 mm, less the lag), the fingers' pads a box
#: face they slide along from 2.8 to 2.9 mm (2 mm of margins + 0.9 to 1.2 mm).
BREAKING_FACTOR = 0.02

#: How far the free-flying hand trails its commanded pose on the approach (m): it moves
#: at 0.1 m/s on a constraint, is checked for contacts only on the way, and catches up
#: unchecked (measured: 1.2 to 1.9 mm).
APPROACH_LAG = 0.0015

#: VGN keeps surface points whose outward normal has a z component above this.
MIN_NORMAL_Z = -0.1

#: VGN's grasp depth range, in finger depths.
DEPTH_RANGE = GRASP_DEPTH_RANGE


def table_top(world: SimWorld) -> float:
    """World z of the top of the world's table (its box shape's upper face)."""
    shape = pb.getCollisionShapeData(world.table, -1, physicsClientId=world.client)[0]
    position = pb.getBasePositionAndOrientation(world.table, physicsClientId=world.client)[0]
    return float(position[2] + 0.5 * shape[3][2])


@lru_cache(maxsize=4096)
def _piece(path: str) -> F64:
    vertices, _ = load_mesh(path)
    vertices.flags.writeable = False
    return vertices


@lru_cache(maxsize=1024)
def _surface(path: str) -> tuple[F64, npt.NDArray[np.int64]]:
    """A visual mesh with its faces turned outward (by its signed volume)."""
    v, f = load_mesh(path)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    if np.einsum("ij,ij->i", a, np.cross(b, c)).sum() < 0:
        f = f[:, ::-1].copy()
    v.flags.writeable = False
    f.flags.writeable = False
    return v, f


def bullet_size(pieces: list[F64] | tuple[F64, ...]) -> float:
    """Bullet's size of a collision shape (its "angular motion disc"): the radius of the
    ball around the bounding box of ``pieces`` ((V, 3) vertices in the body's frame, m)
    plus the box centre's distance from the frame's origin."""
    v = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in pieces])
    lo, hi = v.min(axis=0), v.max(axis=0)
    return float(np.linalg.norm(hi - lo) / 2 + np.linalg.norm((hi + lo) / 2))


def panda_hand_parts(opening: float = MAX_OPENING) -> dict[str, Any]:
    """The Panda hand as PyBullet collides it, for :class:`heapgrasp.GraspLabeller`:
    the vertices of ``hand.obj`` and of the two ``finger.obj`` of
    :data:`~heapgrasp.sim.hand.PANDA_MESHES` (each collided as its convex hull) placed
    as :class:`~heapgrasp.sim.gripper.PandaHand`'s URDF places them, in the TCP frame
    with the finger pads ``opening`` apart.

    Returns ``{"palm": [(V, 3)], "left": [(V, 3)], "right": [(V, 3)], "max_opening":
    opening, "palm_threshold": ..., "finger_threshold": ...}`` (float64 arrays, metres;
    ``left`` on the +y side; the thresholds Bullet's contact-breaking distances of the
    hand's and a finger's link, :data:`BREAKING_FACTOR` times their :func:`bullet_size`).
    """
    collision = PANDA_MESHES / "collision"
    palm = _piece(str(collision / "hand.obj")) - np.array([0.0, 0.0, TCP_OFFSET])
    finger = _piece(str(collision / "finger.obj"))
    z = FINGER_JOINT_Z - TCP_OFFSET
    # The right finger's collision origin turns it by π about z (the URDF's rpy).
    left = finger + np.array([0.0, 0.5 * opening, z])
    right = finger * np.array([-1.0, -1.0, 1.0]) + np.array([0.0, -0.5 * opening, z])
    return {
        "palm": [palm],
        "left": [left],
        "right": [right],
        "max_opening": opening,
        "palm_threshold": BREAKING_FACTOR * bullet_size([_piece(str(collision / "hand.obj"))]),
        "finger_threshold": BREAKING_FACTOR * bullet_size([finger]),
    }


def labeller(
    world: SimWorld,
    *,
    hand: Mapping[str, Any] | None = None,
    pregrasp_distance: float = PREGRASP_DISTANCE,
) -> GraspLabeller:
    """A labeller of ``world``'s scene as it is now (objects at their PyBullet poses).

    ``hand``: what :class:`heapgrasp.GraspLabeller` takes (convex parts, or a
    :class:`~heapgrasp.geometry.gripper.GripperGeometry` as a dict for its boxes);
    default :func:`panda_hand_parts`, the simulated hand. Object ids are the world's
    (:attr:`SimWorld.objects`). Friction is the world's object friction times
    :data:`~heapgrasp.sim.hand.FINGER_FRICTION`, as PyBullet combines them.
    """
    out = GraspLabeller(
        panda_hand_parts() if hand is None else hand,
        table_z=table_top(world),
        friction=world.config.friction * FINGER_FRICTION,
        pregrasp_distance=pregrasp_distance,
        hand_margin=CONVEX_MARGIN,
        object_margin=CONVEX_MARGIN,
        min_width=MIN_HELD_WIDTH,
        approach_lag=APPROACH_LAG,
    )
    for oid, obj in world.objects.items():
        pieces = [_piece(str(p)) for p in obj.model.collision_meshes]
        threshold = BREAKING_FACTOR * bullet_size(pieces)
        out.add_object(oid, world.object_pose(oid), pieces, threshold)
    return out


@dataclass(frozen=True)
class GraspSamples:
    """Grasps sampled VGN's way, grouped per surface point (``P`` points, ``Y`` yaws)."""

    points: F64
    """``(P, 3)`` surface points (world)."""
    normals: F64
    """``(P, 3)`` outward unit normals there (world)."""
    objects: npt.NDArray[np.int64]
    """``(P,)`` world id of the object each point lies on."""
    depths: F64
    """``(P,)`` grasp depth (m): how far the point lies in front of the palm's face."""
    yaws: F64
    """``(Y,)`` yaw angles (rad) about the grasp's z, evenly in ``[0, π)``."""
    poses: F64
    """``(P, Y, 4, 4)`` TCP poses ``tcp2world``."""

    def flat(self) -> F64:
        """``(P·Y, 4, 4)`` C-contiguous poses, point-major."""
        return np.ascontiguousarray(self.poses.reshape(-1, 4, 4))


def _frames(normals: F64) -> F64:
    """VGN's grasp frame per normal: z = -normal, x from world x (world y when z is
    along x), y = z × x. ``(P, 3, 3)`` rotations, columns x, y, z."""
    z = -normals
    helper = np.zeros_like(z)
    along_x = np.isclose(np.abs(z[:, 0]), 1.0, atol=1e-4)
    helper[~along_x, 0] = 1.0
    helper[along_x, 1] = 1.0
    y = np.cross(z, helper)
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=2)


def sample_grasps(
    world: SimWorld,
    rng: np.random.Generator,
    points: int = 120,
    yaws: int = 6,
    *,
    gripper: GripperGeometry = PANDA_HAND,
    objects: Collection[int] | None = None,
) -> GraspSamples:
    """VGN's grasps on ``world``'s objects (see the module docstring).

    Surface points are drawn area-weighted over the triangles of every object's visual
    mesh (or only of ``objects``, world ids) at its current pose whose outward normal has
    ``n_z >`` :data:`MIN_NORMAL_Z`. A world without objects gives ``P = 0``.
    """
    if points < 0 or yaws < 1:
        raise ValueError(f"points must be >= 0 and yaws >= 1, got {points} and {yaws}")
    tris, norms, areas, owners = [], [], [], []
    for oid, obj in world.objects.items():
        if objects is not None and oid not in objects:
            continue
        v, f = _surface(str(obj.model.visual_mesh))
        pose = world.object_pose(oid)
        w = v @ pose[:3, :3].T + pose[:3, 3]
        t = w[f]
        cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        double_area = np.linalg.norm(cross, axis=1)
        ok = double_area > 1e-12
        n = cross[ok] / double_area[ok, None]
        up = n[:, 2] > MIN_NORMAL_Z
        tris.append(t[ok][up])
        norms.append(n[up])
        areas.append(0.5 * double_area[ok][up])
        owners.append(np.full(int(up.sum()), oid, dtype=np.int64))
    yaw = np.pi * np.arange(yaws) / yaws
    area = np.concatenate(areas) if areas else np.zeros(0)
    if points == 0 or area.size == 0 or area.sum() <= 0:
        empty = np.zeros((0, 3))
        return GraspSamples(
            empty, empty, np.zeros(0, np.int64), np.zeros(0), yaw, np.zeros((0, yaws, 4, 4))
        )
    tri, normal, owner = np.concatenate(tris), np.concatenate(norms), np.concatenate(owners)
    pick = rng.choice(area.size, size=points, p=area / area.sum())
    r1, r2 = rng.random(points), rng.random(points)
    s = np.sqrt(r1)
    bary = np.stack([1.0 - s, s * (1.0 - r2), s * r2], axis=1)
    point = np.einsum("pk,pkj->pj", bary, tri[pick])
    return grasps_at(point, normal[pick], owner[pick], rng, yaws, gripper=gripper)


def grasps_at(
    points: F64,
    normals: F64,
    objects: npt.NDArray[np.int64],
    rng: np.random.Generator,
    yaws: int = 6,
    *,
    gripper: GripperGeometry = PANDA_HAND,
) -> GraspSamples:
    """VGN's grasps at given surface ``points`` ``(P, 3)`` with outward unit ``normals``
    ``(P, 3)`` (world; ``objects`` ``(P,)`` their object ids, −1 where unknown): a depth
    drawn per point from :data:`DEPTH_RANGE` × the finger depth, ``yaws`` yaws."""
    n_points = len(points)
    yaw = np.pi * np.arange(yaws) / yaws
    depth = rng.uniform(*DEPTH_RANGE, size=n_points) * gripper.finger_depth
    tcp = points + normals * (depth + gripper.palm_front)[:, None]
    base = _frames(normals)
    c, s_ = np.cos(yaw), np.sin(yaw)
    rz = np.zeros((yaws, 3, 3))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = c, -s_, s_, c, 1.0
    poses = np.zeros((n_points, yaws, 4, 4))
    poses[:, :, :3, :3] = np.einsum("pij,yjk->pyik", base, rz)
    poses[:, :, :3, 3] = tcp[:, None, :]
    poses[:, :, 3, 3] = 1.0
    return GraspSamples(points, normals, objects, depth, yaw, poses)


def best_yaw(
    success: npt.ArrayLike, width: npt.ArrayLike
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.uint8], npt.NDArray[np.float32]]:
    """VGN's reduction of the ``(P, Y)`` yaws tried at each point to one grasp.

    Where any yaw succeeds: the middle of the longest run of successful yaws (the yaws
    span ``[0, π)``, a full turn of a parallel-jaw grasp, so a run may wrap from the last
    yaw to the first; of equally long runs the one starting at the lowest yaw, of an
    even run the lower middle),
    label 1, its width. Else yaw 0, label 0 and its width (the widest opening).

    Returns ``(yaw_index (P,) int64, label (P,) uint8, width (P,) float32)``.
    """
    ok = np.asarray(success, dtype=bool)
    w = np.asarray(width, dtype=np.float32)
    if ok.ndim != 2 or w.shape != ok.shape:
        raise ValueError(
            f"success and width must be (P, Y) arrays of one shape, got {ok.shape} and {w.shape}"
        )
    n_points, n_yaws = ok.shape
    index = np.zeros(n_points, dtype=np.int64)
    for p in range(n_points):
        row = ok[p]
        if row.all():
            index[p] = (n_yaws - 1) // 2
            continue
        if not row.any():
            continue
        # Walk once round from a failing yaw, so that no run is cut by the wrap-around.
        start = int(np.argmin(row))
        best_len, best_first, run, run_first = 0, 0, 0, 0
        for step in range(1, n_yaws + 1):
            k = (start + step) % n_yaws
            if not row[k]:
                run = 0
                continue
            if run == 0:
                run_first = k
            run += 1
            if run > best_len or (run == best_len and run_first < best_first):
                best_len, best_first = run, run_first
        index[p] = (best_first + (best_len - 1) // 2) % n_yaws
    rows = np.arange(n_points)
    label = ok[rows, index].astype(np.uint8)
    return index, label, w[rows, index]


def label_scene(
    world: SimWorld,
    rng: np.random.Generator,
    *,
    points: int = 120,
    yaws: int = 6,
    threads: int = 0,
    gripper: GripperGeometry = PANDA_HAND,
) -> dict[str, Any]:
    """VGN's labelled grasps of ``world``'s scene, one per surface point.

    Samples :func:`sample_grasps`, labels every yaw with :func:`labeller` on ``threads``
    threads (0: all) and reduces each point with :func:`best_yaw`. Returns arrays over
    the ``P`` points: ``position`` ``(P, 3)`` float64 TCP (world), ``quat`` ``(P, 4)``
    float64 TCP orientation ``x, y, z, w``, ``pose`` ``(P, 4, 4)`` float64, ``width``
    ``(P,)`` float32 (the widest opening for a failure), ``label`` ``(P,)`` uint8,
    ``yaw_index`` ``(P,)`` int64, ``object`` ``(P,)`` int64 (the object the point lies
    on), ``held`` ``(P,)`` int32 (the object held, -1 for none), ``reason`` ``(P,)``
    uint8 (:data:`REASONS`).
    """
    samples = sample_grasps(world, rng, points, yaws, gripper=gripper)
    return label_samples(world, samples, threads=threads)


def label_samples(
    world: SimWorld,
    samples: GraspSamples,
    *,
    threads: int = 0,
    hand: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """``samples`` labelled on ``world`` and reduced to one grasp per point, as
    :func:`label_scene` returns them; ``hand`` as :func:`labeller` takes it (default:
    the simulated Panda hand's convex parts)."""
    from scipy.spatial.transform import Rotation

    yaws = len(samples.yaws)
    n = len(samples.points)
    ok, width, held, reason = labeller(world, hand=hand).label(samples.flat(), threads=threads)
    index, label, best_width = best_yaw(ok.reshape(n, yaws), width.reshape(n, yaws))
    rows = np.arange(n)
    pose = samples.poses[rows, index]
    flat = rows * yaws + index
    quat = Rotation.from_matrix(pose[:, :3, :3]).as_quat() if n else np.zeros((0, 4))
    return {
        "position": np.ascontiguousarray(pose[:, :3, 3]),
        "quat": np.asarray(quat, dtype=np.float64),
        "pose": pose,
        "width": best_width,
        "label": label,
        "yaw_index": index,
        "object": samples.objects,
        "held": held[flat],
        "reason": reason[flat],
    }
