"""An object of the simulation's library: its model (mesh files in the object frame, mass,
split), the train/test split of its name, and the cache its files are written to.

The model's frame and collision meshes are described in :mod:`heapgrasp.sim.objects`,
which makes the models of each source and gathers them into a library.
"""

from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

__all__ = [
    "DENSITY",
    "MASS_RANGE",
    "MAX_COLLISION_PIECES",
    "SOURCES",
    "SPLITS",
    "ObjectModel",
    "Source",
    "Split",
    "clamped_mass",
    "default_cache_dir",
    "split_of",
]

Source = Literal["pybullet_data", "procedural", "user"]
"""Where a model comes from."""

Split = Literal["train", "test"]
"""Train subset or the unseen test subset."""

SOURCES: tuple[str, ...] = ("pybullet_data", "procedural", "user")
"""Every :data:`Source`."""
SPLITS: tuple[str, ...] = ("train", "test")
"""Every :data:`Split`."""

DENSITY: float = 500.0
"""Density used for the mass of procedural and user objects, kg/m³."""

MASS_RANGE: tuple[float, float] = (0.02, 0.5)
"""Clamp of density-derived masses, kg."""

MAX_COLLISION_PIECES: int = 16
"""Most convex collision meshes per model.

``pybullet.createCollisionShapeArray`` silently keeps only the first 16 child shapes
(``MAX_COMPOUND_COLLISION_SHAPES`` in PyBullet 3.2), so every decomposition fits in 16.
"""


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
        if self.source not in SOURCES:
            raise ValueError(f"ObjectModel.source must be one of {SOURCES}, got {self.source!r}")
        if self.split not in SPLITS:
            raise ValueError(f"ObjectModel.split must be one of {SPLITS}, got {self.split!r}")
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


def clamped_mass(volume: float) -> float:
    """Mass (kg) of :data:`DENSITY` times ``volume`` (m³), clamped to :data:`MASS_RANGE`."""
    lo, hi = MASS_RANGE
    return float(min(max(DENSITY * volume, lo), hi))
