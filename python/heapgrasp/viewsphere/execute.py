"""Executing a grasp Natarajan et al.'s synthesis found, with the simulated hand.

The paper counts a grasp *found* as success (§5.1). Here the grasp is also executed:
the object (its resting meshes turned by the pose's yaw) is placed on PyBullet's table,
the free-flying Panda hand (:class:`~heapgrasp.sim.gripper.PandaHand`) runs VGN's
protocol (:func:`~heapgrasp.sim.gripper.execute_grasp`: pre-grasp, approach, close,
lift, shake) at the found TCP pose, and the outcome is what happened: ``success`` (the
object held after lifting and shaking), ``collision``, ``empty`` or ``unreachable``.

The object collides as its meshes where they are convex and as their convex
decomposition elsewhere (``pybullet.vhacd``, cached by content); its collision and
visual files are written once per object, at rest, and turned at spawn.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt

from heapgrasp.sim.decomposition import decomposed as _decomposed
from heapgrasp.sim.mesh_files import is_convex as _is_convex
from heapgrasp.sim.mesh_files import mesh_extents as _extents
from heapgrasp.sim.mesh_files import mesh_volume as _mesh_volume
from heapgrasp.sim.mesh_files import obj_text as _obj_text
from heapgrasp.sim.mesh_files import round_vertices as _round
from heapgrasp.sim.mesh_files import write_if_changed as _write_if_changed
from heapgrasp.sim.object_model import MAX_COLLISION_PIECES, ObjectModel, default_cache_dir
from heapgrasp.sim.object_model import clamped_mass as _clamped_mass
from heapgrasp.viewsphere.grasps import FoundGrasp
from heapgrasp.viewsphere.objects import Mesh

__all__ = ["execute_found_grasp", "object_model"]

#: Lift before the object is let go on the table (m): no initial contact.
_DROP = 0.002


def object_model(name: str, meshes: Sequence[Mesh], cache_dir: Path | None = None) -> ObjectModel:
    """The object's files for PyBullet (in ``cache_dir/viewsphere/<hash>``, written once),
    in the frame of its bounding box's centre: one visual mesh of all parts, and a
    collision piece per convex part or per piece of a concave part's convex
    decomposition (at most ``MAX_COLLISION_PIECES``)."""
    cache = default_cache_dir() if cache_dir is None else cache_dir
    every = np.vstack([np.asarray(v, dtype=np.float64) for v, _ in meshes])
    box_centre = (every.min(axis=0) + every.max(axis=0)) / 2  # the model's frame
    parts = [
        (_round(np.asarray(v, dtype=np.float64) - box_centre), np.asarray(f, dtype=np.int64))
        for v, f in meshes
    ]
    h = hashlib.sha256(b"viewsphere-object-v1")
    for v, f in parts:
        h.update(_obj_text(v, f, "").encode("ascii"))
    folder = cache / "viewsphere" / h.hexdigest()[:24]
    offsets = np.cumsum([0] + [len(v) for v, _ in parts])[:-1]
    vertices = np.vstack([v for v, _ in parts])
    faces = np.vstack([f + o for (_, f), o in zip(parts, offsets, strict=True)])
    visual = folder / "visual.obj"
    _write_if_changed(visual, _obj_text(vertices, faces, f"heapgrasp viewsphere object {name}"))
    convex = [p for p in parts if _is_convex(*p)]
    concave = [p for p in parts if not _is_convex(*p)]
    collision: list[Path] = []
    for k, (v, f) in enumerate(convex):
        path = folder / f"collision_{k:02d}.obj"
        _write_if_changed(path, _obj_text(v, f, f"heapgrasp viewsphere object {name}, part {k}"))
        collision.append(path)
    if concave:
        room = max(1, MAX_COLLISION_PIECES - len(collision))
        collision += _decomposed(concave, room, cache / "convex", name)
    volume = sum(_mesh_volume(v, f) for v, f in parts)
    return ObjectModel(
        name=name,
        source="procedural",
        visual_mesh=visual,
        collision_meshes=tuple(collision[:MAX_COLLISION_PIECES]),
        mass=_clamped_mass(volume),
        split="test",
        extents=_extents(vertices),
    )


#: This process's object models by (name, digest of the meshes).
_MODELS: dict[tuple[str, bytes], ObjectModel] = {}


def _cached_model(name: str, meshes: Sequence[Mesh]) -> ObjectModel:
    key = hashlib.sha256(b"".join(np.ascontiguousarray(v).tobytes() for v, _ in meshes)).digest()
    if (name, key) not in _MODELS:
        if len(_MODELS) >= 8:
            _MODELS.clear()
        _MODELS[(name, key)] = object_model(name, meshes)
    return _MODELS[(name, key)]


def execute_found_grasp(name: str, meshes: Sequence[Mesh], yaw: float, grasp: FoundGrasp) -> str:
    """Executes ``grasp`` (the viewsphere's frame: the object's resting meshes turned by
    ``yaw`` radians about the vertical through the origin) with the simulated hand;
    returns the outcome's name (module doc)."""
    from heapgrasp.robot.grasping import Grasp
    from heapgrasp.sim.gripper import MAX_OPENING, PandaHand, execute_grasp
    from heapgrasp.sim.objects import ObjectLibrary
    from heapgrasp.sim.optics import Category
    from heapgrasp.sim.world import SimWorld, WorldConfig

    rest = tuple(
        (np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in meshes
    )
    model = _cached_model(name, rest)
    config = WorldConfig()
    with SimWorld(library=ObjectLibrary([]), config=config) as world:
        centre = config.cube_size / 2
        # The model's frame is its bounding box's centre; the viewsphere's frame has its
        # origin at the centre of the table under the object: here at the cube's centre.
        v = np.vstack([m[0] for m in rest])
        box_centre = (v.min(axis=0) + v.max(axis=0)) / 2
        shift = _translation([centre, centre, _DROP])
        obj2world = shift @ _pose(yaw, [0.0, 0.0, 0.0]) @ _translation(box_centre)
        world.spawn(model, obj2world, Category.OPAQUE)
        world.step_physics(int(0.3 / config.time_step))
        hand = PandaHand(world)
        tcp = shift @ np.asarray(grasp.pose, dtype=np.float64)
        result = execute_grasp(hand, Grasp(tcp, min(grasp.width, MAX_OPENING)))
    return str(result.outcome.value)


def _translation(t: npt.ArrayLike) -> npt.NDArray[np.float64]:
    out = np.eye(4)
    out[:3, 3] = np.asarray(t, dtype=np.float64)
    return out


def _pose(yaw: float, t: npt.ArrayLike) -> npt.NDArray[np.float64]:
    c, s = math.cos(yaw), math.sin(yaw)
    out = _translation(t)
    out[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    return out
