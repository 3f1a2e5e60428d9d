"""URDF objects: the first link with a mesh visual of a URDF file, read (visual mesh,
collision meshes, mass) and baked into an :class:`~heapgrasp.sim.object_model.ObjectModel`
(scale and ``<origin>`` applied, recentred to the bounding-box centre, concave collision
meshes decomposed where asked).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from heapgrasp.sim.decomposition import decomposed
from heapgrasp.sim.mesh_files import (
    bbox_centre,
    is_convex,
    load_mesh,
    load_parts,
    mesh_extents,
    mesh_volume,
    obj_text,
    round_vertices,
    write_if_changed,
)
from heapgrasp.sim.object_model import (
    MAX_COLLISION_PIECES,
    ObjectModel,
    Source,
    clamped_mass,
    split_of,
)

__all__ = [
    "MeshRef",
    "UrdfLink",
    "model_from_link",
    "model_from_urdf",
    "parse_urdf",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True)
class MeshRef:
    """A ``<mesh>`` of a URDF: its file, ``scale`` and ``<origin>`` (xyz, rpy)."""

    path: Path
    scale: tuple[float, float, float]
    origin: tuple[float, ...]  # xyz + rpy


@dataclass(frozen=True)
class UrdfLink:
    """What an object is made from: a link's visual mesh, its collision meshes and mass."""

    visual: MeshRef
    collisions: tuple[MeshRef, ...]
    mass: float | None


def _floats(text: str | None, n: int, default: float, what: str) -> tuple[float, ...]:
    if text is None or not text.strip():
        return (default,) * n
    parts = text.split()
    if len(parts) == 1 and n > 1:
        parts = parts * n
    try:
        values = tuple(float(p) for p in parts)
    except ValueError as exc:
        raise ValueError(f"{what}: expected {n} numbers, got {text!r}") from exc
    if len(values) != n or not all(math.isfinite(x) for x in values):
        raise ValueError(f"{what}: expected {n} finite numbers, got {text!r}")
    return values


def _mesh_ref(element: ET.Element, urdf: Path, what: str) -> MeshRef | None:
    mesh = element.find("geometry/mesh")
    if mesh is None:
        return None
    filename = mesh.get("filename")
    if not filename:
        raise ValueError(f"{urdf}: {what} <mesh> has no filename")
    if filename.startswith("package://"):
        filename = filename[len("package://") :].split("/", 1)[-1]
    elif filename.startswith("file://"):
        filename = filename[len("file://") :]
    path = Path(filename)
    if not path.is_absolute():
        path = urdf.parent / path
    if not path.exists() and (urdf.parent / path.name).is_file():
        path = urdf.parent / path.name  # a package:// path to a mesh beside the URDF
    scale = _floats(mesh.get("scale"), 3, 1.0, f"{urdf}: {what} mesh scale")
    if any(s == 0.0 for s in scale):
        raise ValueError(f"{urdf}: {what} mesh scale must be non-zero, got {scale}")
    origin_el = element.find("origin")
    xyz = _floats(
        None if origin_el is None else origin_el.get("xyz"), 3, 0.0, f"{urdf}: {what} xyz"
    )
    rpy = _floats(
        None if origin_el is None else origin_el.get("rpy"), 3, 0.0, f"{urdf}: {what} rpy"
    )
    return MeshRef(path, (scale[0], scale[1], scale[2]), (*xyz, *rpy))


def parse_urdf(urdf: Path) -> UrdfLink:
    """First link with a mesh visual of a URDF: visual mesh, mesh collisions, mass."""
    if not urdf.is_file():
        raise FileNotFoundError(f"URDF not found: {urdf}")
    try:
        root = ET.parse(urdf).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"cannot parse URDF {urdf}: {exc}") from exc
    for link in root.iter("link"):
        visual = None
        for element in link.findall("visual"):
            visual = _mesh_ref(element, urdf, "visual")
            if visual is not None:
                break
        if visual is None:
            continue
        collisions = tuple(
            ref
            for element in link.findall("collision")
            if (ref := _mesh_ref(element, urdf, "collision")) is not None
        )
        mass_el = link.find("inertial/mass")
        mass = None
        if mass_el is not None:
            mass = _floats(mass_el.get("value"), 1, 0.0, f"{urdf}: mass")[0]
            if mass <= 0.0:
                mass = None
        return UrdfLink(visual, collisions, mass)
    raise ValueError(
        f"URDF {urdf} has no link with a <visual> mesh (<geometry><mesh filename=...>; "
        "primitive shapes are not read)"
    )


def _origin_matrix(origin: tuple[float, ...]) -> FloatArray:
    x, y, z, roll, pitch, yaw = origin
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]], dtype=np.float64)
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]], dtype=np.float64)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]], dtype=np.float64)
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx  # URDF: fixed-axis roll, pitch, yaw
    m[:3, 3] = (x, y, z)
    return m


def _placed(
    ref: MeshRef, extra_scale: float, v: FloatArray, f: IntArray
) -> tuple[FloatArray, IntArray]:
    """A mesh of ``ref``'s file in the link frame (scale and origin applied)."""
    scale = np.asarray(ref.scale, dtype=np.float64) * extra_scale
    m = _origin_matrix(ref.origin)
    v = (v * scale) @ m[:3, :3].T + m[:3, 3]
    if np.prod(scale) < 0:  # mirrored: keep outward orientation
        f = f[:, ::-1].copy()
    return v, f


def _baked(ref: MeshRef, extra_scale: float) -> tuple[FloatArray, IntArray]:
    """Mesh of a URDF reference in the link frame (scale and origin applied)."""
    return _placed(ref, extra_scale, *load_mesh(ref.path))


def _baked_parts(ref: MeshRef, extra_scale: float) -> list[tuple[FloatArray, IntArray]]:
    """:func:`_baked`, one mesh per part of the file (:func:`load_parts`)."""
    return [_placed(ref, extra_scale, v, f) for v, f in load_parts(ref.path)]


def model_from_urdf(
    urdf: Path,
    name: str,
    source: Source,
    visual_path: Path,
    collision_prefix: Path,
    test_fraction: float,
) -> ObjectModel:
    link = parse_urdf(urdf)
    return model_from_link(
        link, urdf.name, name, source, visual_path, collision_prefix, test_fraction
    )


def model_from_link(
    link: UrdfLink,
    origin: str,
    name: str,
    source: Source,
    visual_path: Path,
    collision_prefix: Path,
    test_fraction: float,
    extra_scale: float = 1.0,
    convex_cache: Path | None = None,
    max_extent: float | None = None,
) -> ObjectModel:
    """The model of a link: its visual mesh recentred into ``visual_path`` and its
    collision meshes (the visual mesh when it has none) baked into
    ``collision_prefix<k>.obj``. With ``convex_cache``, each collision mesh is split into
    the parts of its file (an OBJ file that is already a set of convex objects) and a
    concave one is replaced by its convex decomposition (:func:`decomposed`, cached
    there); without, each collides as a whole (PyBullet takes its convex hull). An
    object larger than ``max_extent`` (m) raises ValueError, before any decomposition."""
    v, f = _baked(link.visual, extra_scale)
    why = None if max_extent is None else _too_large(mesh_extents(v), max_extent)
    if why is not None:
        raise ValueError(f"{name} {why}")
    centre = bbox_centre(v)
    v = round_vertices(v - centre)
    write_if_changed(visual_path, obj_text(v, f, f"heapgrasp {name} visual (from {origin})"))
    decompose = convex_cache is not None
    collision: list[Path] = []
    concave: list[tuple[FloatArray, IntArray]] = []
    k = 0
    for ref in link.collisions or (link.visual,):
        if ref == link.visual and (not decompose or is_convex(v, f)):
            if visual_path not in collision:
                collision.append(visual_path)
            continue
        for cv, cf in _baked_parts(ref, extra_scale) if decompose else [_baked(ref, extra_scale)]:
            cv = round_vertices(cv - centre)
            if decompose and not is_convex(cv, cf):
                concave.append((cv, cf))
                continue
            path = collision_prefix.with_name(f"{collision_prefix.name}{k:02d}.obj")
            write_if_changed(path, obj_text(cv, cf, f"heapgrasp {name} collision {k}"))
            collision.append(path)
            k += 1
    if concave and convex_cache is not None:
        budget = max(1, MAX_COLLISION_PIECES - len(collision))
        collision += decomposed(concave, budget, convex_cache, name)
    mass = link.mass if link.mass is not None else clamped_mass(mesh_volume(v, f))
    return ObjectModel(
        name=name,
        source=source,
        visual_mesh=visual_path,
        collision_meshes=tuple(collision),
        mass=float(mass),
        split=split_of(name, test_fraction),
        extents=mesh_extents(v),
    )


def _too_large(extents: tuple[float, float, float], most: float) -> str | None:
    """Why an object of these extents (m) does not fit a cube of side ``most`` (m)."""
    if max(extents) <= most:
        return None
    size = " x ".join(f"{e:.3f}" for e in extents)
    why = f"is {size} m, larger than the {most:g} m workspace cube"
    if max(extents) > 1.0:
        why += (
            "; meshes are read in metres and this one looks like millimetres: give its "
            '<mesh> elements scale="0.001 0.001 0.001" in its URDF'
        )
    return why
