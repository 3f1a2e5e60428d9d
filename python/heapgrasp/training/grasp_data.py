"""The grasp network's dataset in memory, batches of scenes with their grasps, and the
exact augmentations (HEAPGrasp §IV-B eq. 11, VGN's training).

* :func:`load_grasp_dataset` / :func:`find_datasets` / :func:`concatenate` — directories
  written by ``heapgrasp grasps data`` (``manifest.json`` and ``shard-NNNNN.npz``, the
  layout of :mod:`heapgrasp.data.grasps`), read whole and checked. Only the grid the
  network reads is kept, as it was written: ``occupancy`` (``Ŝ≥λ`` as the loop feeds it:
  0 or Ŝ ∈ [λ, 1]) or ``tsdf`` (float32, 256 KiB a scene at R = 40).
* :func:`make_batch` — ``B`` scenes and all their labelled grasps: one forward pass per
  scene gives the network's output at every labelled voxel (VGN runs one pass per
  grasp).
* :func:`augment_scene` / :func:`draw_augments` — a quarter turn about the vertical axis
  through the grid's centre and an integer x–y shift, both exact on the grid:
  ``np.rot90(grid, k, axes=(0, 1))`` (x towards y, counter-clockwise seen from above)
  sends voxel ``[i, j]`` to ``[R−1−j, i]``, the TCP ``p`` to ``c + R_z(90°)(p − c)``
  (``c`` the grid's centre) and its orientation ``q`` to ``q_z(90°) ⊗ q``; a shift by
  ``(di, dj)`` voxels moves the TCP by ``(di, dj, 0) · voxel_size``. Voxels shifted in
  from outside the grid are empty, 0 for both inputs: no occupancy, and the TSDF's
  value where no camera looked (the Rust core's initial value; VGN pads with 0 too);
  a grasp whose voxel leaves the grid is dropped. The table stays where it is (no z
  shift: the grids' floor is the table).

Only numpy is needed here; the writer, :mod:`heapgrasp.data.grasps`, sits above this
package, so the format is read from its documented layout.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.training.datasets import (
    check_array,
    check_finite,
    first_of_same,
    open_shard,
    read_manifest,
    read_shards,
)

__all__ = [
    "DATA_FORMAT",
    "GEOMETRY_KEYS",
    "INPUT_KINDS",
    "Augment",
    "GraspBatch",
    "GraspDataError",
    "GraspDataset",
    "GraspSource",
    "augment_scene",
    "check_compatible",
    "concatenate",
    "draw_augments",
    "find_datasets",
    "load_grasp_dataset",
    "make_batch",
    "quat_multiply",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

#: ``"format"`` of a grasp dataset's manifest (:data:`heapgrasp.data.grasps.FORMAT`).
DATA_FORMAT = "heapgrasp-grasp-data"
_DATA_VERSION = 2
#: The grids a grasp network reads: ``Ŝ≥λ`` (HEAPGrasp, no-vp) or the TSDF (VGN).
INPUT_KINDS = ("occupancy", "tsdf")
#: Settings of a dataset's ``config`` a network trained on it depends on: datasets
#: trained and validated together must agree on them.
GEOMETRY_KEYS = (
    "resolution",
    "cube_size",
    "lam",
    "roof_radius",
    "tsdf_truncation",
    "max_opening",
    "gripper",
)

_PER_SCENE = {
    "origin": (np.float64, (3,)),
    "voxel_size": (np.float64, ()),
    "scene_seed": (np.int64, ()),
    "scene_index": (np.int64, ()),
    "k": (np.int64, ()),
}
_PER_GRASP = {
    "grasp_scene": (np.int64, ()),
    "grasp_voxel": (np.int64, (3,)),
    "grasp_position": (np.float32, (3,)),
    "grasp_quat": (np.float32, (4,)),
    "grasp_width": (np.float32, ()),
    "grasp_label": (np.uint8, ()),
}


class GraspDataError(ValueError):
    """A grasp dataset directory is missing, not a dataset, or inconsistent."""


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class GraspSource:
    """One dataset directory: its path, split, scene and grasp counts and objects."""

    path: str
    split: str
    scenes: int
    grasps: int
    objects: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        """Plain types for JSON."""
        return {
            "path": self.path,
            "split": self.split,
            "scenes": self.scenes,
            "grasps": self.grasps,
        }


@dataclass(frozen=True, eq=False)
class GraspDataset:
    """Scenes and their labelled grasps from one or more grasp dataset directories.

    Per scene (leading axis ``S``): ``grids`` float32 ``(S, R, R, R)`` indexed
    ``[x, y, z]`` (the dataset's ``occupancy`` or ``tsdf``), ``origin`` float64 ``(S, 3)``
    (the grid's minimum corner, world metres), ``voxel_size`` float64 ``(S,)``,
    ``scene_seed``, ``scene_index``, ``k`` int64 ``(S,)``, and ``offsets`` int64
    ``(S + 1,)``: scene ``s``'s grasps are rows ``offsets[s]:offsets[s + 1]`` of the
    per-grasp arrays ``voxel`` int64 ``(G, 3)`` (its position's voxel), ``position``
    float32 ``(G, 3)`` (VGN's grasp origin, the centre of the palm's face, world
    metres), ``quat`` float32 ``(G, 4)`` (``x, y, z, w``, world =
    grid axes; z = approach, fingers close along y), ``width`` float32 ``(G,)``
    (opening, metres), ``label`` uint8 ``(G,)`` (1 success, 0 failure).
    """

    split: str
    input_kind: str
    geometry: Mapping[str, Any]
    sources: tuple[GraspSource, ...]
    grids: F32
    origin: F64
    voxel_size: F64
    scene_seed: I64
    scene_index: I64
    k: I64
    offsets: I64
    voxel: I64
    position: F32
    quat: F32
    width: F32
    label: npt.NDArray[np.uint8]

    def __len__(self) -> int:
        return int(self.origin.shape[0])

    @property
    def resolution(self) -> int:
        """Grid side ``R``."""
        return int(self.grids.shape[1])

    @property
    def grasps(self) -> int:
        """Labelled grasps of all scenes."""
        return int(self.label.shape[0])

    @property
    def positives(self) -> int:
        """Successful grasps."""
        return int(self.label.sum())

    @property
    def objects(self) -> frozenset[str]:
        """Objects of every source."""
        return frozenset(o for s in self.sources for o in s.objects)

    def scene_grasps(self, scene: int) -> slice:
        """Rows of scene ``scene``'s grasps."""
        return slice(int(self.offsets[scene]), int(self.offsets[scene + 1]))

    def summary(self) -> str:
        """``N scenes, G grasps (P % positive)``."""
        share = 100.0 * self.positives / max(self.grasps, 1)
        return f"{len(self)} scenes, {self.grasps} grasps ({share:.0f} % positive)"


def _check_kind(input_kind: str) -> None:
    if input_kind not in INPUT_KINDS:
        raise ValueError(f"input_kind must be one of {', '.join(INPUT_KINDS)}, got {input_kind!r}")


def _load_shard(file: Path, expected: int, input_kind: str, r: int) -> dict[str, np.ndarray] | None:
    names = [input_kind, *_PER_SCENE, *_PER_GRASP]
    out = open_shard(file, names, expected, what="scenes", error=GraspDataError)
    if out is None:
        return None
    n = expected
    grid = out.pop(input_kind)
    check_array(file, input_kind, grid, np.float32, (n, r, r, r), GraspDataError)
    check_finite(file, input_kind, grid, GraspDataError)
    g = int(out["grasp_label"].shape[0]) if out["grasp_label"].ndim == 1 else -1
    for name, (dtype, shape) in {**_PER_SCENE, **_PER_GRASP}.items():
        lead = n if name in _PER_SCENE else g
        check_array(file, name, out[name], dtype, (lead, *shape), GraspDataError)
    _check_grasps(file, out, n, r)
    out["grids"] = grid
    return out


def _check_grasps(file: Path, a: Mapping[str, np.ndarray], n: int, r: int) -> None:
    scene = a["grasp_scene"]
    if scene.size and (scene.min() < 0 or scene.max() >= n):
        raise GraspDataError(f"{file}: 'grasp_scene' outside [0, {n})")
    voxel = a["grasp_voxel"]
    if voxel.size and (voxel.min() < 0 or voxel.max() >= r):
        raise GraspDataError(f"{file}: 'grasp_voxel' outside the {r}³ grid")
    for name in ("origin", "voxel_size", "grasp_position", "grasp_quat", "grasp_width"):
        if not np.isfinite(a[name]).all():
            raise GraspDataError(f"{file}: {name!r} holds NaN or infinity")
    if (a["voxel_size"] <= 0).any():
        raise GraspDataError(f"{file}: 'voxel_size' not > 0")
    if (a["grasp_label"] > 1).any():
        raise GraspDataError(f"{file}: 'grasp_label' holds values other than 0 and 1")
    norm = np.linalg.norm(a["grasp_quat"].astype(np.float64), axis=1)
    if norm.size and np.abs(norm - 1.0).max() > 1e-3:
        raise GraspDataError(f"{file}: 'grasp_quat' holds quaternions that are not unit")


def _geometry(config: Mapping[str, Any], where: str) -> dict[str, Any]:
    r = config.get("resolution")
    if isinstance(r, bool) or not isinstance(r, int) or r < 8 or r % 8:
        raise GraspDataError(
            f"{where}: config['resolution'] is {r!r}, not a multiple of 8 (the network's "
            "three stride-2 levels)"
        )
    geometry = {key: config.get(key) for key in GEOMETRY_KEYS}
    # Datasets made before the gripper option were the Panda's.
    geometry["gripper"] = geometry["gripper"] or "panda"
    if geometry["max_opening"] is None:
        from heapgrasp.geometry.gripper import gripper_named

        try:
            geometry["max_opening"] = gripper_named(str(geometry["gripper"])).max_opening
        except ValueError as exc:
            raise GraspDataError(f"{where}: config['gripper']: {exc}") from None
    return geometry


def load_grasp_dataset(
    path: str | os.PathLike[str], *, input_kind: str | None = None, workers: int = 1
) -> GraspDataset:
    """Reads a grasp dataset directory written by ``heapgrasp grasps data``.

    ``input_kind``: the grid to read, ``occupancy`` or ``tsdf``; None: the one the
    dataset was made with (its manifest's ``config["input"]``; ``occupancy`` in a
    manifest without it). Every shard the manifest lists is read (``workers`` threads)
    and checked against the manifest's scene count and ``R``, the arrays' dtypes and
    shapes, and each other (grasp scenes and voxels in range, finite values, 0/1 labels,
    unit quaternions). Raises :class:`GraspDataError` naming the directory or file
    otherwise, when the dataset holds another grid, or when it holds no scene.
    """
    root = Path(path)
    manifest = read_manifest(
        root,
        fmt=DATA_FORMAT,
        version=_DATA_VERSION,
        what="grasp dataset",
        command="heapgrasp grasps data",
        error=GraspDataError,
    )
    made = manifest["config"].get("input")
    if input_kind is None:
        input_kind = made if isinstance(made, str) else "occupancy"
    _check_kind(input_kind)
    if isinstance(made, str) and made != input_kind:
        raise GraspDataError(
            f"{root}: a dataset of {made!r} grids (made with --input {made}); the "
            f"{input_kind!r} network needs one made with --input {input_kind}"
        )
    geometry = _geometry(manifest["config"], f"{root / 'manifest.json'}")
    r = int(geometry["resolution"])
    shards = read_shards(
        root,
        manifest,
        lambda file, n: _load_shard(file, n, input_kind, r),
        workers=workers,
        error=GraspDataError,
    )
    if not shards:
        raise GraspDataError(f"{root}: the dataset holds no scene")
    parts = []
    for s in shards:
        order = np.argsort(s["grasp_scene"], kind="stable")
        counts = np.bincount(s["grasp_scene"], minlength=len(s["k"]))
        parts.append(({k: v[order] if k in _PER_GRASP else v for k, v in s.items()}, counts))
    arrays = {name: np.concatenate([p[name] for p, _ in parts]) for name in parts[0][0]}
    counts = np.concatenate([c for _, c in parts])
    objects = manifest.get("objects", [])
    source = GraspSource(
        path=str(root.resolve()),
        split=str(manifest["split"]),
        scenes=len(arrays["k"]),
        grasps=len(arrays["grasp_label"]),
        objects=tuple(str(o) for o in objects) if isinstance(objects, list) else (),
    )
    return GraspDataset(
        split=source.split,
        input_kind=input_kind,
        geometry=geometry,
        sources=(source,),
        **_fields(arrays, counts),
    )


#: The dataset's arrays but ``offsets``.
_ARRAYS: tuple[str, ...] = ("grids", "origin", "voxel_size", "scene_seed", "scene_index", "k")
_ARRAYS += ("voxel", "position", "quat", "width", "label")


def _fields(arrays: Mapping[str, np.ndarray], counts: I64) -> dict[str, Any]:
    """:class:`GraspDataset`'s array fields from arrays named as the dataset's (or the
    shards' ``grasp_*``) and each scene's grasp count."""
    offsets = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    fields = {n: arrays[n if n in arrays else f"grasp_{n}"] for n in _ARRAYS}
    return {**fields, "offsets": offsets}


def find_datasets(paths: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The grasp dataset directories among ``paths``: each path is one (it holds a
    ``manifest.json``) or holds them as subdirectories (``DATA/train``, ``DATA/val``,
    ...). GraspDataError naming a path that is missing, not a directory, or holds no
    dataset."""
    found: list[Path] = []
    for path in paths:
        p = Path(path)
        if not p.exists():
            raise GraspDataError(f"{p}: no such directory")
        if not p.is_dir():
            raise GraspDataError(f"{p}: not a directory (expected a grasp dataset directory)")
        if (p / "manifest.json").exists():
            found.append(p)
            continue
        subs = sorted(d for d in p.iterdir() if d.is_dir() and (d / "manifest.json").exists())
        if not subs:
            raise GraspDataError(
                f"{p}: not a grasp dataset (no manifest.json in it or its subdirectories; "
                f"write one with 'heapgrasp grasps data {p}/train --split train')"
            )
        found += subs
    return found


def check_compatible(a: GraspDataset, b: GraspDataset) -> None:
    """GraspDataError unless ``a`` and ``b`` read the same grid kind and agree on
    :data:`GEOMETRY_KEYS`."""
    if a.input_kind != b.input_kind:
        raise GraspDataError(f"datasets read as {a.input_kind!r} and {b.input_kind!r}")
    if dict(a.geometry) == dict(b.geometry):
        return
    diff = ", ".join(
        f"{k} = {a.geometry[k]} vs {b.geometry[k]}"
        for k in a.geometry
        if a.geometry[k] != b.geometry[k]
    )
    raise GraspDataError(
        f"datasets {a.sources[0].path} and {b.sources[0].path} do not match ({diff}); "
        "one network reads one kind of grid"
    )


def concatenate(datasets: Sequence[GraspDataset]) -> GraspDataset:
    """One dataset of several of the same split, input kind and geometry
    (GraspDataError otherwise)."""
    first = first_of_same(datasets, check_compatible, GraspDataError)
    if len(datasets) == 1:
        return first
    arrays = {n: np.concatenate([getattr(d, n) for d in datasets]) for n in _ARRAYS}
    counts = np.concatenate([np.diff(d.offsets) for d in datasets])
    return GraspDataset(
        split=first.split,
        input_kind=first.input_kind,
        geometry=first.geometry,
        sources=tuple(s for d in datasets for s in d.sources),
        **_fields(arrays, counts),
    )


# --------------------------------------------------------------------------- augmentation


@dataclass(frozen=True)
class Augment:
    """A quarter-turn count about the grid's vertical centre axis (counter-clockwise seen
    from above), then a shift by whole voxels along x and y."""

    turns: int = 0
    shift: tuple[int, int] = (0, 0)


def quat_multiply(a: npt.ArrayLike, b: npt.ArrayLike) -> F64:
    """Hamilton products ``a ⊗ b`` of ``(..., 4)`` quaternions ``x, y, z, w``."""
    x1, y1, z1, w1 = np.moveaxis(np.asarray(a, dtype=np.float64), -1, 0)
    x2, y2, z2, w2 = np.moveaxis(np.asarray(b, dtype=np.float64), -1, 0)
    return np.stack(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ],
        axis=-1,
    )


def _shift_grid(grid: np.ndarray, di: int, dj: int) -> np.ndarray:
    """``grid`` moved by ``(di, dj)`` voxels along x and y, 0 shifted in."""
    out = np.zeros_like(grid)
    r = grid.shape[0]
    src_i, dst_i = slice(max(0, -di), r - max(0, di)), slice(max(0, di), r - max(0, -di))
    src_j, dst_j = slice(max(0, -dj), r - max(0, dj)), slice(max(0, dj), r - max(0, -dj))
    out[dst_i, dst_j] = grid[src_i, src_j]
    return out


def augment_scene(
    grid: np.ndarray,
    voxel: I64,
    position: npt.NDArray[np.floating[Any]],
    quat: npt.NDArray[np.floating[Any]],
    origin: npt.ArrayLike,
    voxel_size: float,
    augment: Augment,
) -> tuple[np.ndarray, I64, F32, F32, npt.NDArray[np.bool_]]:
    """One scene and its grasps turned and shifted (module docstring).

    Parameters
    ----------
    grid : (R, R, R) array
        The scene's grid, indexed ``[x, y, z]``.
    voxel : (N, 3) int array
        Voxel of each grasp's TCP.
    position : (N, 3) array
        TCP positions, world metres.
    quat : (N, 4) array
        TCP orientations ``x, y, z, w`` (world = grid axes).
    origin : (3,) array
        The grid's minimum corner (world metres).
    voxel_size : float
        Edge of a voxel (m).
    augment : Augment
        The turn and shift.

    Returns
    -------
    grid, voxel, position, quat, keep
        The transformed grid, and the transformed grasps that stay inside it; ``keep``
        ``(N,)`` says which of the given grasps those are.
    """
    r = grid.shape[0]
    if grid.shape != (r, r, r):
        raise ValueError(f"grid must be (R, R, R), got {grid.shape}")
    turns = augment.turns % 4
    di, dj = augment.shift
    v = np.asarray(voxel, dtype=np.int64).copy()
    p = np.asarray(position, dtype=np.float64).copy()
    q = np.asarray(quat, dtype=np.float64)
    out = np.rot90(grid, turns, axes=(0, 1)) if turns else grid
    if turns:
        centre = np.asarray(origin, dtype=np.float64)[:2] + 0.5 * r * voxel_size
        rel = p[:, :2] - centre
        for _ in range(turns):
            v[:, 0], v[:, 1] = r - 1 - v[:, 1], v[:, 0].copy()
            rel = np.stack([-rel[:, 1], rel[:, 0]], axis=1)
        p[:, :2] = centre + rel
        half = 0.25 * math.pi * turns
        q = quat_multiply([0.0, 0.0, math.sin(half), math.cos(half)], q)
    if di or dj:
        out = _shift_grid(out, di, dj)
        v[:, 0] += di
        v[:, 1] += dj
        p[:, 0] += di * voxel_size
        p[:, 1] += dj * voxel_size
    keep = np.all((v >= 0) & (v < r), axis=1)
    out = np.ascontiguousarray(out)
    return out, v[keep], p[keep].astype(np.float32), q[keep].astype(np.float32), keep


def draw_augments(rng: np.random.Generator, n: int, max_shift: int) -> list[Augment]:
    """``n`` augmentations: a uniform number of quarter turns and uniform shifts in
    ``[−max_shift, max_shift]`` voxels along x and y."""
    turns = rng.integers(0, 4, n)
    shifts = rng.integers(-max_shift, max_shift + 1, (n, 2))
    return [Augment(int(t), (int(s[0]), int(s[1]))) for t, s in zip(turns, shifts, strict=True)]


# --------------------------------------------------------------------------- batches


@dataclass(frozen=True)
class GraspBatch:
    """Scenes stacked for one forward pass and their grasps.

    ``grids`` float32 ``(B, 1, R, R, R)``; per grasp (``N`` of them, all the scenes'):
    ``scene`` int64 (the batch row), ``voxel`` int64 ``(N, 3)``, ``position`` float32
    ``(N, 3)``, ``quat`` float32 ``(N, 4)``, ``width`` float32 (m), ``label`` float32
    (1, 0), ``voxel_size`` float32 (m, the scene's).
    """

    grids: F32
    scene: I64
    voxel: I64
    position: F32
    quat: F32
    width: F32
    label: F32
    voxel_size: F32

    def __len__(self) -> int:
        return int(self.label.shape[0])


def make_batch(
    data: GraspDataset, scenes: npt.ArrayLike, augments: Sequence[Augment] | None = None
) -> GraspBatch:
    """The network's input for ``scenes`` and their grasps, each scene transformed by
    its augmentation where given (:func:`augment_scene`)."""
    idx = np.asarray(scenes, dtype=np.int64).reshape(-1)
    if augments is not None and len(augments) != len(idx):
        raise ValueError(f"{len(idx)} scenes but {len(augments)} augmentations")
    r = data.resolution
    grids = np.empty((len(idx), 1, r, r, r), dtype=np.float32)
    parts: dict[str, list[np.ndarray]] = {
        k: [] for k in ("scene", "voxel", "position", "quat", "width", "label", "voxel_size")
    }
    for b, s in enumerate(idx):
        rows = data.scene_grasps(int(s))
        grid, voxel = data.grids[s], data.voxel[rows]
        position, quat = data.position[rows], data.quat[rows]
        width, label = data.width[rows], data.label[rows]
        if augments is not None:
            grid, voxel, position, quat, keep = augment_scene(
                grid, voxel, position, quat, data.origin[s], float(data.voxel_size[s]), augments[b]
            )
            width, label = width[keep], label[keep]
        grids[b, 0] = grid
        parts["scene"].append(np.full(len(label), b, dtype=np.int64))
        parts["voxel"].append(voxel)
        parts["position"].append(position)
        parts["quat"].append(quat)
        parts["width"].append(width)
        parts["label"].append(label)
        parts["voxel_size"].append(np.full(len(label), data.voxel_size[s]))
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    return GraspBatch(
        grids=grids,
        scene=cat["scene"].astype(np.int64),
        voxel=cat["voxel"].astype(np.int64),
        position=cat["position"].astype(np.float32),
        quat=cat["quat"].astype(np.float32),
        width=cat["width"].astype(np.float32),
        label=cat["label"].astype(np.float32),
        voxel_size=cat["voxel_size"].astype(np.float32),
    )
