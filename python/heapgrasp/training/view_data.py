"""The view network's dataset in memory, and the problem's symmetries (HEAPGrasp
§IV-B, eq. 12-14).

* :func:`load_view_dataset` / :func:`concatenate` — a directory written by ``heapgrasp
  views data`` (``manifest.json`` and ``shard-NNNNN.npz``) read whole and checked
  against its manifest; the SfS counts stay uint16 in memory (256 KiB a sample at
  R = 40) and become the network's float32 input per batch (:func:`batch_inputs`).
* :func:`transform_grid` / :func:`transform_scores` — the exact symmetries. The
  candidates of eq. 12 sit on a sphere about the vertical axis through the cube's
  centre, and the grid's x–y cross-section is a square centred on that axis, so turning
  the scene by 90° about it maps voxels onto voxels and candidates onto candidates:
  ``np.rot90(grid, k, axes=(0, 1))`` (x towards y: counter-clockwise seen from above)
  shifts the scores by ``+k U/4`` rows (``roll(scores, k·U/4, axis=0)``); the mirror
  ``y → −y`` (``np.flip(grid, axis=1)``) sends row ``u`` to ``(−u) mod U``. Together the
  8 elements of the square's symmetry group (:data:`SYMMETRIES`).
  ``tests/test_train_views.py`` proves the mapping with the exact scorer on a box scene
  turned and mirrored whole (meshes, camera, counts). It is exact for every candidate
  but the pole (``v = 0``, θ = 0): that camera looks straight down with a fixed roll and
  its 320 × 240 image is not square, so a quarter turn changes its eq. 14 a little (by
  0.005 in the test, where the other candidates agree to 0.0).

Only the geometry layer is imported (the candidates of :meth:`DataGeometry.candidates`);
the dataset's writer, :mod:`heapgrasp.data.views`, sits above this package, so the
format is read here from its documented layout.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import torch
from torch import Tensor

from heapgrasp.geometry.motion import ViewSphere
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
    "SYMMETRIES",
    "DataGeometry",
    "DataSource",
    "ViewDataError",
    "ViewDataset",
    "batch_inputs",
    "check_compatible",
    "concatenate",
    "load_view_dataset",
    "transform_grid",
    "transform_scores",
]

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
U16 = npt.NDArray[np.uint16]

#: ``"format"`` of a view dataset's manifest.
DATA_FORMAT = "heapgrasp-view-data"
_DATA_VERSION = 1
#: The 8 symmetries ``(k, mirror)``: mirror ``y → −y`` first, then ``k`` quarter turns.
SYMMETRIES: tuple[tuple[int, bool], ...] = tuple((k, m) for m in (False, True) for k in range(4))
#: The arrays of a sample and their dtypes.
ARRAYS = {
    "segmented": np.uint16,
    "visible": np.uint16,
    "region": np.bool_,
    "scores": np.float32,
    "current": np.float64,
    "target": np.float64,
    "scene_seed": np.int64,
    "k": np.int64,
}


class ViewDataError(ValueError):
    """A view dataset directory is missing, not a dataset, or inconsistent."""


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class DataGeometry:
    """What a network trained on a dataset depends on: grid side, candidate layout,
    view sphere and λ (``manifest.json``'s ``config``)."""

    resolution: int
    U: int
    V: int
    theta_max: float
    cube_size: float
    radius: float
    lam: float

    @classmethod
    def from_config(cls, config: Mapping[str, Any], where: str) -> DataGeometry:
        """From a manifest's ``config`` (ViewDataError naming ``where`` if a key is bad)."""
        values: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            value = config.get(f.name)
            bad = ViewDataError(f"{where}: config[{f.name!r}] is {value!r}")
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise bad
            if f.type == "int":
                if not isinstance(value, int) or value < 1:
                    raise bad
                values[f.name] = value
            else:
                if not (math.isfinite(value) and value > 0):
                    raise bad
                values[f.name] = float(value)
        return cls(**values)

    @property
    def view_shape(self) -> tuple[int, int]:
        """``(U, V)``."""
        return (self.U, self.V)

    def candidates(self) -> F64:
        """``(U, V, 4, 4)`` candidates of eq. 12 (the grid's origin at the world's)."""
        sphere = ViewSphere.for_cube((0.0, 0.0, 0.0), self.cube_size, radius=self.radius)
        return sphere.candidates(self.U, self.V, self.theta_max)


@dataclass(frozen=True)
class DataSource:
    """One dataset directory: its path, split, sample count and objects."""

    path: str
    split: str
    samples: int
    objects: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        """Plain types for JSON."""
        return {"path": self.path, "split": self.split, "samples": self.samples}


@dataclass(frozen=True, eq=False)
class ViewDataset:
    """Samples of one or more view dataset directories, in memory.

    Arrays have a leading sample axis ``N``: ``segmented``, ``visible`` uint16
    ``(N, R, R, R)`` (SfS counts indexed ``[x, y, z]``), ``region`` bool ``(N, R, R)``
    (the x–y column eq. 14 was counted on), ``scores`` float32 ``(N, U, V)`` (eq. 14),
    ``current``, ``target`` float64 ``(N, 4, 4)`` (``cam2world`` scored from; target
    grasp, NaN where none), ``scene_seed``, ``k`` int64 ``(N,)``.
    """

    split: str
    geometry: DataGeometry
    sources: tuple[DataSource, ...]
    segmented: U16
    visible: U16
    region: npt.NDArray[np.bool_]
    scores: F32
    current: F64
    target: F64
    scene_seed: npt.NDArray[np.int64]
    k: npt.NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.scores.shape[0])

    @property
    def objects(self) -> frozenset[str]:
        """Objects of every source."""
        return frozenset(o for s in self.sources for o in s.objects)

    @property
    def has_target(self) -> npt.NDArray[np.bool_]:
        """``(N,)``: the sample has a target grasp."""
        return np.asarray(np.isfinite(self.target).all(axis=(1, 2)))

    @property
    def whole_grid(self) -> npt.NDArray[np.bool_]:
        """``(N,)``: eq. 14 was counted on the whole grid (the paper's), not a region."""
        return np.asarray(self.region.all(axis=(1, 2)))

    def for_network(self, in_channels: int) -> ViewDataset:
        """The samples a network with ``in_channels`` inputs can learn: all of them with
        the region channel (2); without it (1) only the whole-grid samples, since a
        region's labels are another function of the same grid."""
        if in_channels not in (1, 2, 3):
            raise ValueError(f"in_channels must be 1, 2 or 3, got {in_channels!r}")
        whole = self.whole_grid
        return self if in_channels >= 2 or whole.all() else self.subset(np.flatnonzero(whole))

    def subset(self, index: npt.ArrayLike) -> ViewDataset:
        """The samples at ``index`` (same sources)."""
        i = np.asarray(index)
        arrays = {name: getattr(self, name)[i] for name in ARRAYS}
        return dataclasses.replace(self, **arrays)


def _load_shard(file: Path, expected: int, geo: DataGeometry) -> dict[str, np.ndarray] | None:
    r, (u, v) = geo.resolution, geo.view_shape
    shapes = {
        "segmented": (r, r, r),
        "visible": (r, r, r),
        "region": (r, r),
        "scores": (u, v),
        "current": (4, 4),
        "target": (4, 4),
        "scene_seed": (),
        "k": (),
    }
    out = open_shard(file, list(ARRAYS), expected, what="samples", error=ViewDataError)
    if out is None:
        return None
    n = expected
    for name, dtype in ARRAYS.items():
        check_array(file, name, out[name], dtype, (n, *shapes[name]), ViewDataError)
    check_finite(file, "scores", out["scores"], ViewDataError)
    if (out["segmented"] > out["visible"]).any():
        raise ViewDataError(f"{file}: segmented counts exceed visible counts")
    return out


def load_view_dataset(path: str | os.PathLike[str], *, workers: int = 1) -> ViewDataset:
    """Reads a view dataset directory written by ``heapgrasp views data``.

    Every shard the manifest lists is read (``workers`` threads decompress them) and
    checked against the manifest's sample count, the config's ``R``, ``U``, ``V`` and the
    arrays' dtypes. Raises :class:`ViewDataError` naming the directory or file otherwise,
    or when it holds no sample.
    """
    root = Path(path)
    manifest = read_manifest(
        root,
        fmt=DATA_FORMAT,
        version=_DATA_VERSION,
        what="view dataset",
        command="heapgrasp views data",
        error=ViewDataError,
    )
    geo = DataGeometry.from_config(manifest["config"], f"{root / 'manifest.json'}")
    shards = read_shards(
        root,
        manifest,
        lambda file, n: _load_shard(file, n, geo),
        workers=workers,
        error=ViewDataError,
    )
    if not shards:
        raise ViewDataError(f"{root}: the dataset holds no sample")
    arrays = {name: np.concatenate([s[name] for s in shards]) for name in ARRAYS}
    objects = manifest.get("objects", [])
    source = DataSource(
        path=str(root.resolve()),
        split=str(manifest["split"]),
        samples=len(arrays["k"]),
        objects=tuple(str(o) for o in objects) if isinstance(objects, list) else (),
    )
    return ViewDataset(split=source.split, geometry=geo, sources=(source,), **arrays)


def concatenate(datasets: Sequence[ViewDataset]) -> ViewDataset:
    """One dataset of several of the same split and geometry (ViewDataError otherwise,
    naming the directories and the values that differ)."""
    first = first_of_same(datasets, check_compatible, ViewDataError)
    if len(datasets) == 1:
        return first
    arrays = {n: np.concatenate([getattr(d, n) for d in datasets]) for n in ARRAYS}
    sources = tuple(s for d in datasets for s in d.sources)
    return ViewDataset(split=first.split, geometry=first.geometry, sources=sources, **arrays)


def check_compatible(a: ViewDataset, b: ViewDataset) -> None:
    """ViewDataError unless ``a`` and ``b`` share grid side, candidates, sphere and λ."""
    if a.geometry == b.geometry:
        return
    ga, gb = dataclasses.asdict(a.geometry), dataclasses.asdict(b.geometry)
    diff = ", ".join(f"{k} = {ga[k]} vs {gb[k]}" for k in ga if ga[k] != gb[k])
    raise ViewDataError(
        f"datasets {a.sources[0].path} and {b.sources[0].path} do not match ({diff}); "
        "one network reads one grid side and scores one candidate layout"
    )


def batch_inputs(data: ViewDataset, index: npt.ArrayLike, in_channels: int = 1) -> F32:
    """The network's input for the samples at ``index``: float32 ``(n, C, R, R, R)``.

    Channel 0 is the occupancy ``Ŝ_{0-1}`` of eq. 10 (``segmented / visible`` where
    ``visible > 0``, else 0: :meth:`heapgrasp.OccupancyGrid.occupancy` bit for bit);
    channel 1 (``in_channels = 2``) the region mask broadcast along z (0/1).
    """
    if in_channels not in (1, 2, 3):
        raise ValueError(f"in_channels must be 1, 2 or 3, got {in_channels!r}")
    i = np.asarray(index)
    seg = data.segmented[i].astype(np.float32)
    vis = data.visible[i].astype(np.float32)
    r = data.geometry.resolution
    out = np.zeros((len(i), in_channels, r, r, r), dtype=np.float32)
    np.divide(seg, vis, out=out[:, 0], where=vis > 0)
    if in_channels >= 2:
        out[:, 1] = data.region[i][:, :, :, None]
    if in_channels == 3:
        from heapgrasp.geometry.grid import GridFrame

        geo = data.geometry
        frame = GridFrame((0.0, 0.0, 0.0), geo.cube_size, r)
        for j, pose in enumerate(data.current[i]):
            out[j, 2] = frame.distance_field(pose[:3, 3])
    return out


# --------------------------------------------------------------------------- symmetries


def transform_grid(x: Tensor, k: int, mirror: bool) -> Tensor:
    """The grid of the scene mirrored (``y → −y``, if ``mirror``) and then turned by
    ``k`` quarter turns counter-clockwise about the vertical axis through the grid's
    centre. ``x`` is ``(..., X, Y, Z)``; the x–y cross-section must be square."""
    if x.shape[-3] != x.shape[-2]:
        raise ValueError(f"grid cross-section must be square, got {tuple(x.shape)}")
    if mirror:
        x = torch.flip(x, dims=(-2,))
    return torch.rot90(x, k % 4, dims=(-3, -2)) if k % 4 else x


def transform_scores(scores: Tensor, k: int, mirror: bool) -> Tensor:
    """The eq. 14 scores ``(..., U, V)`` of the scene :func:`transform_grid` makes:
    mirrored rows ``u → (−u) mod U``, then rolled by ``k·U/4`` (``U`` divisible by 4)."""
    u = scores.shape[-2]
    if u % 4:
        raise ValueError(f"U = {u} azimuths: a quarter turn is a symmetry only if 4 divides U")
    if mirror:
        scores = torch.roll(torch.flip(scores, dims=(-2,)), 1, dims=-2)
    return torch.roll(scores, (k % 4) * u // 4, dims=-2) if k % 4 else scores
