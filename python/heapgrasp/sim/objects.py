"""Object library of the simulation: pybullet_data models, procedural shapes, user meshes.

Every object is an :class:`ObjectModel`: a visual mesh file (what ground-truth silhouettes
are rendered from and what a scene export points to) and one or more *convex* collision
mesh files, all written to a cache directory in the **object frame**, in metres.

Object frame
    The object frame is the mesh's own axes translated so that the origin is the centre
    of the axis-aligned bounding box of the visual mesh (bounds are symmetric about 0 up
    to 1e-9 m). A PyBullet body made with ``createMultiBody(...,
    baseInertialFramePosition=[0, 0, 0])`` from these files has its base frame equal to
    the mesh frame, so its pose is the ``obj2world`` of the object. Source offsets (URDF
    ``<origin>`` of the visual, mesh ``scale``) are baked into the written files; the
    object frame of a URDF model is its link frame translated to the bounding-box centre.

Collision geometry
    PyBullet treats every dynamic mesh collision shape as its convex hull. Convex-ish
    objects (boxes, cylinders, the random_urdfs blobs) therefore use their visual mesh
    as the single collision mesh. Concave procedural objects (cups, bowls, bottles) are
    decomposed procedurally into convex pieces (wall wedges, bands, a base) whose union
    approximates the object, so a cup is hollow in the physics too. A user object's
    collision meshes are used as they are where convex and replaced by their convex
    decomposition (``pybullet.vhacd``, cached by content) where concave.

Sources
    * ``pybullet_data``: ``random_urdfs/NNN`` (1000 watertight ~9 cm blobs, mesh scale
      from the URDF) and ``pybullet_data/mug``.
    * ``procedural``: boxes, cylinders, bottles, bowls and cups, sized for a gripper with
      an 8 cm opening; the same seed gives byte-identical files.
    * ``user``: a directory of object folders (``NAME/model.urdf`` beside its meshes, the
      YCB / Google Scanned Objects layout for PyBullet) or of ``*.obj``, ``*.stl``,
      ``*.ply`` and ``*.urdf`` files (:func:`user_models`).

Train/test splits are a stable hash of the object name (:func:`split_of`). Optical
categories (transparent, specular, opaque) are not a property of a model: the world
assigns them per scene.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import os
import shutil
import sys
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import numpy.typing as npt
import trimesh

__all__ = [
    "DENSITY",
    "MASS_RANGE",
    "MAX_COLLISION_PIECES",
    "OBJECT_URDF",
    "PROCEDURAL_KINDS",
    "REVOLVE_SECTIONS",
    "VHACD_RESOLUTION",
    "ObjectLibrary",
    "ObjectModel",
    "Source",
    "Split",
    "default_cache_dir",
    "generate_procedural",
    "load_mesh",
    "pybullet_data_models",
    "split_of",
    "user_models",
]

Source = Literal["pybullet_data", "procedural", "user"]
"""Where a model comes from."""

Split = Literal["train", "test"]
"""Train subset or the unseen test subset."""

_SOURCES: tuple[str, ...] = ("pybullet_data", "procedural", "user")
_SPLITS: tuple[str, ...] = ("train", "test")

PROCEDURAL_KINDS: tuple[str, ...] = ("box", "cylinder", "bottle", "bowl", "cup")
"""Kinds of procedural objects, in generation order."""

DENSITY: float = 500.0
"""Density used for the mass of procedural and user objects, kg/m³."""

MASS_RANGE: tuple[float, float] = (0.02, 0.5)
"""Clamp of density-derived masses, kg."""

REVOLVE_SECTIONS: int = 32
"""Angular sections of the revolved procedural meshes (bottles, bowls, cups, cylinders)."""

MAX_COLLISION_PIECES: int = 16
"""Most convex collision meshes per model.

``pybullet.createCollisionShapeArray`` silently keeps only the first 16 child shapes
(``MAX_COMPOUND_COLLISION_SHAPES`` in PyBullet 3.2), so every decomposition fits in 16.
"""

_CUP_WEDGES = 15  # convex wall wedges of a cup, + 1 base = 16 pieces
_BOWL_WEDGES = 7  # angular wedges of a bowl wall
_BOWL_BANDS = 2  # bands along the bowl wall profile: 7 * 2 + 1 foot = 15 pieces
_DECIMALS = 9  # vertices are rounded to 1 nm so that files and memory agree exactly
_MESH_SUFFIXES: tuple[str, ...] = (".obj", ".stl", ".ply")
_N_RANDOM_URDFS = 1000
_MIN_EXTENT = 0.002  # thinner pybullet_data meshes are degenerate (skipped)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


# --------------------------------------------------------------------------- model
@dataclass(frozen=True)
class ObjectModel:
    """One object of the library, with its mesh files in the object frame.

    Attributes
    ----------
    name : str
        Unique name, e.g. ``"random_urdfs/017"``, ``"procedural/cup_03"``, ``"user/<stem>"``.
    source : {"pybullet_data", "procedural", "user"}
        Where the model comes from.
    visual_mesh : Path
        Triangle mesh file (OBJ) in the object frame, metres, already scaled. Ground-truth
        silhouettes are rendered from it and scene exports point to it.
    collision_meshes : tuple of Path
        One or more convex mesh files in the same frame whose union approximates the
        object (PyBullet takes the convex hull of each).
    mass : float
        Mass, kg.
    split : {"train", "test"}
        Subset the model belongs to.
    extents : tuple of float
        Size ``(dx, dy, dz)`` of the axis-aligned bounding box of the visual mesh, metres.
        The object frame origin is the centre of that box.
    """

    name: str
    source: Source
    visual_mesh: Path
    collision_meshes: tuple[Path, ...]
    mass: float
    split: Split
    extents: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("ObjectModel.name must be a non-empty string")
        if self.source not in _SOURCES:
            raise ValueError(f"ObjectModel.source must be one of {_SOURCES}, got {self.source!r}")
        if self.split not in _SPLITS:
            raise ValueError(f"ObjectModel.split must be one of {_SPLITS}, got {self.split!r}")
        if not 1 <= len(self.collision_meshes) <= MAX_COLLISION_PIECES:
            raise ValueError(
                f"ObjectModel {self.name!r}: needs 1 to {MAX_COLLISION_PIECES} collision "
                f"meshes (PyBullet's compound limit), got {len(self.collision_meshes)}"
            )
        if not (math.isfinite(self.mass) and self.mass > 0.0):
            raise ValueError(f"ObjectModel {self.name!r}: mass must be > 0, got {self.mass}")
        if len(self.extents) != 3 or not all(math.isfinite(e) and e >= 0.0 for e in self.extents):
            raise ValueError(
                f"ObjectModel {self.name!r}: extents must be 3 finite values >= 0, "
                f"got {self.extents}"
            )


# --------------------------------------------------------------------------- helpers
def split_of(name: str, test_fraction: float = 0.2) -> Split:
    """Train/test subset of an object, from a stable hash of its name.

    Parameters
    ----------
    name : str
        Object name.
    test_fraction : float
        Probability (over names) of landing in the test subset, in ``[0, 1]``.

    Returns
    -------
    {"train", "test"}
        The same for the same name and fraction on every machine and run (SHA-256, not
        Python's salted ``hash()``).
    """
    if not (0.0 <= test_fraction <= 1.0):
        raise ValueError(f"test_fraction must be in [0, 1], got {test_fraction}")
    digest = hashlib.sha256(name.encode("utf-8")).digest()
    u = int.from_bytes(digest[:8], "big") / 2.0**64
    return "test" if u < test_fraction else "train"


def default_cache_dir() -> Path:
    """Default cache directory of generated object files.

    Returns
    -------
    Path
        ``$HEAPGRASP_CACHE/objects`` when ``HEAPGRASP_CACHE`` is set (and non-empty),
        else ``~/.cache/heapgrasp/objects``.
    """
    root = os.environ.get("HEAPGRASP_CACHE")
    if root:
        return Path(root).expanduser() / "objects"
    return Path.home() / ".cache" / "heapgrasp" / "objects"


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


def _obj_text(vertices: FloatArray, faces: IntArray, header: str) -> str:
    """OBJ file text of a triangle mesh, with fixed formatting (deterministic bytes)."""
    fmt = f"{{:.{_DECIMALS}f}}"  # callers pass _round()ed vertices: no "-0.000000000"
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


def _write_if_changed(path: Path, text: str) -> None:
    """Writes ``text`` to ``path`` unless the file already has exactly this content."""
    data = text.encode("ascii")
    if path.is_file() and path.read_bytes() == data:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _round(vertices: FloatArray) -> FloatArray:
    out = np.round(np.asarray(vertices, dtype=np.float64), _DECIMALS) + 0.0
    return np.asarray(out, dtype=np.float64)


def _bbox_centre(vertices: FloatArray) -> FloatArray:
    centre: FloatArray = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    return centre


def _extents(vertices: FloatArray) -> tuple[float, float, float]:
    e = vertices.max(axis=0) - vertices.min(axis=0)
    return (float(e[0]), float(e[1]), float(e[2]))


def _clamped_mass(volume: float) -> float:
    lo, hi = MASS_RANGE
    return float(min(max(DENSITY * volume, lo), hi))


def _mesh_volume(vertices: FloatArray, faces: IntArray) -> float:
    """Enclosed volume if the mesh is closed and outward, else its convex hull's."""
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0:
        return float(mesh.volume)
    return float(mesh.convex_hull.volume)


def _stem_hash(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:10]


# --------------------------------------------------------------------------- procedural
def _hull(points: FloatArray) -> trimesh.Trimesh:
    """Convex hull of points as an outward-oriented closed mesh."""
    hull: trimesh.Trimesh = trimesh.convex.convex_hull(np.asarray(points, dtype=np.float64))
    if hull.volume < 0:
        hull.invert()
    return hull


def _ring(profile: FloatArray, angles: FloatArray) -> FloatArray:
    """Points of the 2-D ``(r, z)`` profile points swept to the given angles."""
    r = profile[:, 0][None, :]
    z = profile[:, 1][None, :]
    c = np.cos(angles)[:, None]
    s = np.sin(angles)[:, None]
    pts = np.stack([r * c, r * s, np.broadcast_to(z, (len(angles), profile.shape[0]))], axis=-1)
    out: FloatArray = pts.reshape(-1, 3)
    return out


def _revolve(profile: FloatArray) -> trimesh.Trimesh:
    """Closed outward mesh revolving an ``(r, z)`` profile that starts and ends on the axis."""
    mesh = trimesh.creation.revolve(profile, sections=REVOLVE_SECTIONS)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _full_angles() -> FloatArray:
    out: FloatArray = np.linspace(0.0, 2.0 * np.pi, REVOLVE_SECTIONS, endpoint=False)
    return out


def _make_box(rng: np.random.Generator) -> tuple[trimesh.Trimesh, list[trimesh.Trimesh]]:
    size = (rng.uniform(0.03, 0.07), rng.uniform(0.03, 0.12), rng.uniform(0.04, 0.14))
    return trimesh.creation.box(extents=size), []


def _make_cylinder(rng: np.random.Generator) -> tuple[trimesh.Trimesh, list[trimesh.Trimesh]]:
    radius = rng.uniform(0.015, 0.035)
    height = rng.uniform(0.04, 0.14)
    return trimesh.creation.cylinder(radius=radius, height=height, sections=REVOLVE_SECTIONS), []


def _make_bottle(rng: np.random.Generator) -> tuple[trimesh.Trimesh, list[trimesh.Trimesh]]:
    rb = rng.uniform(0.02, 0.035)  # body radius
    height = rng.uniform(0.09, 0.14)
    rn = rb * rng.uniform(0.35, 0.5)  # neck radius
    hb = height * rng.uniform(0.5, 0.62)  # body height
    hs = height * rng.uniform(0.12, 0.2)  # shoulder height
    phi = np.linspace(0.0, 0.5 * np.pi, 7)
    shoulder = np.stack([rn + (rb - rn) * np.cos(phi), hb + hs * np.sin(phi)], axis=1)
    profile = np.vstack([[[0.0, 0.0], [rb, 0.0]], shoulder, [[rn, height], [0.0, height]]])
    visual = _revolve(profile)
    angles = _full_angles()
    body = _hull(_ring(np.array([[rb, 0.0], [rb, hb]]), angles))
    dome = _hull(np.vstack([_ring(shoulder, angles), [[0.0, 0.0, hb]]]))
    neck = _hull(_ring(np.array([[rn, hb + hs], [rn, height]]), angles))
    return visual, [body, dome, neck]


def _make_cup(rng: np.random.Generator) -> tuple[trimesh.Trimesh, list[trimesh.Trimesh]]:
    r_bot = rng.uniform(0.022, 0.031)
    r_top = r_bot + rng.uniform(0.0, 0.004)  # <= 0.035: graspable across
    height = rng.uniform(0.06, 0.12)
    t = rng.uniform(0.003, 0.005)  # wall
    b = rng.uniform(0.004, 0.008)  # base

    def r_out(z: float) -> float:
        return r_bot + (r_top - r_bot) * z / height

    profile = np.array(
        [
            [0.0, 0.0],
            [r_bot, 0.0],
            [r_top, height],
            [r_top - t, height],
            [r_out(b) - t, b],
            [0.0, b],
        ]
    )
    visual = _revolve(profile)
    wall = np.array([[r_bot, 0.0], [r_top, height], [r_top - t, height], [r_bot - t, 0.0]])
    step = 2.0 * np.pi / _CUP_WEDGES
    pieces = [_hull(_ring(wall, np.array([k * step, (k + 1) * step]))) for k in range(_CUP_WEDGES)]
    base = np.array([[r_bot, 0.0], [r_out(b), b]])
    pieces.append(_hull(_ring(base, _full_angles())))
    return visual, pieces


def _make_bowl(rng: np.random.Generator) -> tuple[trimesh.Trimesh, list[trimesh.Trimesh]]:
    radius = rng.uniform(0.028, 0.035)  # rim radius: <= 7 cm across
    height = rng.uniform(0.04, 0.055)
    rb = radius * rng.uniform(0.4, 0.6)  # foot radius
    t = rng.uniform(0.003, 0.005)
    rbi = rb - t
    phi = np.linspace(0.0, 0.5 * np.pi, 10)
    outer = np.stack([rb + (radius - rb) * np.sin(phi), height * (1.0 - np.cos(phi))], axis=1)
    inner = np.stack(
        [rbi + (radius - t - rbi) * np.sin(phi), t + (height - t) * (1.0 - np.cos(phi))], axis=1
    )
    profile = np.vstack([[[0.0, 0.0]], outer, inner[::-1], [[0.0, t]]])
    visual = _revolve(profile)
    step = 2.0 * np.pi / _BOWL_WEDGES
    bounds = np.linspace(0, len(phi) - 1, _BOWL_BANDS + 1).round().astype(int)
    pieces: list[trimesh.Trimesh] = []
    for j in range(_BOWL_BANDS):
        lo, hi = int(bounds[j]), int(bounds[j + 1])
        band = np.vstack([outer[lo : hi + 1], inner[lo : hi + 1]])
        for k in range(_BOWL_WEDGES):
            pieces.append(_hull(_ring(band, np.array([k * step, (k + 1) * step]))))
    pieces.append(_hull(_ring(np.array([[rb, 0.0], [rb, t]]), _full_angles())))
    return visual, pieces


_MAKERS: dict[
    str, Callable[[np.random.Generator], tuple[trimesh.Trimesh, list[trimesh.Trimesh]]]
] = {
    "box": _make_box,
    "cylinder": _make_cylinder,
    "bottle": _make_bottle,
    "bowl": _make_bowl,
    "cup": _make_cup,
}


def generate_procedural(
    cache_dir: Path | str,
    *,
    count_per_kind: int = 8,
    seed: int = 0,
    test_fraction: float = 0.2,
) -> list[ObjectModel]:
    """Generates (or reuses) the procedural objects.

    Kinds are boxes, cylinders, bottles (revolved body, shoulder and neck), bowls (open
    shell with wall thickness and a flat foot) and cups (open cylinder shell with a wall
    and a base). Every visual mesh is closed, consistently wound with outward normals and
    of positive volume. All extents lie in 0.02-0.15 m, heights in 0.04-0.14 m, and at
    least one horizontal width is <= 0.07 m (graspable with an 8 cm opening). Bottles,
    bowls and cups get a procedural convex decomposition (bottle: body, shoulder, neck;
    cup: 15 wall wedges and a base; bowl: 7 x 2 wall pieces and a foot); boxes and
    cylinders collide with their visual mesh. Pieces per model are at most
    :data:`MAX_COLLISION_PIECES`.

    Parameters
    ----------
    cache_dir : Path or str
        Files go to ``cache_dir/<name>/visual.obj`` and ``collision_<k>.obj``, i.e.
        ``cache_dir/procedural/cup_03/...`` for seed 0.
    count_per_kind : int
        Objects per kind (>= 0). Object ``i`` of a kind does not depend on the count.
    seed : int
        Seed (>= 0). Names are ``procedural/<kind>_<ii>`` for seed 0 and
        ``procedural/seed<seed>/<kind>_<ii>`` otherwise, so different seeds never share
        names or files.
    test_fraction : float
        Fraction of names in the test subset (see :func:`split_of`).

    Returns
    -------
    list of ObjectModel
        Ordered by kind (as in :data:`PROCEDURAL_KINDS`), then index.

    Notes
    -----
    Deterministic: the same seed gives byte-identical files. Files whose content is
    already right are not rewritten.
    """
    if isinstance(count_per_kind, bool) or not isinstance(count_per_kind, int | np.integer):
        raise ValueError(f"count_per_kind must be an int, got {count_per_kind!r}")
    if count_per_kind < 0:
        raise ValueError(f"count_per_kind must be >= 0, got {count_per_kind}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be an int >= 0, got {seed!r}")
    cache = Path(cache_dir)
    prefix = "procedural" if seed == 0 else f"procedural/seed{int(seed)}"
    manifest = cache / prefix / _MANIFEST
    key = _generator_key(int(seed), int(count_per_kind), float(test_fraction))
    cached = _read_manifest(manifest, key)
    if cached is not None:
        return cached
    models: list[ObjectModel] = []
    for kind_index, kind in enumerate(PROCEDURAL_KINDS):
        for i in range(int(count_per_kind)):
            rng = np.random.default_rng([int(seed), kind_index, i])
            visual, pieces = _MAKERS[kind](rng)
            name = f"{prefix}/{kind}_{i:02d}"
            models.append(_write_procedural(cache, name, visual, pieces, test_fraction))
    if key is not None and models:
        _write_manifest(manifest, key, models)
    return models


_MANIFEST = "manifest.json"
"""File beside the procedural objects recording what made them (see :func:`_generator_key`)."""


def _generator_key(seed: int, count: int, test_fraction: float) -> str | None:
    """What the procedural files depend on: this module's code, trimesh's and NumPy's
    versions and the arguments; ``None`` when the module's source cannot be read (then
    nothing is cached)."""
    try:
        source = Path(__file__).read_bytes()
    except OSError:
        return None
    h = hashlib.sha256(source)
    h.update(f"|{trimesh.__version__}|{np.__version__}|{seed}|{count}|{test_fraction!r}".encode())
    return h.hexdigest()


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _read_manifest(path: Path, key: str | None) -> list[ObjectModel] | None:
    """The models a manifest records, if it was written for ``key`` and every file it
    lists still has the content it recorded; ``None`` otherwise (regenerate)."""
    if key is None or not path.is_file():
        return None
    try:
        data = json.loads(path.read_text("utf-8"))
        if data.get("key") != key:
            return None
        root = path.parent
        for rel, digest in data["files"].items():
            f = root / rel
            if not f.is_file() or _file_digest(f) != digest:
                return None
        return [
            ObjectModel(
                name=m["name"],
                source="procedural",
                visual_mesh=root / m["visual_mesh"],
                collision_meshes=tuple(root / c for c in m["collision_meshes"]),
                mass=float(m["mass"]),
                split=m["split"],
                extents=(float(m["extents"][0]), float(m["extents"][1]), float(m["extents"][2])),
            )
            for m in data["models"]
        ]
    except (OSError, ValueError, KeyError, TypeError, IndexError):
        return None  # unreadable or from another version: regenerate


def _write_manifest(path: Path, key: str, models: list[ObjectModel]) -> None:
    root = path.parent
    files: dict[str, str] = {}
    records = []
    for m in models:
        paths = [m.visual_mesh, *m.collision_meshes]
        for p in paths:
            files[p.relative_to(root).as_posix()] = _file_digest(p)
        records.append(
            {
                "name": m.name,
                "visual_mesh": m.visual_mesh.relative_to(root).as_posix(),
                "collision_meshes": [c.relative_to(root).as_posix() for c in m.collision_meshes],
                "mass": m.mass,
                "split": m.split,
                "extents": list(m.extents),
            }
        )
    text = json.dumps({"key": key, "files": files, "models": records}, indent=1)
    _write_if_changed(path, text)


def _write_procedural(
    cache: Path,
    name: str,
    visual: trimesh.Trimesh,
    pieces: list[trimesh.Trimesh],
    test_fraction: float,
) -> ObjectModel:
    vertices = np.asarray(visual.vertices, dtype=np.float64)
    centre = _bbox_centre(vertices)
    v = _round(vertices - centre)
    f = np.asarray(visual.faces, dtype=np.int64)
    folder = cache / name
    visual_path = folder / "visual.obj"
    _write_if_changed(visual_path, _obj_text(v, f, f"heapgrasp {name} visual"))
    collision: list[Path] = []
    for k, piece in enumerate(pieces):
        path = folder / f"collision_{k:02d}.obj"
        pv = _round(np.asarray(piece.vertices, dtype=np.float64) - centre)
        pf = np.asarray(piece.faces, dtype=np.int64)
        _write_if_changed(path, _obj_text(pv, pf, f"heapgrasp {name} convex piece {k}"))
        collision.append(path)
    keep = {p.name for p in collision}
    for stale in folder.glob("collision_*.obj"):
        if stale.name not in keep:
            stale.unlink()
    if not collision:
        collision.append(visual_path)
    return ObjectModel(
        name=name,
        source="procedural",
        visual_mesh=visual_path,
        collision_meshes=tuple(collision),
        mass=_clamped_mass(float(visual.volume)),
        split=split_of(name, test_fraction),
        extents=_extents(v),
    )


# --------------------------------------------------------------------------- URDF
@dataclass(frozen=True)
class _MeshRef:
    path: Path
    scale: tuple[float, float, float]
    origin: tuple[float, ...]  # xyz + rpy


@dataclass(frozen=True)
class _UrdfLink:
    visual: _MeshRef
    collisions: tuple[_MeshRef, ...]
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


def _mesh_ref(element: ET.Element, urdf: Path, what: str) -> _MeshRef | None:
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
    return _MeshRef(path, (scale[0], scale[1], scale[2]), (*xyz, *rpy))


def _parse_urdf(urdf: Path) -> _UrdfLink:
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
        return _UrdfLink(visual, collisions, mass)
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
    ref: _MeshRef, extra_scale: float, v: FloatArray, f: IntArray
) -> tuple[FloatArray, IntArray]:
    """A mesh of ``ref``'s file in the link frame (scale and origin applied)."""
    scale = np.asarray(ref.scale, dtype=np.float64) * extra_scale
    m = _origin_matrix(ref.origin)
    v = (v * scale) @ m[:3, :3].T + m[:3, 3]
    if np.prod(scale) < 0:  # mirrored: keep outward orientation
        f = f[:, ::-1].copy()
    return v, f


def _baked(ref: _MeshRef, extra_scale: float) -> tuple[FloatArray, IntArray]:
    """Mesh of a URDF reference in the link frame (scale and origin applied)."""
    return _placed(ref, extra_scale, *load_mesh(ref.path))


def _baked_parts(ref: _MeshRef, extra_scale: float) -> list[tuple[FloatArray, IntArray]]:
    """:func:`_baked`, one mesh per part of the file (:func:`_load_parts`)."""
    return [_placed(ref, extra_scale, v, f) for v, f in _load_parts(ref.path)]


def _model_from_urdf(
    urdf: Path,
    name: str,
    source: Source,
    visual_path: Path,
    collision_prefix: Path,
    test_fraction: float,
) -> ObjectModel:
    link = _parse_urdf(urdf)
    return _model_from_link(
        link, urdf.name, name, source, visual_path, collision_prefix, test_fraction
    )


def _model_from_link(
    link: _UrdfLink,
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
    concave one is replaced by its convex decomposition (:func:`_decomposed`, cached
    there); without, each collides as a whole (PyBullet takes its convex hull). An
    object larger than ``max_extent`` (m) raises ValueError, before any decomposition."""
    v, f = _baked(link.visual, extra_scale)
    why = None if max_extent is None else _too_large(_extents(v), max_extent)
    if why is not None:
        raise ValueError(f"{name} {why}")
    centre = _bbox_centre(v)
    v = _round(v - centre)
    _write_if_changed(visual_path, _obj_text(v, f, f"heapgrasp {name} visual (from {origin})"))
    decompose = convex_cache is not None
    collision: list[Path] = []
    concave: list[tuple[FloatArray, IntArray]] = []
    k = 0
    for ref in link.collisions or (link.visual,):
        if ref == link.visual and (not decompose or _is_convex(v, f)):
            if visual_path not in collision:
                collision.append(visual_path)
            continue
        for cv, cf in _baked_parts(ref, extra_scale) if decompose else [_baked(ref, extra_scale)]:
            cv = _round(cv - centre)
            if decompose and not _is_convex(cv, cf):
                concave.append((cv, cf))
                continue
            path = collision_prefix.with_name(f"{collision_prefix.name}{k:02d}.obj")
            _write_if_changed(path, _obj_text(cv, cf, f"heapgrasp {name} collision {k}"))
            collision.append(path)
            k += 1
    if concave and convex_cache is not None:
        budget = max(1, MAX_COLLISION_PIECES - len(collision))
        collision += _decomposed(concave, budget, convex_cache, name)
    mass = link.mass if link.mass is not None else _clamped_mass(_mesh_volume(v, f))
    return ObjectModel(
        name=name,
        source=source,
        visual_mesh=visual_path,
        collision_meshes=tuple(collision),
        mass=float(mass),
        split=split_of(name, test_fraction),
        extents=_extents(v),
    )


# --------------------------------------------------------------------------- convex pieces
VHACD_RESOLUTION: int = 100_000
"""Voxels of ``pybullet.vhacd``'s voxelisation (V-HACD's own default; PyBullet's is 10x,
about 10x slower for the same pieces on our cups and bowls)."""


def _is_convex(vertices: FloatArray, faces: IntArray) -> bool:
    """Whether a mesh is convex (trimesh: closed, consistently wound, no reflex edge)."""
    return bool(trimesh.Trimesh(vertices, faces, process=False).is_convex)


def _load_parts(path: Path) -> list[tuple[FloatArray, IntArray]]:
    """A collision mesh file as PyBullet's compound of it: an OBJ file whose objects
    (``o`` groups) are each convex, e.g. a V-HACD result, is one part per object; any
    other file is one part (:func:`load_mesh`)."""
    whole = load_mesh(path)
    if path.suffix.lower() != ".obj":
        return [whole]
    try:
        parts = [_checked(g, path) for g in _obj_objects(path)]
    except ValueError:
        return [whole]
    if len(parts) > 1 and all(_is_convex(pv, pf) for pv, pf in parts):
        return parts
    return [whole]


def _obj_objects(path: Path) -> list[object]:
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


#: The longest one convex decomposition may run (s) before the object is skipped: a
#: mesh that passes the checks of :func:`_not_a_solid` can still keep V-HACD busy for
#: minutes (our objects take seconds).
VHACD_TIMEOUT_S = 120.0

#: The child process that runs ``pybullet.vhacd`` (C code that cannot be interrupted in
#: the process that calls it): arguments in, out, log, resolution.
_VHACD_CHILD = (
    "import sys, pybullet as pb; "
    "pb.vhacd(sys.argv[1], sys.argv[2], sys.argv[3], resolution=int(sys.argv[4]))"
)


def _vhacd(
    vertices: FloatArray, faces: IntArray, work: Path, *, timeout: float | None = None
) -> list[FloatArray]:
    """The vertices of each convex piece of ``pybullet.vhacd``'s decomposition, run in a
    child process that is stopped after ``timeout`` s (default :data:`VHACD_TIMEOUT_S`;
    then a ValueError saying so)."""
    import subprocess

    limit = VHACD_TIMEOUT_S if timeout is None else timeout
    src, out, log = work / "in.obj", work / "out.obj", work / "vhacd.log"
    src.write_text(_obj_text(vertices, faces, "heapgrasp vhacd input"))
    argv = [sys.executable, "-c", _VHACD_CHILD, str(src), str(out), str(log)]
    try:
        subprocess.run(
            [*argv, str(VHACD_RESOLUTION)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            timeout=limit,
            check=False,
        )
    except subprocess.TimeoutExpired:  # the child is killed
        raise ValueError(
            f"the convex decomposition (pybullet.vhacd) of its {len(faces)}-triangle collision "
            f"mesh ran past {limit:g} s and was stopped; give it a simpler or convex mesh"
        ) from None
    if not out.is_file():
        return []
    pieces = [
        np.asarray(g.vertices, dtype=np.float64)
        for g in _obj_objects(out)
        if isinstance(g, trimesh.Trimesh)
    ]
    for p in (src, out, log):
        p.unlink(missing_ok=True)
    return [p for p in pieces if len(p) >= 4]


#: The thinnest a collision mesh may be along any axis (m), and the least volume its
#: convex hull may enclose (m³), for it to be decomposed (a flat triangle hung V-HACD).
MIN_THICKNESS = 0.001
MIN_HULL_VOLUME = 1e-9


def _not_a_solid(vertices: FloatArray, faces: IntArray) -> str | None:
    """Why a mesh is no solid to decompose, None if it is one: too few triangles, flat
    along an axis (thinner than :data:`MIN_THICKNESS`), or a hull of no volume."""
    if len(faces) < 4 or len(vertices) < 4:
        return f"has {len(faces)} triangle(s)"
    extents = vertices.max(axis=0) - vertices.min(axis=0)
    if float(extents.min()) < MIN_THICKNESS:
        size = " x ".join(f"{e * 1000:.1f}" for e in extents)
        return f"is flat ({size} mm)"
    if _hull_volume(vertices) < MIN_HULL_VOLUME:
        return "encloses no volume"
    return None


def _hull_volume(points: FloatArray) -> float:
    from scipy.spatial import ConvexHull, QhullError

    try:
        return float(ConvexHull(points).volume)
    except (QhullError, ValueError):  # flat or too few points
        return 0.0


def _merged(pieces: list[FloatArray], most: int) -> list[FloatArray]:
    """At most ``most`` convex pieces: the two pieces whose hull adds the least volume
    are merged into their hull, again and again."""
    points = list(pieces)
    labels = list(range(len(points)))  # a merged piece gets a new label: costs stay valid
    fresh = itertools.count(len(points))
    volumes = [_hull_volume(p) for p in points]
    cost: dict[tuple[int, int], float] = {}
    while len(points) > most:
        best: tuple[float, int, int] | None = None
        for i in range(len(points)):
            for j in range(i + 1, len(points)):
                key = (labels[i], labels[j])
                if key not in cost:
                    both = _hull_volume(np.vstack([points[i], points[j]]))
                    cost[key] = both - volumes[i] - volumes[j]
                if best is None or cost[key] < best[0]:
                    best = (cost[key], i, j)
        assert best is not None
        _, i, j = best
        joined = np.vstack([points[i], points[j]])
        for index in (j, i):
            del points[index], labels[index], volumes[index]
        points.append(joined)
        labels.append(next(fresh))
        volumes.append(_hull_volume(joined))
    return points


def _decomposed(
    parts: list[tuple[FloatArray, IntArray]], most: int, cache: Path, name: str
) -> list[Path]:
    """Convex pieces (at most ``most``) of concave meshes, by ``pybullet.vhacd``
    (:data:`VHACD_RESOLUTION`), merged down to ``most`` (:func:`_merged`).

    Cached by content: ``cache/<hash>/piece_<k>.obj``, the hash of the meshes (in the
    object frame, as written), ``most``, the resolution and PyBullet's version; a second
    load reads the files and runs nothing."""
    from importlib.metadata import version

    h = hashlib.sha256(f"vhacd|{VHACD_RESOLUTION}|{most}|{version('pybullet')}".encode())
    for v, f in parts:
        h.update(_obj_text(v, f, "").encode("ascii"))
    folder = cache / h.hexdigest()[:24]
    done = sorted(folder.glob("piece_*.obj"))
    if done:
        return done
    for v, f in parts:  # V-HACD runs for ever on a mesh that encloses nothing
        problem = _not_a_solid(v, f)
        if problem is not None:
            raise ValueError(f"{name}: its collision mesh {problem}: nothing to decompose")
    work = cache / f".{folder.name}.{os.getpid()}.tmp"
    work.mkdir(parents=True, exist_ok=True)
    try:
        try:
            pieces = [p for v, f in parts for p in _vhacd(v, f, work)]
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None
        if not pieces:
            raise ValueError(
                f"{name}: the convex decomposition (pybullet.vhacd) of its concave collision "
                "mesh gave no pieces"
            )
        for k, points in enumerate(_merged(pieces, most)):
            hull = _hull(points)
            text = _obj_text(
                _round(np.asarray(hull.vertices, dtype=np.float64)),
                np.asarray(hull.faces, dtype=np.int64),
                f"heapgrasp convex piece {k} (pybullet.vhacd)",
            )
            (work / f"piece_{k:02d}.obj").write_text(text)
        try:
            os.replace(work, folder)  # atomic: whole or absent
        except OSError:  # another process wrote it first: the same content
            pass
    finally:
        if work.exists():
            shutil.rmtree(work, ignore_errors=True)
    return sorted(folder.glob("piece_*.obj"))


# --------------------------------------------------------------------------- pybullet_data
def _pybullet_data_dir() -> Path:
    import pybullet_data  # type: ignore[import-untyped, import-not-found, unused-ignore]

    return Path(pybullet_data.getDataPath())


def pybullet_data_models(
    cache_dir: Path | str,
    indices: Iterable[int] | None = None,
    *,
    mug: bool = True,
    data_dir: Path | str | None = None,
    test_fraction: float = 0.2,
    skip_invalid: bool = True,
) -> list[ObjectModel]:
    """Models of pybullet_data: ``random_urdfs/NNN`` and ``pybullet_data/mug``.

    The URDF is parsed for the first visual mesh, its ``scale`` and ``<origin>`` and the
    link mass; the scaled, origin-baked and recentred mesh is written to
    ``cache_dir/random_urdfs/NNN.obj`` (mug: ``cache_dir/pybullet_data/mug/visual.obj``).
    Collision meshes are the URDF's collision meshes, baked the same way; for the
    random_urdfs this is the visual mesh itself (PyBullet takes its convex hull, which is
    close for these blobs). The mug collides as the hull of ``mug_col.obj`` (handle and
    cavity filled), and its visual mesh is not closed.

    Some shipped meshes are unusable (``random_urdfs/168`` has only NaN vertices, a few
    are flat to under 2 mm, e.g. ``random_urdfs/295``); they are left out unless
    ``skip_invalid`` is False.

    Parameters
    ----------
    cache_dir : Path or str
        Cache directory for the written meshes.
    indices : iterable of int, optional
        Which random_urdfs, each in ``[0, 1000)``; all 1000 when omitted.
    mug : bool
        Also return ``pybullet_data/mug`` (last).
    data_dir : Path or str, optional
        pybullet_data directory; default ``pybullet_data.getDataPath()``.
    test_fraction : float
        Fraction of names in the test subset (see :func:`split_of`).
    skip_invalid : bool
        Leave out models whose mesh cannot be loaded (missing, empty or non-finite)
        instead of raising ``ValueError`` / ``FileNotFoundError``, and degenerate ones
        (a bounding-box extent under 2 mm).

    Returns
    -------
    list of ObjectModel
        In the order of ``indices`` (duplicates dropped), then the mug.
    """
    cache = Path(cache_dir)
    data = Path(data_dir) if data_dir is not None else _pybullet_data_dir()
    if indices is None:
        wanted: list[int] = list(range(_N_RANDOM_URDFS))
    else:
        wanted = []
        for raw in indices:
            if isinstance(raw, bool) or not isinstance(raw, int | np.integer):
                raise ValueError(f"random_urdfs index must be an int, got {raw!r}")
            i = int(raw)
            if not 0 <= i < _N_RANDOM_URDFS:
                raise ValueError(f"random_urdfs index must be in [0, 1000), got {i}")
            if i not in wanted:
                wanted.append(i)
    jobs: list[tuple[Path, str, Path, Path]] = []
    for i in wanted:
        stem = f"{i:03d}"
        urdf = data / "random_urdfs" / stem / f"{stem}.urdf"
        out = cache / "random_urdfs"
        jobs.append((urdf, f"random_urdfs/{stem}", out / f"{stem}.obj", out / f"{stem}_collision_"))
    if mug:
        out = cache / "pybullet_data" / "mug"
        jobs.append(
            (
                data / "objects" / "mug.urdf",
                "pybullet_data/mug",
                out / "visual.obj",
                out / "collision_",
            )
        )
    models: list[ObjectModel] = []
    for urdf, name, visual, prefix in jobs:
        try:
            model = _model_from_urdf(urdf, name, "pybullet_data", visual, prefix, test_fraction)
        except (ValueError, FileNotFoundError):
            if skip_invalid:
                continue
            raise
        if skip_invalid and min(model.extents) < _MIN_EXTENT:
            continue
        models.append(model)
    return models


# --------------------------------------------------------------------------- user
OBJECT_URDF: str = "model.urdf"
"""The URDF of an object folder of a user directory (YCB's and Google Scanned Objects'
PyBullet layout: ``DIR/003_cracker_box/model.urdf`` beside its meshes)."""


def _user_sources(folder: Path, on_skip: Callable[[str], None]) -> dict[str, Path]:
    """The objects of a user directory by stem: its URDF and mesh files (a mesh that a
    URDF of the directory references is not an object of its own) and its subfolders'
    :data:`OBJECT_URDF` (or their only ``*.urdf``). Subfolders without one are skipped
    and named to ``on_skip``, as are the directory's URDFs that cannot be parsed."""
    files = sorted(p for p in folder.iterdir() if p.is_file())
    urdfs = [p for p in files if p.suffix.lower() == ".urdf"]
    referenced: set[Path] = set()
    for urdf in urdfs:
        try:
            link = _parse_urdf(urdf)
        except ValueError:
            continue  # reported when the object is made
        for ref in (link.visual, *link.collisions):
            referenced.add(ref.path.resolve())
    found = urdfs + [
        p for p in files if p.suffix.lower() in _MESH_SUFFIXES and p.resolve() not in referenced
    ]
    sources: dict[str, Path] = {}
    for path in sorted(found):
        _add_source(sources, path.stem, path, folder)
    for sub in sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")):
        urdf = sub / OBJECT_URDF
        if not urdf.is_file():
            others = sorted(sub.glob("*.urdf"))
            if len(others) != 1:
                what = "" if not others else f" (and {len(others)} other URDFs: which one?)"
                on_skip(f"skipped {sub}: no {OBJECT_URDF}{what}")
                continue
            urdf = others[0]
        _add_source(sources, sub.name, urdf, folder)
    return sources


def _add_source(sources: dict[str, Path], stem: str, path: Path, folder: Path) -> None:
    if stem in sources:
        raise ValueError(
            f"user objects {sources[stem].relative_to(folder)} and {path.relative_to(folder)} "
            f"in {folder} have the same name 'user/{stem}'; rename one"
        )
    sources[stem] = path


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


def user_models(
    directory: Path | str,
    cache_dir: Path | str,
    *,
    scale: float = 1.0,
    test_fraction: float = 0.2,
    max_extent: float | None = None,
    on_skip: Callable[[str], None] | None = None,
    on_bad: Callable[[str, str], None] | None = None,
) -> list[ObjectModel]:
    """Models of the user's objects in a directory.

    The directory holds objects in either (or both) of two layouts:

    * a folder per object, PyBullet's (YCB, Google Scanned Objects): every subfolder
      with a :data:`OBJECT_URDF` (or a single ``*.urdf``) is one object, named after the
      subfolder, e.g. ``DIR/003_cracker_box/model.urdf`` is ``user/003_cracker_box``;
    * files: every ``*.urdf`` is one object and every ``*.obj``, ``*.stl`` and ``*.ply``
      that no URDF of the directory references is one, named after the file's stem.

    A URDF object is the first visual mesh of its first link with a mesh (with its
    ``scale`` and ``<origin>``), colliding with the link's collision meshes (its visual
    mesh when it has none); a plain mesh file is its own visual and collision mesh.
    Every collision mesh that is convex (trimesh) is used as it is; an OBJ file whose
    objects are each convex (a convex decomposition) gives one piece per object; a
    concave mesh is replaced by its convex decomposition (``pybullet.vhacd``, cached by
    content in ``cache_dir/convex``), so that an object collides as its shape, not as
    its convex hull; at most :data:`MAX_COLLISION_PIECES` pieces in all. Meshes are read
    in metres, times ``scale``; each object is recentred to its bounding-box centre and
    written to ``cache_dir/user/<hash of directory>/<stem>/``. Its mass is the URDF's,
    else :data:`DENSITY` times its volume (its convex hull's when not closed), clamped
    to :data:`MASS_RANGE`.

    Parameters
    ----------
    directory : Path or str
        Directory of object folders and/or mesh / URDF files.
    cache_dir : Path or str
        Cache directory for the written meshes.
    scale : float
        Uniform factor applied to every mesh (e.g. 0.001 for millimetre files), > 0.
    test_fraction : float
        Fraction of names in the test subset (see :func:`split_of`); 1 puts every object
        in the test subset, 0 in the train subset.
    max_extent : float, optional
        An object larger than this (m) along an axis is an error, e.g. the side of the
        workspace cube.
    on_skip : callable, optional
        Called with a message naming each subfolder that holds no object; default
        :func:`warnings.warn`.
    on_bad : callable, optional
        Called with ``(name, problem)`` for each object that cannot be used, which is
        then left out; by default such objects are an error (below).

    Returns
    -------
    list of ObjectModel
        Named ``user/<stem>``, sorted by name.

    Raises
    ------
    FileNotFoundError
        If ``directory`` does not exist or is not a directory.
    ValueError
        For a bad ``scale``, two objects with the same name, no object at all, or objects
        that cannot be used (a URDF without a visual mesh, a mesh that does not load, an
        object larger than ``max_extent``): one error naming each such object's file and
        its problem.
    """
    folder = Path(directory)
    if not folder.is_dir():
        raise FileNotFoundError(f"user object directory not found: {folder}")
    if not (isinstance(scale, int | float) and math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a finite number > 0, got {scale!r}")
    skip = on_skip if on_skip is not None else (lambda m: warnings.warn(m, stacklevel=3))
    sources = _user_sources(folder, skip)
    if not sources:
        raise ValueError(
            f"no objects in {folder}: expected subfolders holding a {OBJECT_URDF} (with "
            "the meshes it names) or mesh files (.obj, .stl, .ply) and URDFs"
        )
    cache = Path(cache_dir)
    base = cache / "user" / _stem_hash(str(folder.resolve()))
    models: list[ObjectModel] = []
    problems: list[str] = []
    for stem, path in sorted(sources.items()):
        name, out = f"user/{stem}", base / stem
        try:
            if path.suffix.lower() == ".urdf":
                link = _parse_urdf(path)
            else:  # a plain mesh: its own visual and collision mesh
                link = _UrdfLink(_MeshRef(path, (1.0, 1.0, 1.0), (0.0,) * 6), (), None)
            model = _model_from_link(
                link,
                path.name,
                name,
                "user",
                out / "visual.obj",
                out / "collision_",
                test_fraction,
                float(scale),
                cache / "convex",
                max_extent,
            )
        except (ValueError, OSError) as exc:
            if on_bad is not None:
                on_bad(name, f"{path.relative_to(folder)}: {exc}")
                continue
            problems.append(f"{path.relative_to(folder)}: {exc}")
            continue
        models.append(model)
    if problems:
        raise ValueError(
            f"{len(problems)} of the {len(sources)} objects in {folder} cannot be used:\n  "
            + "\n  ".join(problems)
        )
    return models


# --------------------------------------------------------------------------- library
class ObjectLibrary:
    """A set of uniquely named object models with train/test subsets.

    Parameters
    ----------
    models : sequence of ObjectModel
        The models; names must be unique.
    cache_dir : Path or str, optional
        Where :meth:`add_user_directory` writes meshes; default :func:`default_cache_dir`.
    """

    def __init__(self, models: Sequence[ObjectModel], cache_dir: Path | str | None = None) -> None:
        self._models: list[ObjectModel] = []
        self._by_name: dict[str, ObjectModel] = {}
        self.cache_dir: Path = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        self._extend(models)

    @classmethod
    def default(
        cls,
        cache_dir: Path | str | None = None,
        *,
        random_urdfs: int = 200,
        procedural_per_kind: int = 8,
        seed: int = 0,
        mug: bool = True,
    ) -> ObjectLibrary:
        """The standard library: random_urdfs ``000 .. random_urdfs-1``, the mug, procedural.

        Parameters
        ----------
        cache_dir : Path or str, optional
            Cache directory; default :func:`default_cache_dir`.
        random_urdfs : int
            How many random_urdfs (the first ones), in ``[0, 1000]``.
        procedural_per_kind : int
            Procedural objects per kind.
        seed : int
            Seed of the procedural objects.
        mug : bool
            Include ``pybullet_data/mug``.

        Returns
        -------
        ObjectLibrary
        """
        if isinstance(random_urdfs, bool) or not 0 <= random_urdfs <= _N_RANDOM_URDFS:
            raise ValueError(f"random_urdfs must be in [0, 1000], got {random_urdfs!r}")
        cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        models = pybullet_data_models(cache, range(int(random_urdfs)), mug=mug)
        models += generate_procedural(cache, count_per_kind=procedural_per_kind, seed=seed)
        return cls(models, cache)

    def _extend(self, models: Iterable[ObjectModel]) -> None:
        new = list(models)
        seen: set[str] = set()
        for m in new:
            if not isinstance(m, ObjectModel):
                raise ValueError(f"expected ObjectModel, got {type(m).__name__}")
            if m.name in self._by_name or m.name in seen:
                raise ValueError(f"duplicate object name {m.name!r}")
            seen.add(m.name)
        for m in new:
            self._models.append(m)
            self._by_name[m.name] = m

    def add(self, models: Iterable[ObjectModel]) -> None:
        """Adds ``models``; raises ValueError on a name already in the library."""
        self._extend(models)

    def models(self, split: str | None = None, source: str | None = None) -> list[ObjectModel]:
        """Models, optionally of one split and/or one source, in library order.

        Parameters
        ----------
        split : {"train", "test"}, optional
        source : {"pybullet_data", "procedural", "user"}, optional

        Returns
        -------
        list of ObjectModel
        """
        if split is not None and split not in _SPLITS:
            raise ValueError(f"split must be one of {_SPLITS} or None, got {split!r}")
        if source is not None and source not in _SOURCES:
            raise ValueError(f"source must be one of {_SOURCES} or None, got {source!r}")
        return [
            m
            for m in self._models
            if (split is None or m.split == split) and (source is None or m.source == source)
        ]

    def get(self, name: str) -> ObjectModel:
        """The model called ``name`` (raises ``KeyError`` naming it when absent)."""
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"no object named {name!r} in the library") from None

    def sample(
        self, rng: np.random.Generator, n: int, *, split: str | None = "train"
    ) -> list[ObjectModel]:
        """Draws ``n`` models of a split.

        Without replacement when the split has at least ``n`` models; otherwise every
        model appears ``n // len`` or ``n // len + 1`` times (whole shuffled passes).

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of randomness (same state, same draw).
        n : int
            Number of models, >= 0.
        split : {"train", "test"} or None
            Subset to draw from; None for all models.

        Returns
        -------
        list of ObjectModel
        """
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise ValueError(f"n must be an int >= 0, got {n!r}")
        pool = self.models(split=split)
        if n == 0:
            return []
        if not pool:
            raise ValueError(f"cannot sample {n} objects: the library has no {split!r} objects")
        picks: list[int] = []
        while len(picks) < n:
            take = min(n - len(picks), len(pool))
            picks.extend(int(i) for i in rng.choice(len(pool), size=take, replace=False))
        return [pool[i] for i in picks]

    def add_user_directory(self, path: Path | str, scale: float = 1.0) -> list[ObjectModel]:
        """Adds the objects of a user directory (see :func:`user_models`).

        Parameters
        ----------
        path : Path or str
            Directory of object folders (``NAME/model.urdf``) and/or ``*.obj`` / ``*.stl``
            / ``*.ply`` / ``*.urdf`` files.
        scale : float
            Factor from file units to metres.

        Returns
        -------
        list of ObjectModel
            The added models. Nothing is added if any name is already in the library.
        """
        added = user_models(path, self.cache_dir, scale=scale)
        self._extend(added)
        return added

    def __len__(self) -> int:
        return len(self._models)

    def __iter__(self) -> Iterator[ObjectModel]:
        return iter(list(self._models))

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def __repr__(self) -> str:
        n_test = sum(m.split == "test" for m in self._models)
        return f"ObjectLibrary({len(self)} models, {n_test} test, cache_dir={self.cache_dir})"
