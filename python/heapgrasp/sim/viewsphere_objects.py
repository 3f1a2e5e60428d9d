"""Stand-ins for seed 001's objects: the 12 YCB test objects and the training shapes.

The YCB meshes of seed ``001_95c7dd5c6a7c3646.txt`` cannot be downloaded here, so each
test object is a procedural stand-in of its published size, built from closed meshes
(:mod:`trimesh.creation`) and already in the resting pose the protocol gives it
(:data:`~heapgrasp.sim.viewsphere_protocol.REST_POSES`: the pudding box and the drill lie
on their sides), its lowest point on the table (``z = 0``) and centred on the vertical
axis. The drill and the toy airplane part are plausible composites of boxes and
cylinders. The training objects of §4.3 are the three prisms, a handle, a gasket and a
cinder block. Real meshes come in through ``--object-dir``; nothing here is tuned to.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import trimesh
from trimesh import creation

from heapgrasp.sim.objects import _revolve

__all__ = ["TEST_OBJECTS", "TRAIN_OBJECTS", "Mesh", "stand_in"]

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
    ends on the axis (:func:`heapgrasp.sim.objects` revolves its profiles the same way)."""
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
    "008_pudding_box": lambda: [_box(0.11, 0.089, 0.035)],
    "010_potted_meat_can": lambda: [_box(0.05, 0.097, 0.082)],
    "013_apple": lambda: [_sphere(0.075)],
    "021_bleach_cleanser": lambda: [_box(0.098, 0.065, 0.25)],
    "024_bowl": _bowl,
    "025_mug": _mug,
    "035_power_drill": _drill,
    "055_baseball": lambda: [_sphere(0.075)],
    "072-a_toy_airplane": _airplane,
}

#: The training objects of seed 001 §4.3.
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
