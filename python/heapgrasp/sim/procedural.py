"""Procedural objects: boxes, cylinders, bottles, bowls and cups, sized for a gripper with
an 8 cm opening, each with a procedural convex decomposition where it is concave; the same
seed gives byte-identical files, and a manifest beside them lets later runs reuse them.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh

from heapgrasp.sim import mesh_files, object_model
from heapgrasp.sim.mesh_files import (
    bbox_centre,
    convex_hull,
    mesh_extents,
    obj_text,
    round_vertices,
    write_if_changed,
)
from heapgrasp.sim.object_model import ObjectModel, clamped_mass, split_of

__all__ = [
    "PROCEDURAL_KINDS",
    "REVOLVE_SECTIONS",
    "generate_procedural",
    "procedural_mesh",
    "revolve",
]

PROCEDURAL_KINDS: tuple[str, ...] = ("box", "cylinder", "bottle", "bowl", "cup")
"""Kinds of procedural objects, in generation order."""

REVOLVE_SECTIONS: int = 32
"""Angular sections of the revolved procedural meshes (bottles, bowls, cups, cylinders)."""

_CUP_WEDGES = 15  # convex wall wedges of a cup, + 1 base = 16 pieces
_BOWL_WEDGES = 7  # angular wedges of a bowl wall
_BOWL_BANDS = 2  # bands along the bowl wall profile: 7 * 2 + 1 foot = 15 pieces

FloatArray = npt.NDArray[np.float64]


def _ring(profile: FloatArray, angles: FloatArray) -> FloatArray:
    """Points of the 2-D ``(r, z)`` profile points swept to the given angles."""
    r = profile[:, 0][None, :]
    z = profile[:, 1][None, :]
    c = np.cos(angles)[:, None]
    s = np.sin(angles)[:, None]
    pts = np.stack([r * c, r * s, np.broadcast_to(z, (len(angles), profile.shape[0]))], axis=-1)
    out: FloatArray = pts.reshape(-1, 3)
    return out


def revolve(profile: FloatArray) -> trimesh.Trimesh:
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
    visual = revolve(profile)
    angles = _full_angles()
    body = convex_hull(_ring(np.array([[rb, 0.0], [rb, hb]]), angles))
    dome = convex_hull(np.vstack([_ring(shoulder, angles), [[0.0, 0.0, hb]]]))
    neck = convex_hull(_ring(np.array([[rn, hb + hs], [rn, height]]), angles))
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
    visual = revolve(profile)
    wall = np.array([[r_bot, 0.0], [r_top, height], [r_top - t, height], [r_bot - t, 0.0]])
    step = 2.0 * np.pi / _CUP_WEDGES
    pieces = [
        convex_hull(_ring(wall, np.array([k * step, (k + 1) * step]))) for k in range(_CUP_WEDGES)
    ]
    base = np.array([[r_bot, 0.0], [r_out(b), b]])
    pieces.append(convex_hull(_ring(base, _full_angles())))
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
    visual = revolve(profile)
    step = 2.0 * np.pi / _BOWL_WEDGES
    bounds = np.linspace(0, len(phi) - 1, _BOWL_BANDS + 1).round().astype(int)
    pieces: list[trimesh.Trimesh] = []
    for j in range(_BOWL_BANDS):
        lo, hi = int(bounds[j]), int(bounds[j + 1])
        band = np.vstack([outer[lo : hi + 1], inner[lo : hi + 1]])
        for k in range(_BOWL_WEDGES):
            pieces.append(convex_hull(_ring(band, np.array([k * step, (k + 1) * step]))))
    pieces.append(convex_hull(_ring(np.array([[rb, 0.0], [rb, t]]), _full_angles())))
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


def procedural_mesh(kind: str, index: int, seed: int = 0) -> trimesh.Trimesh:
    """The visual mesh of procedural object ``index`` of ``kind`` for ``seed``, in
    memory: the mesh :func:`generate_procedural` writes for it (upright, in its maker's
    frame, not recentred)."""
    if kind not in _MAKERS:
        raise ValueError(f"kind must be one of {', '.join(PROCEDURAL_KINDS)}, got {kind!r}")
    if index < 0 or seed < 0:
        raise ValueError(f"index and seed must be >= 0, got {index} and {seed}")
    rng = np.random.default_rng([int(seed), PROCEDURAL_KINDS.index(kind), int(index)])
    return _MAKERS[kind](rng)[0]


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


#: The modules whose code makes the procedural files: this one, and those that write the
#: mesh files and give the models' masses and splits.
_GENERATOR_SOURCES = (__file__, mesh_files.__file__, object_model.__file__)


def _generator_key(seed: int, count: int, test_fraction: float) -> str | None:
    """What the procedural files depend on: the code of :data:`_GENERATOR_SOURCES`,
    trimesh's and NumPy's versions and the arguments; ``None`` when a module's source
    cannot be read (then nothing is cached)."""
    try:
        source = b"".join(Path(f).read_bytes() for f in _GENERATOR_SOURCES)
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
    write_if_changed(path, text)


def _write_procedural(
    cache: Path,
    name: str,
    visual: trimesh.Trimesh,
    pieces: list[trimesh.Trimesh],
    test_fraction: float,
) -> ObjectModel:
    vertices = np.asarray(visual.vertices, dtype=np.float64)
    centre = bbox_centre(vertices)
    v = round_vertices(vertices - centre)
    f = np.asarray(visual.faces, dtype=np.int64)
    folder = cache / name
    visual_path = folder / "visual.obj"
    write_if_changed(visual_path, obj_text(v, f, f"heapgrasp {name} visual"))
    collision: list[Path] = []
    for k, piece in enumerate(pieces):
        path = folder / f"collision_{k:02d}.obj"
        pv = round_vertices(np.asarray(piece.vertices, dtype=np.float64) - centre)
        pf = np.asarray(piece.faces, dtype=np.int64)
        write_if_changed(path, obj_text(pv, pf, f"heapgrasp {name} convex piece {k}"))
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
        mass=clamped_mass(float(visual.volume)),
        split=split_of(name, test_fraction),
        extents=mesh_extents(v),
    )
