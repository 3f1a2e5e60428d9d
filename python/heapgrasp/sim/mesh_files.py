"""Triangle mesh files of the object library: reading them (:func:`load_mesh`, the parts of
an OBJ file), writing them byte-for-byte reproducibly (:func:`obj_text`,
:func:`write_if_changed`), and the few mesh measures the models are made with (bounding
box, volume, convex hull, convexity).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh

__all__ = [
    "bbox_centre",
    "convex_hull",
    "is_convex",
    "load_mesh",
    "load_parts",
    "mesh_extents",
    "mesh_volume",
    "obj_objects",
    "obj_text",
    "round_vertices",
    "write_if_changed",
]

_DECIMALS = 9  # vertices are rounded to 1 nm so that files and memory agree exactly

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def load_mesh(path: Path | str) -> tuple[FloatArray, IntArray]:
    """Loads a triangle mesh file.

    Polygons are triangulated and vertices at identical positions are welded (so that a
    closed STL mesh is closed), nothing else is changed.

    Parameters
    ----------
    path : Path or str
        Mesh file readable by trimesh (OBJ, STL, PLY, OFF, GLB, ...).

    Returns
    -------
    vertices : ndarray of float64, shape (V, 3)
    faces : ndarray of int64, shape (F, 3)
        Indices into ``vertices``.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file cannot be parsed as a mesh, has no triangles, or has non-finite
        vertices.
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"mesh file not found: {p}")
    try:
        mesh = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for bad files
        raise _unreadable(p, exc) from exc
    return _checked(mesh, p)


def _unreadable(p: Path, exc: Exception) -> ValueError:
    """The error for a mesh file trimesh cannot parse. trimesh meets bytes that are
    neither a binary nor a text mesh by reaching for an optional text-encoding detector
    (an ImportError that says nothing about the file): that is a damaged or misnamed
    file, said so."""
    kind = p.suffix.lstrip(".").upper() or "mesh"
    if isinstance(exc, ImportError):
        return ValueError(
            f"cannot load mesh {p}: not a valid {kind} file (neither a binary nor a text "
            "mesh: damaged, or another format under that name)"
        )
    return ValueError(f"cannot load mesh {p}: {exc}")


def _checked(mesh: object, p: Path) -> tuple[FloatArray, IntArray]:
    """:func:`load_mesh`'s checks and welding of a mesh loaded from ``p``."""
    if not isinstance(mesh, trimesh.Trimesh):
        raise ValueError(f"cannot load mesh {p}: got {type(mesh).__name__}, not a mesh")
    if len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise ValueError(f"mesh {p} is empty (no triangles)")
    used = np.unique(np.asarray(mesh.faces, dtype=np.int64))
    if not np.all(np.isfinite(np.asarray(mesh.vertices)[used])):
        raise ValueError(f"mesh {p} has non-finite (NaN or inf) vertices")
    mesh.remove_unreferenced_vertices()
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise ValueError(f"mesh {p} is empty (no triangles)")
    return vertices, faces


def obj_text(vertices: FloatArray, faces: IntArray, header: str) -> str:
    """OBJ file text of a triangle mesh, with fixed formatting (deterministic bytes)."""
    fmt = f"{{:.{_DECIMALS}f}}"  # callers pass round_vertices()ed vertices: no "-0.000000000"
    # the header may hold the user's file name: kept ASCII, escaped ("objé" -> "obj\xe9")
    header = header.encode("ascii", "backslashreplace").decode("ascii")
    lines = [f"# {header}", f"# {len(vertices)} vertices, {len(faces)} triangles, metres"]
    for x, y, z in vertices.tolist():
        xs, ys, zs = (fmt.format(c + 0.0) for c in (x, y, z))
        lines.append(f"v {xs} {ys} {zs}")
    for a, b, c in (faces + 1).tolist():
        lines.append(f"f {a} {b} {c}")
    lines.append("")
    return "\n".join(lines)


def write_if_changed(path: Path, text: str) -> None:
    """Writes ``text`` to ``path`` unless the file already has exactly this content."""
    data = text.encode("ascii")
    if path.is_file() and path.read_bytes() == data:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def round_vertices(vertices: FloatArray) -> FloatArray:
    """Vertices rounded to 1 nm (as written to the files), without negative zeros."""
    out = np.round(np.asarray(vertices, dtype=np.float64), _DECIMALS) + 0.0
    return np.asarray(out, dtype=np.float64)


def bbox_centre(vertices: FloatArray) -> FloatArray:
    """Centre of the axis-aligned bounding box of ``vertices``."""
    centre: FloatArray = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    return centre


def mesh_extents(vertices: FloatArray) -> tuple[float, float, float]:
    """Size ``(dx, dy, dz)`` of the axis-aligned bounding box of ``vertices``."""
    e = vertices.max(axis=0) - vertices.min(axis=0)
    return (float(e[0]), float(e[1]), float(e[2]))


def mesh_volume(vertices: FloatArray, faces: IntArray) -> float:
    """Enclosed volume if the mesh is closed and outward, else its convex hull's."""
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0:
        return float(mesh.volume)
    return float(mesh.convex_hull.volume)


def convex_hull(points: FloatArray) -> trimesh.Trimesh:
    """Convex hull of points as an outward-oriented closed mesh."""
    hull: trimesh.Trimesh = trimesh.convex.convex_hull(np.asarray(points, dtype=np.float64))
    if hull.volume < 0:
        hull.invert()
    return hull


def is_convex(vertices: FloatArray, faces: IntArray) -> bool:
    """Whether a mesh is convex (trimesh: closed, consistently wound, no reflex edge)."""
    return bool(trimesh.Trimesh(vertices, faces, process=False).is_convex)


def load_parts(path: Path) -> list[tuple[FloatArray, IntArray]]:
    """A collision mesh file as PyBullet's compound of it: an OBJ file whose objects
    (``o`` groups) are each convex, e.g. a V-HACD result, is one part per object; any
    other file is one part (:func:`load_mesh`)."""
    whole = load_mesh(path)
    if path.suffix.lower() != ".obj":
        return [whole]
    try:
        parts = [_checked(g, path) for g in obj_objects(path)]
    except ValueError:
        return [whole]
    if len(parts) > 1 and all(is_convex(pv, pf) for pv, pf in parts):
        return parts
    return [whole]


def obj_objects(path: Path) -> list[object]:
    """The objects (``o`` groups) of an OBJ file, as trimesh loads them."""
    try:
        scene = trimesh.load(
            str(path), force="scene", process=False, split_objects=True, group_material=False
        )
    except Exception as exc:  # trimesh raises many types for bad files
        raise _unreadable(path, exc) from exc
    if not isinstance(scene, trimesh.Scene):
        raise ValueError(f"cannot load mesh {path}: got {type(scene).__name__}, not objects")
    return list(scene.geometry.values())
