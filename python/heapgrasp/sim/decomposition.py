"""Convex decomposition of concave collision meshes: ``pybullet.vhacd`` run in a child
process (stopped after :data:`VHACD_TIMEOUT_S`), its pieces merged down to a budget, and
the result cached by content.

PyBullet treats every dynamic mesh collision shape as its convex hull, so a user object's
concave collision mesh is replaced by these pieces (:mod:`heapgrasp.sim.urdf`).
"""

from __future__ import annotations

import hashlib
import itertools
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt
import trimesh

from heapgrasp.sim.mesh_files import convex_hull, obj_objects, obj_text, round_vertices

__all__ = [
    "MIN_HULL_VOLUME",
    "MIN_THICKNESS",
    "VHACD_RESOLUTION",
    "VHACD_TIMEOUT_S",
    "decomposed",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


VHACD_RESOLUTION: int = 100_000
"""Voxels of ``pybullet.vhacd``'s voxelisation (V-HACD's own default; PyBullet's is 10x,
about 10x slower for the same pieces on our cups and bowls)."""


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
    src.write_text(obj_text(vertices, faces, "heapgrasp vhacd input"))
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
        for g in obj_objects(out)
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


def decomposed(
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
        h.update(obj_text(v, f, "").encode("ascii"))
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
            hull = convex_hull(points)
            text = obj_text(
                round_vertices(np.asarray(hull.vertices, dtype=np.float64)),
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
