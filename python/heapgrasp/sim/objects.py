"""Object library of the simulation: pybullet_data models, procedural shapes, user meshes.

Every object is an :class:`~heapgrasp.sim.object_model.ObjectModel`: a visual mesh file
(what ground-truth silhouettes are rendered from and what a scene export points to) and
one or more *convex* collision mesh files, all written to a cache directory in the
**object frame**, in metres.

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
    decomposition (``pybullet.vhacd``, cached by content; :mod:`heapgrasp.sim.decomposition`)
    where concave.

Sources
    * ``pybullet_data``: ``random_urdfs/NNN`` (1000 watertight ~9 cm blobs, mesh scale
      from the URDF) and ``pybullet_data/mug``.
    * ``procedural``: boxes, cylinders, bottles, bowls and cups, sized for a gripper with
      an 8 cm opening; the same seed gives byte-identical files
      (:mod:`heapgrasp.sim.procedural`).
    * ``user``: a directory of object folders (``NAME/model.urdf`` beside its meshes, the
      YCB / Google Scanned Objects layout for PyBullet, or the downloads' own layouts such
      as ``NAME/google_16k/textured.obj``) or of ``*.obj``, ``*.stl``, ``*.ply`` and
      ``*.urdf`` files (:func:`user_models`).

Train/test splits are a stable hash of the object name
(:func:`~heapgrasp.sim.object_model.split_of`). Optical categories (transparent, specular,
opaque) are not a property of a model: the world assigns them per scene.

This module makes the ``pybullet_data`` and user models and gathers models into an
:class:`ObjectLibrary`; the model itself is :mod:`heapgrasp.sim.object_model`, mesh files
are read and written by :mod:`heapgrasp.sim.mesh_files`, and URDF files are read into
models by :mod:`heapgrasp.sim.urdf`.
"""

from __future__ import annotations

import hashlib
import math
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

import numpy as np

from heapgrasp.sim.object_model import (
    SOURCES,
    SPLITS,
    ObjectModel,
    default_cache_dir,
)
from heapgrasp.sim.procedural import generate_procedural
from heapgrasp.sim.urdf import MeshRef, UrdfLink, model_from_link, model_from_urdf, parse_urdf

__all__ = [
    "FOLDER_MESHES",
    "OBJECT_URDF",
    "ObjectLibrary",
    "pybullet_data_models",
    "user_models",
]

_MESH_SUFFIXES: tuple[str, ...] = (".obj", ".stl", ".ply")
_N_RANDOM_URDFS = 1000
_MIN_EXTENT = 0.002  # thinner pybullet_data meshes are degenerate (skipped)


def _stem_hash(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:10]


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
            model = model_from_urdf(urdf, name, "pybullet_data", visual, prefix, test_fraction)
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

#: Where an object folder without a URDF keeps its mesh, in order of preference: the
#: YCB download's scans (``google_16k``, then ``google_64k``, ``poisson``, ``tsdf``),
#: Google Scanned Objects' ``meshes/model.obj``, and the flat folders of the simulators'
#: copies (iGibson's ``textured_simple.obj``, ManiSkill's and others' ``textured.obj``).
FOLDER_MESHES: tuple[str, ...] = (
    "google_16k/textured.obj",
    "google_16k/nontextured.ply",
    "google_16k/nontextured.stl",
    "google_64k/textured.obj",
    "google_64k/nontextured.ply",
    "poisson/textured.obj",
    "poisson/nontextured.ply",
    "tsdf/textured.obj",
    "tsdf/nontextured.ply",
    "meshes/model.obj",
    "textured_simple.obj",
    "textured.obj",
    "nontextured.ply",
    "nontextured.stl",
    "model.obj",
)
"""The URDF of an object folder of a user directory (YCB's and Google Scanned Objects'
PyBullet layout: ``DIR/003_cracker_box/model.urdf`` beside its meshes)."""


def _user_sources(folder: Path, on_skip: Callable[[str], None]) -> dict[str, Path]:
    """The objects of a user directory by stem: its URDF and mesh files (a mesh that a
    URDF of the directory references is not an object of its own) and its subfolders'
    :data:`OBJECT_URDF` (or their only ``*.urdf``, or else the first of
    :data:`FOLDER_MESHES` they hold). Subfolders with none are skipped and named to
    ``on_skip``, as are the directory's URDFs that cannot be parsed."""
    files = sorted(p for p in folder.iterdir() if p.is_file())
    urdfs = [p for p in files if p.suffix.lower() == ".urdf"]
    referenced: set[Path] = set()
    for urdf in urdfs:
        try:
            link = parse_urdf(urdf)
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
        found_in = _folder_object(sub)
        if isinstance(found_in, str):
            on_skip(f"skipped {sub}: {found_in}")
            continue
        _add_source(sources, sub.name, found_in, folder)
    return sources


def _folder_object(sub: Path) -> Path | str:
    """The file that makes ``sub`` an object (its :data:`OBJECT_URDF`, its only URDF, or
    its first :data:`FOLDER_MESHES`), or why it is none."""
    urdf = sub / OBJECT_URDF
    if urdf.is_file():
        return urdf
    urdfs = sorted(sub.glob("*.urdf"))
    if len(urdfs) == 1:
        return urdfs[0]
    mesh = next((sub / m for m in FOLDER_MESHES if (sub / m).is_file()), None)
    if mesh is not None:
        return mesh
    if urdfs:
        names = ", ".join(u.name for u in urdfs)
        return f"no {OBJECT_URDF} and {len(urdfs)} other URDFs ({names}): which one?"
    return (
        f"no {OBJECT_URDF}, other URDF or known mesh file ({', '.join(FOLDER_MESHES[:3])}, "
        "meshes/model.obj, textured.obj, ...)"
    )


def _add_source(sources: dict[str, Path], stem: str, path: Path, folder: Path) -> None:
    if stem in sources:
        raise ValueError(
            f"user objects {sources[stem].relative_to(folder)} and {path.relative_to(folder)} "
            f"in {folder} have the same name 'user/{stem}'; rename one"
        )
    sources[stem] = path


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

    * a folder per object: every subfolder with a :data:`OBJECT_URDF` (or a single
      ``*.urdf``: PyBullet's copies of YCB and Google Scanned Objects, e.g.
      ``pybullet_object_models/ycb_objects/YcbCrackerBox/model.urdf``) or, without
      one, a mesh where the common downloads keep it (:data:`FOLDER_MESHES`: YCB's
      ``003_cracker_box/google_16k/textured.obj``, Google Scanned Objects'
      ``meshes/model.obj``, ...) is one object named after the subfolder, e.g.
      ``user/003_cracker_box``;
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
            "the meshes it names) or a mesh (e.g. google_16k/textured.obj, "
            "meshes/model.obj), or mesh files (.obj, .stl, .ply) and URDFs"
        )
    cache = Path(cache_dir)
    base = cache / "user" / _stem_hash(str(folder.resolve()))
    models: list[ObjectModel] = []
    problems: list[str] = []
    for stem, path in sorted(sources.items()):
        name, out = f"user/{stem}", base / stem
        try:
            if path.suffix.lower() == ".urdf":
                link = parse_urdf(path)
            else:  # a plain mesh: its own visual and collision mesh
                link = UrdfLink(MeshRef(path, (1.0, 1.0, 1.0), (0.0,) * 6), (), None)
            model = model_from_link(
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
        if split is not None and split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS} or None, got {split!r}")
        if source is not None and source not in SOURCES:
            raise ValueError(f"source must be one of {SOURCES} or None, got {source!r}")
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
