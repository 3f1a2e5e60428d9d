"""Stand-ins for Natarajan et al.'s objects: the 12 YCB test objects and the training shapes.

The YCB meshes of seed ``001_95c7dd5c6a7c3646.txt`` cannot be downloaded here, so each
test object is a procedural stand-in of its published size, built from closed meshes
(:mod:`trimesh.creation`) and already in the resting pose the protocol gives it
(:data:`~heapgrasp.viewsphere.protocol.REST_POSES`: the drill lies on its side, the
pudding box stands on its end), its lowest point on the table (``z = 0``) and centred on
the vertical axis. The drill and the toy airplane part are plausible composites of boxes and
cylinders. The training objects of §4.3 are the three prisms, a handle, a gasket and a
cinder block. Real meshes come in through ``--object-dir`` (:func:`user_objects`);
nothing here is tuned to.

A benchmark object (:class:`ViewsphereObject`) is its meshes at rest and the range of
yaws its poses take (:func:`~heapgrasp.viewsphere.protocol.protocol_yaws`);
:meth:`ViewsphereObject.posed` turns it by one of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh
from trimesh import creation

from heapgrasp.sim.mesh_files import load_mesh
from heapgrasp.sim.objects import user_models
from heapgrasp.sim.procedural import revolve as _revolve
from heapgrasp.viewsphere.protocol import REST_POSES

__all__ = [
    "TEST_OBJECTS",
    "TRAIN_OBJECTS",
    "Mesh",
    "ViewsphereObject",
    "stand_in",
    "stand_ins",
    "user_objects",
]

Mesh = tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]

_SECTIONS = 48


def _quarter_turn(axis: str) -> npt.NDArray[np.float64]:
    """A 4 × 4 rotation by 90° about world ``axis`` ("x" or "y")."""
    m = np.eye(4)
    if axis == "x":
        m[1:3, 1:3] = [[0.0, -1.0], [1.0, 0.0]]
    else:
        m[0, 0], m[0, 2], m[2, 0], m[2, 2] = 0.0, 1.0, -1.0, 0.0
    return m


def _box(
    x: float, y: float, z: float, at: tuple[float, float, float] = (0, 0, 0)
) -> trimesh.Trimesh:
    m: trimesh.Trimesh = creation.box(extents=(x, y, z))
    m.apply_translation(at)
    return m


def _cylinder(
    diameter: float, length: float, axis: str = "z", at: tuple[float, float, float] = (0, 0, 0)
) -> trimesh.Trimesh:
    m: trimesh.Trimesh = creation.cylinder(radius=diameter / 2, height=length, sections=_SECTIONS)
    if axis == "x":  # z onto x: a quarter turn about y
        m.apply_transform(_quarter_turn("y"))
    elif axis == "y":
        m.apply_transform(_quarter_turn("x"))
    m.apply_translation(at)
    return m


def _sphere(diameter: float) -> trimesh.Trimesh:
    m: trimesh.Trimesh = creation.icosphere(subdivisions=3, radius=diameter / 2)
    return m


def _revolved(profile: list[tuple[float, float]]) -> trimesh.Trimesh:
    """A closed solid of revolution about z from an ``(r, z)`` outline that starts and
    ends on the axis (:func:`heapgrasp.sim.procedural.revolve` turns its profiles the same way)."""
    return _revolve(np.asarray(profile, dtype=np.float64))


def _bowl() -> list[trimesh.Trimesh]:
    r, h, wall = 0.159 / 2, 0.053, 0.004
    base = 0.03
    outline = [
        (0.0, 0.0),
        (base, 0.0),
        (r, h),
        (r - wall, h),
        (base - wall, wall),
        (0.0, wall),
    ]
    return [_revolved(outline)]


def _mug() -> list[trimesh.Trimesh]:
    r, h, wall = 0.040, 0.082, 0.004
    body = _revolved([(0.0, 0.0), (r, 0.0), (r, h), (r - wall, h), (r - wall, wall), (0, wall)])
    handle: trimesh.Trimesh = creation.torus(
        major_radius=0.025, minor_radius=0.006, major_sections=32
    )
    handle.apply_transform(_quarter_turn("x"))  # in the x-z plane
    handle.apply_translation((r + 0.012, 0.0, h / 2))
    return [body, handle]


def _drill() -> list[trimesh.Trimesh]:
    # Lying on its side: the body along x, the grip and the battery pack along -y.
    body = _cylinder(0.05, 0.18, "x", (0.0, 0.0, 0.0))
    grip = _box(0.035, 0.11, 0.045, (0.02, -0.08, 0.0))
    battery = _box(0.075, 0.05, 0.057, (0.02, -0.155, 0.0))
    return [body, grip, battery]


def _airplane() -> list[trimesh.Trimesh]:
    fuselage = _cylinder(0.045, 0.17, "x", (0.0, 0.0, 0.0))
    wing = _box(0.05, 0.16, 0.012, (0.01, 0.0, -0.01))
    tail = _box(0.03, 0.012, 0.05, (-0.07, 0.0, 0.03))
    return [fuselage, wing, tail]


def _handle() -> list[trimesh.Trimesh]:
    grip = _cylinder(0.025, 0.12, "x", (0.0, 0.0, 0.05))
    legs = [_box(0.02, 0.02, 0.05, (s * 0.05, 0.0, 0.025)) for s in (-1, 1)]
    return [grip, *legs]


def _gasket() -> list[trimesh.Trimesh]:
    return [creation.torus(major_radius=0.04, minor_radius=0.008, major_sections=48)]


def _cinder_block() -> list[trimesh.Trimesh]:
    # 20 × 10 × 10 cm with two square cores: walls as boxes.
    x, y, z, wall = 0.20, 0.10, 0.10, 0.02
    return [
        _box(x, wall, z, (0.0, (y - wall) / 2, 0.0)),
        _box(x, wall, z, (0.0, -(y - wall) / 2, 0.0)),
        *(
            _box(wall, y - 2 * wall, z, (cx, 0.0, 0.0))
            for cx in (-(x - wall) / 2, 0.0, (x - wall) / 2)
        ),
    ]


#: The 12 test objects (YCB ids), in their resting poses.
TEST_OBJECTS: dict[str, Callable[[], list[trimesh.Trimesh]]] = {
    "003_cracker_box": lambda: [_box(0.06, 0.158, 0.21)],
    "005_tomato_soup_can": lambda: [_cylinder(0.066, 0.101)],
    "006_mustard_bottle": lambda: [_box(0.05, 0.085, 0.175)],
    # Standing on its 35 × 89 mm end: the protocol puts its origin 0.06 m above the
    # table, about half its 110 mm length (as the cracker box's 0.106 m is half its
    # 210 mm height); lying on its 110 × 89 mm face it could not be grasped at all.
    "008_pudding_box": lambda: [_box(0.035, 0.089, 0.11)],
    "010_potted_meat_can": lambda: [_box(0.05, 0.097, 0.082)],
    "013_apple": lambda: [_sphere(0.075)],
    "021_bleach_cleanser": lambda: [_box(0.098, 0.065, 0.25)],
    "024_bowl": _bowl,
    "025_mug": _mug,
    "035_power_drill": _drill,
    "055_baseball": lambda: [_sphere(0.075)],
    "072-a_toy_airplane": _airplane,
}

#: The training objects of Natarajan et al. §4.3.
TRAIN_OBJECTS: dict[str, Callable[[], list[trimesh.Trimesh]]] = {
    "prism_6x6x6": lambda: [_box(0.06, 0.06, 0.06)],
    "prism_10x8x4": lambda: [_box(0.10, 0.08, 0.04)],
    "prism_20x6x5": lambda: [_box(0.20, 0.06, 0.05)],
    "handle": _handle,
    "gasket": _gasket,
    "cinder_block": _cinder_block,
}


def stand_in(name: str) -> list[Mesh]:
    """The meshes of object ``name`` (a key of :data:`TEST_OBJECTS` or
    :data:`TRAIN_OBJECTS`), resting on the table at ``z = 0`` and centred on the z
    axis; ValueError naming the known objects otherwise."""
    make = TEST_OBJECTS.get(name) or TRAIN_OBJECTS.get(name)
    if make is None:
        known = ", ".join([*TEST_OBJECTS, *TRAIN_OBJECTS])
        raise ValueError(f"unknown object {name!r}; known: {known}")
    parts = make()
    lo = np.min([p.bounds[0] for p in parts], axis=0)
    hi = np.max([p.bounds[1] for p in parts], axis=0)
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return [
        (np.asarray(p.vertices, dtype=np.float64) + shift, np.asarray(p.faces, dtype=np.int64))
        for p in parts
    ]


@dataclass(frozen=True)
class ViewsphereObject:
    """One benchmark object: its meshes resting on the table (``z = 0``) centred on the
    vertical axis, the range of its yaws (89, 179 or 359 degrees) and where it came
    from (``"stand-in"`` or the user's folder)."""

    name: str
    meshes: tuple[Mesh, ...]
    yaw_range: int
    source: str

    def posed(self, yaw: float) -> list[Mesh]:
        """The meshes turned by ``yaw`` (radians) about the vertical axis."""
        c, s = math.cos(yaw), math.sin(yaw)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return [(v @ turn.T, f) for v, f in self.meshes]

    def check_size(self, half_xy: float, height: float) -> None:
        """ValueError naming the object when, at some yaw, it leaves the box where the
        benchmark looks for the object's points (± ``half_xy`` around the centre, up to
        ``height``)."""
        v = np.vstack([m[0] for m in self.meshes])
        reach = float(np.hypot(v[:, 0], v[:, 1]).max())
        top = float(v[:, 2].max())
        if reach > half_xy or top > height:
            raise ValueError(
                f"object {self.name!r} reaches {reach:.3f} m from the centre and "
                f"{top:.3f} m high at rest; the workspace holds ±{half_xy:g} m and "
                f"{height:g} m (is the mesh in millimetres? give its <mesh> elements "
                'scale="0.001 0.001 0.001")'
                if max(reach, top) > 1.0
                else f"object {self.name!r} reaches {reach:.3f} m from the centre and "
                f"{top:.3f} m high at rest, larger than the workspace (±{half_xy:g} m, "
                f"{height:g} m high)"
            )


def _at_rest(meshes: Sequence[Mesh]) -> tuple[Mesh, ...]:
    """The meshes shifted so their lowest point is at ``z = 0`` and their bounding box
    is centred on the vertical axis."""
    v = np.vstack([m[0] for m in meshes])
    lo, hi = v.min(axis=0), v.max(axis=0)
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    return tuple((np.asarray(m[0], dtype=np.float64) + shift, m[1]) for m in meshes)


def stand_ins(names: Sequence[str] | None = None) -> list[ViewsphereObject]:
    """The stand-ins named (default: the 12 test objects), each with its protocol's yaw
    range (the training shapes: 0–359°)."""
    chosen = list(TEST_OBJECTS) if names is None else list(names)
    out = []
    for name in chosen:
        meshes = tuple(stand_in(name))
        rest = REST_POSES.get(name)
        out.append(
            ViewsphereObject(name, meshes, 359 if rest is None else rest.yaw_range, "stand-in")
        )
    return out


def _rotation(roll: float, pitch: float) -> npt.NDArray[np.float64]:
    """``R_y(pitch) R_x(roll)``: PyBullet's Euler order with no yaw."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    out: npt.NDArray[np.float64] = ry @ rx
    return out


def _stable(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.int64]
) -> npt.NDArray[np.float64]:
    """The rotation of the mesh's most probable resting pose (trimesh's quasi-static
    estimate on its convex hull)."""
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    transforms, _ = trimesh.poses.compute_stable_poses(mesh)
    if len(transforms) == 0:
        return np.eye(3)
    out: npt.NDArray[np.float64] = np.asarray(transforms[0], dtype=np.float64)[:3, :3]
    return out


def user_objects(
    directory: Path | str,
    cache_dir: Path | str,
    *,
    on_bad: Callable[[str, str], None],
) -> list[ViewsphereObject]:
    """The user's objects (:func:`heapgrasp.sim.objects.user_models`: a folder per
    object with its ``model.urdf``, or mesh files) at rest: an object named like a
    protocol object (e.g. ``003_cracker_box``) takes the protocol's roll, pitch and yaw
    range (:data:`~heapgrasp.viewsphere.protocol.REST_POSES`); any other rests in
    its most stable pose, with yaws over 0–359°. Each object that cannot be used is
    reported to ``on_bad(name, problem)`` and left out."""
    models = user_models(
        directory,
        cache_dir,
        test_fraction=1.0,
        on_bad=lambda name, problem: on_bad(name.split("/", 1)[-1], problem),
    )
    out = []
    for model in models:
        stem = model.name.split("/", 1)[-1]
        try:
            v, f = load_mesh(model.visual_mesh)
            rest = REST_POSES.get(stem)
            turn = _stable(v, f) if rest is None else _rotation(rest.roll, rest.pitch)
            meshes = _at_rest(
                [(np.asarray(v, dtype=np.float64) @ turn.T, np.asarray(f, dtype=np.int64))]
            )
        except (ValueError, OSError) as exc:
            on_bad(stem, str(exc))
            continue
        out.append(
            ViewsphereObject(stem, meshes, 359 if rest is None else rest.yaw_range, str(directory))
        )
    return out
