"""The simulator's scene truth (:class:`heapgrasp.robot.interfaces.SceneTruth`).

What a real robot never has: the true meshes at their poses (the oracle view scorer),
exact silhouettes (the ideal and noisy segmenters), the object a grasp took, what a
collision touched, and the objects left (the metrics and the protocol's "cleared").
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from heapgrasp import MeshScene
from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.perception.frames import Frame
from heapgrasp.robot.grasping import Grasp
from heapgrasp.robot.interfaces import Contact
from heapgrasp.sim.robot import Robot
from heapgrasp.sim.world import SimFrame, SimWorld

__all__ = ["SimTruth", "top_down_grasp", "touched_labels"]

#: How far below an object's top a top-down grasp places the TCP at most (m).
FINGER_DEPTH = 0.035

F64 = npt.NDArray[np.float64]


def touched_labels(world: SimWorld, bodies: Iterable[int], target: int | None) -> list[str]:
    """What a collision touched, by name: ``"table"``, ``"target"`` (the object the grasp
    was planned on), ``"object"`` (another object) or ``"other"``; sorted, without
    repeats."""
    by_body = {obj.body: oid for oid, obj in world.objects.items()}
    labels: set[str] = set()
    for body in bodies:
        if body == world.table:
            labels.add("table")
        elif body in by_body:
            labels.add("target" if by_body[body] == target else "object")
        else:
            labels.add("other")
    return sorted(labels)


class SimTruth:
    """Scene truth of a :class:`SimWorld` and the simulated robot in it."""

    def __init__(self, world: SimWorld, body: Robot | None = None) -> None:
        self.world = world
        self.body = body

    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The exact silhouette: the one rendered with a simulated frame, else rendered now
        from the frame's pose."""
        if isinstance(frame, SimFrame):
            return frame.mask
        self.world.sync()
        pose = np.ascontiguousarray(frame.cam2world, dtype=np.float64)
        labels = self.world.object_scene.render_labels(frame.camera.core(), pose)
        return np.asarray(labels > 0)

    def meshes(self) -> MeshScene:
        """The objects' meshes at their current poses."""
        return self.world.object_scene

    def objects_left(self) -> int:
        """Objects still in the world."""
        return len(self.world.objects)

    def object_near(self, point: F64, within: float = 0.03) -> int | None:
        """The object with a mesh vertex nearest ``point``, within ``within`` m."""
        best, best_d = None, within
        for oid in self.world.objects:
            pose = self.world.object_pose(oid)
            verts = self.world.object_vertices(oid) @ pose[:3, :3].T + pose[:3, 3]
            d = float(np.min(np.linalg.norm(verts - point, axis=1)))
            if d < best_d:
                best, best_d = oid, d
        return best

    def held_object(self) -> int | None:
        """The object between the fingers, if any."""
        return None if self.body is None else self.body.held_object()

    def category(self, object_id: int | None) -> str | None:
        """The object's category, None where it is not in the world."""
        if object_id is None or object_id not in self.world.objects:
            return None
        return self.world.objects[object_id].category.value

    def touched(self, contact: Contact, target: int | None) -> list[str]:
        """:func:`touched_labels` of a contact."""
        return touched_labels(self.world, contact.bodies, target)

    def placed(self, object_id: int) -> None:
        """Removes a released object from the world."""
        if object_id in self.world.objects:
            self.world.remove(object_id)

    def settle(self) -> dict[int, str | None]:
        """:meth:`SimWorld.settle`: the objects knocked out of the scene cube, by id."""
        return {obj.id: obj.category.value for obj in self.world.settle()}


def top_down_grasp(world: SimWorld, object_id: int, width: float = PANDA_HAND.max_opening) -> Grasp:
    """A top-down grasp of an upright object from its true pose (a ground-truth baseline
    for tests and benchmarks, not a perception-based planner): TCP at the object's
    origin (raised so the fingers reach at most ``FINGER_DEPTH`` below its top), fingers
    closing along its x or y axis: among the axes along which the object
    is narrower than the opening, the one that keeps the fingers farther from the other
    objects."""
    pose = world.object_pose(object_id)
    extents = world.objects[object_id].model.extents
    others = [world.object_pose(o)[:3, 3] for o in world.objects if o != object_id]

    def clearance(yaw: float) -> float:
        y_axis = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        fingers = [pose[:3, 3] + s * 0.05 * y_axis for s in (-1.0, 1.0)]
        return float(min((np.linalg.norm(f - o) for f in fingers for o in others), default=1.0))

    # Fingers close along the TCP's y axis: object y at yaw = base, object x at base + 90°.
    base = float(np.arctan2(pose[1, 0], pose[0, 0]))
    options = [
        yaw for yaw, ext in ((base, extents[1]), (base + np.pi / 2, extents[0])) if ext < width
    ]
    yaw = max(options or [base], key=clearance)
    c, s = np.cos(yaw), np.sin(yaw)
    tcp = np.eye(4)
    tcp[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.diag(
        [1.0, -1.0, -1.0]
    )
    # No deeper than the fingers reach: the palm is ~4.7 cm above the TCP.
    top = pose[2, 3] + 0.5 * extents[2]
    tcp[:3, 3] = (pose[0, 3], pose[1, 3], max(pose[2, 3], top - FINGER_DEPTH))
    return Grasp(tcp, width)
