"""Optical categories and the simulated depth sensor (HEAPGrasp §VI, Table III).

Silhouettes are category-independent (segmentation works on transparent, specular and
opaque objects alike); depth is not. This module turns the ideal depth of a frame into
what an active stereo camera (RealSense D415 class) returns, per optical category of
the object seen at each pixel:

* **opaque** — axial noise ``σ(z) = 0.0012 + 0.0019 (z − 0.4)²`` m (the Kinect/structured
  light model of Nguyen et al., 2012), quantised to 1 mm;
* **transparent** — the sensor sees *through* the object: in blobs covering
  ``transparent_background`` of its pixels the depth of what lies behind it (table or
  other objects) is returned, in blobs covering ``transparent_missing`` no depth (0),
  elsewhere a noisy depth of the object's surface;
* **specular** — blobs covering ``specular_missing`` of its pixels return no depth;
  a fraction ``specular_outliers`` of the remaining pixels return a depth offset by
  U(−0.05, 0.15) m (inter-reflections); the rest is opaque-like.

"Blobs" are a random field drawn at 1/8 resolution and upsampled (nearest), so holes
and see-through regions come in patches as on real sensors. Everything is drawn from
the ``numpy.random.Generator`` passed in, so a seeded world gives the same depth.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt

__all__ = ["Category", "DepthModel"]


class Category(StrEnum):
    """Optical category of an object."""

    TRANSPARENT = "transparent"
    SPECULAR = "specular"
    OPAQUE = "opaque"


@dataclass(frozen=True)
class DepthModel:
    """Parameters of the simulated depth sensor (see the module docs)."""

    sigma_base: float = 0.0012
    sigma_quadratic: float = 0.0019
    sigma_reference: float = 0.4
    quantum: float = 0.001
    transparent_background: float = 0.6
    transparent_missing: float = 0.3
    specular_missing: float = 0.35
    specular_outliers: float = 0.05
    blob_downsample: int = 8
    ideal: bool = False

    def __post_init__(self) -> None:
        for name in (
            "transparent_background",
            "transparent_missing",
            "specular_missing",
            "specular_outliers",
        ):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"DepthModel.{name} must be in [0, 1], got {v}")
        if self.transparent_background + self.transparent_missing > 1.0:
            raise ValueError("transparent_background + transparent_missing must be <= 1")
        if self.blob_downsample < 1:
            raise ValueError(f"blob_downsample must be >= 1, got {self.blob_downsample}")

    def sigma(self, z: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """Axial noise standard deviation (m) at depth ``z`` (m)."""
        out = self.sigma_base + self.sigma_quadratic * (z - self.sigma_reference) ** 2
        return out.astype(np.float32)

    def _blobs(self, rng: np.random.Generator, shape: tuple[int, int]) -> npt.NDArray[np.float64]:
        k = self.blob_downsample
        h, w = shape
        coarse = rng.random(((h + k - 1) // k, (w + k - 1) // k))
        return np.repeat(np.repeat(coarse, k, axis=0), k, axis=1)[:h, :w]

    def _noisy(
        self, rng: np.random.Generator, z: npt.NDArray[np.float32]
    ) -> npt.NDArray[np.float32]:
        noisy = z + rng.standard_normal(z.shape).astype(np.float32) * self.sigma(z)
        if self.quantum > 0:
            noisy = np.round(noisy / self.quantum) * self.quantum
        return np.where(z > 0, noisy, 0.0).astype(np.float32)

    def apply(
        self,
        rng: np.random.Generator,
        depth: npt.NDArray[np.float32],
        background: npt.NDArray[np.float32],
        category_map: npt.NDArray[np.int8],
    ) -> npt.NDArray[np.float32]:
        """The sensor's depth image.

        Parameters
        ----------
        rng
            Source of noise.
        depth
            Ideal depth (m), float32 ``(H, W)``, 0 where nothing is hit.
        background
            Ideal depth with the transparent objects removed, float32 ``(H, W)``.
        category_map
            int8 ``(H, W)``: -1 for background (table), else the index of the pixel's
            object category in ``list(Category)``.

        Returns
        -------
        numpy.ndarray
            float32 ``(H, W)`` depth in metres, 0 where the sensor returns nothing.
        """
        if depth.shape != background.shape or depth.shape != category_map.shape:
            raise ValueError(
                f"depth {depth.shape}, background {background.shape} and category_map "
                f"{category_map.shape} must have one shape"
            )
        if self.ideal:
            return depth.astype(np.float32, copy=True)
        cats = list(Category)
        transparent = category_map == cats.index(Category.TRANSPARENT)
        specular = category_map == cats.index(Category.SPECULAR)
        out = self._noisy(rng, depth)
        shape = (depth.shape[0], depth.shape[1])
        # Transparent: see-through, missing, or (rarely) the surface itself.
        field = self._blobs(rng, shape)
        see_through = transparent & (field < self.transparent_background)
        missing = (
            transparent
            & (field >= self.transparent_background)
            & (field < self.transparent_background + self.transparent_missing)
        )
        out = np.where(see_through, self._noisy(rng, background), out)
        out[missing] = 0.0
        # Specular: holes and outliers.
        field = self._blobs(rng, shape)
        holes = specular & (field < self.specular_missing)
        outliers = specular & ~holes & (rng.random(shape) < self.specular_outliers)
        out[outliers] += rng.uniform(-0.05, 0.15, size=int(outliers.sum())).astype(np.float32)
        out[holes] = 0.0
        return out.astype(np.float32)
