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
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh
from scipy.spatial import ConvexHull
from trimesh import creation

from heapgrasp.sim.mesh_files import load_mesh
from heapgrasp.sim.objects import user_models
from heapgrasp.sim.procedural import revolve as _revolve
from heapgrasp.viewsphere.protocol import REST_POSES

__all__ = [
    "HEIGHT_TOLERANCE",
    "OUTLINE_TOLERANCE",
    "PREFER_GIVEN",
    "REST_TOLERANCE_DEG",
    "TEST_OBJECTS",
    "TRAIN_OBJECTS",
    "Mesh",
    "Placement",
    "ViewsphereObject",
    "placement",
    "protocol_name",
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
    vertical axis, the range of its yaws (89, 179 or 359 degrees), where it came
    from (``"stand-in"`` or the user's folder), the protocol object it is (a key of
    :data:`REST_POSES`, None for others), how it was made to rest (``placement``) and
    whether that is the protocol's resting pose (``exact``)."""

    name: str
    meshes: tuple[Mesh, ...]
    yaw_range: int
    source: str
    protocol: str | None = None
    placement: str = "the stand-in's resting pose"
    exact: bool = True

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
            ViewsphereObject(
                name,
                meshes,
                359 if rest is None else rest.yaw_range,
                "stand-in",
                protocol=name if rest is not None else None,
            )
        )
    return out


def _rotation(roll: float, pitch: float) -> npt.NDArray[np.float64]:
    """``R_y(pitch) R_x(roll)``: PyBullet's Euler order with no yaw."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    out: npt.NDArray[np.float64] = ry @ rx
    return out


#: How far (degrees) a pose's downward direction may be from one of the mesh's stable
#: poses' for the object to rest in that pose.
REST_TOLERANCE_DEG = 10.0
#: How far an object's height at rest may be from its stand-in's (the published size in
#: the protocol's pose) for the two poses to be the same: this fraction of the
#: stand-in's height, and at least 5 mm (the pudding box's 89 and 110 mm sides differ
#: by 19 %).
HEIGHT_TOLERANCE = 0.1
#: How far the area of an object's outline seen from above (its convex hull's) may be
#: from its stand-in's, as a fraction: a mug upright or on its side is 82 or 80 mm tall,
#: and its outline differs by 70 %.
OUTLINE_TOLERANCE = 0.35
#: The protocol's roll and pitch are kept when they fit within this much of the best
#: stable pose's mismatch (relative height error plus relative outline error).
PREFER_GIVEN = 0.05


def protocol_name(stem: str) -> str | None:
    """The protocol object (a key of :data:`REST_POSES`) that a user's object is named
    after, however the common downloads spell it: YCB's id (``003_cracker_box``),
    pybullet-object-models' (``YcbCrackerBox``), a ``ycb_`` prefix or the bare name
    (``cracker_box``, ``CrackerBox``); None for any other name."""
    key = _name_key(stem)
    return next((name for name in REST_POSES if _name_key(name) == key), None)


def _name_key(name: str) -> str:
    s = re.sub(r"^ycb[_-]?", "", name.lower())
    s = re.sub(r"^\d+(-[a-z])?[_-]", "", s)
    return re.sub(r"[^a-z0-9]", "", s)


@dataclass(frozen=True)
class Placement:
    """How a user's mesh is turned to rest on the table: the ``rotation`` (applied to
    the mesh's vertices), what it is (``note``) and whether it is the protocol's resting
    pose (``exact``; False when the protocol object's pose could not be found among the
    mesh's stable poses, or the object is not a protocol object)."""

    rotation: npt.NDArray[np.float64]
    note: str
    exact: bool


def _stable_rotations(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.int64]
) -> list[npt.NDArray[np.float64]]:
    """The rotations of the mesh's stable poses, most probable first (trimesh's
    quasi-static estimate on its convex hull, about the mesh's centre of mass, or its
    hull's when the mesh is not closed)."""
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    # A scan that is not closed has no volume to weigh: its hull's centre stands in.
    closed = mesh.is_watertight and mesh.volume > 0
    centre = mesh.center_mass if closed else mesh.convex_hull.center_mass
    transforms, _ = trimesh.poses.compute_stable_poses(mesh, center_mass=centre)
    return [np.asarray(t, dtype=np.float64)[:3, :3] for t in transforms]


def _height(vertices: npt.NDArray[np.float64], rotation: npt.NDArray[np.float64]) -> float:
    return float(np.ptp(vertices @ rotation[2]))


def _outline(vertices: npt.NDArray[np.float64], rotation: npt.NDArray[np.float64]) -> float:
    """The area (m²) of the mesh's convex outline seen from above once turned."""
    xy = vertices @ rotation[:2].T
    return float(ConvexHull(xy).volume)


def _rests(rotation: npt.NDArray[np.float64], stable: Sequence[npt.NDArray[np.float64]]) -> bool:
    """Whether turning the mesh by ``rotation`` puts it on one of its stable poses: the
    mesh's downward direction within :data:`REST_TOLERANCE_DEG` of one of theirs."""
    cos_tol = math.cos(math.radians(REST_TOLERANCE_DEG))
    return any(float(rotation[2] @ r[2]) >= cos_tol for r in stable)


def placement(
    vertices: npt.NDArray[np.float64], faces: npt.NDArray[np.int64], protocol: str | None
) -> Placement:
    """How to rest a user's mesh for the benchmark, whatever its frame convention.

    A mesh that is not a protocol object (``protocol`` None) rests in its most stable
    pose. A protocol object rests as its stand-in does (the published size in the
    protocol's pose): of the poses it can rest in, those whose height and outline seen
    from above match the stand-in's (:data:`HEIGHT_TOLERANCE`,
    :data:`OUTLINE_TOLERANCE`), it takes the protocol's roll and pitch
    (:data:`REST_POSES`, published for YCB's frames) when they are one of them and fit
    within :data:`PREFER_GIVEN` of the best, else the best: the mesh is then in another
    frame (Y up, BOP's, a re-oriented copy). When none matches, it rests in its most
    stable pose and the note says it is not the protocol's.
    """
    v = np.asarray(vertices, dtype=np.float64)
    stable = _stable_rotations(v, np.asarray(faces, dtype=np.int64))
    if protocol is None:
        if not stable:
            return Placement(np.eye(3), "as given (no stable pose found)", False)
        return Placement(stable[0], "its most stable pose", False)
    rest = REST_POSES[protocol]
    ref_v = np.vstack([m[0] for m in stand_in(protocol)])
    h_ref, a_ref = _height(ref_v, np.eye(3)), _outline(ref_v, np.eye(3))

    def mismatch(r: npt.NDArray[np.float64]) -> float | None:
        h, a = _height(v, r), _outline(v, r)
        if abs(h - h_ref) > max(HEIGHT_TOLERANCE * h_ref, 0.005):
            return None
        if abs(a - a_ref) > OUTLINE_TOLERANCE * a_ref:
            return None
        return abs(h - h_ref) / h_ref + abs(a - a_ref) / a_ref

    given = _rotation(rest.roll, rest.pitch)
    fits = [(m, i) for i, r in enumerate(stable) if (m := mismatch(r)) is not None]
    best = min(fits)[0] if fits else math.inf
    m_given = mismatch(given) if not stable or _rests(given, stable) else None
    size = f"{_height(v, given):.3f} m tall"
    if m_given is not None and m_given <= best + PREFER_GIVEN:
        return Placement(
            given,
            f"the protocol's roll and pitch for {protocol} ({size}, published {h_ref:.3f} m)",
            True,
        )
    if fits:
        chosen = stable[min(fits)[1]]
        why = size if not stable or _rests(given, stable) else "not resting on the table"
        return Placement(
            chosen,
            f"its stable pose {_height(v, chosen):.3f} m tall, as {protocol} rests "
            f"(published {h_ref:.3f} m); the protocol's roll and pitch ({why}) do not "
            "fit this mesh's frame",
            True,
        )
    heights = sorted({round(_height(v, r), 3) for r in stable})
    return Placement(
        stable[0] if stable else given,
        f"cannot rest it as {protocol} rests ({h_ref:.3f} m tall): its stable poses stand "
        f"{', '.join(f'{h:.3f}' for h in heights[:8])} m tall; it rests in its most "
        "stable pose instead",
        False,
    )


def user_objects(
    directory: Path | str,
    cache_dir: Path | str,
    *,
    on_bad: Callable[[str, str], None],
) -> list[ViewsphereObject]:
    """The user's objects (:func:`heapgrasp.sim.objects.user_models`: a folder per
    object with its ``model.urdf`` or a download's mesh such as
    ``google_16k/textured.obj``, or mesh files) at rest (:func:`placement`): an object
    named like a protocol object (:func:`protocol_name`: ``003_cracker_box``,
    ``YcbCrackerBox``, ...) takes the protocol's resting pose and yaw range
    (:data:`~heapgrasp.viewsphere.protocol.REST_POSES`) whatever its mesh's frame; any
    other rests in its most stable pose, with yaws over 0–359°. Each object that cannot
    be used is reported to ``on_bad(name, problem)`` and left out."""
    models = user_models(
        directory,
        cache_dir,
        test_fraction=1.0,
        on_bad=lambda name, problem: on_bad(name.split("/", 1)[-1], problem),
    )
    out = []
    for model in models:
        stem = model.name.split("/", 1)[-1]
        protocol = protocol_name(stem)
        try:
            v, f = load_mesh(model.visual_mesh)
            placed = placement(v, f, protocol)
            meshes = _at_rest(
                [
                    (
                        np.asarray(v, dtype=np.float64) @ placed.rotation.T,
                        np.asarray(f, dtype=np.int64),
                    )
                ]
            )
        except (ValueError, OSError) as exc:
            on_bad(stem, str(exc))
            continue
        rest = None if protocol is None else REST_POSES[protocol]
        out.append(
            ViewsphereObject(
                stem,
                meshes,
                359 if rest is None else rest.yaw_range,
                str(directory),
                protocol=protocol,
                placement=placed.note,
                exact=placed.exact,
            )
        )
    return out
