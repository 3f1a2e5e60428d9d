"""Segmenters: a captured frame → its binary silhouette (True = object).

A real robot segments the RGB image (the 4-class network of the hardware issue plugs in
through :class:`Segmenter`). The simulator's segmenters read the silhouette from the
scene truth instead (:class:`MaskSource`, implemented by ``heapgrasp.sim``):

* :class:`IdealSegmenter` — the exact silhouettes;
* :class:`NoisySegmenter` — exact silhouettes with each pixel flipped with probability
  ``p`` (HEAPGrasp Table V).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from heapgrasp.perception.frames import Frame

__all__ = ["IdealSegmenter", "MaskSource", "NoisySegmenter", "Segmenter"]


@runtime_checkable
class Segmenter(Protocol):
    """Frame → binary silhouette ``(H, W)`` (True = object)."""

    name: str

    def segment(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The silhouette of ``frame``."""
        ...


@runtime_checkable
class MaskSource(Protocol):
    """Where exact silhouettes come from: the simulator's scene truth."""

    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The exact ``(H, W)`` silhouette of ``frame`` (True where an object is seen)."""
        ...


class IdealSegmenter:
    """The exact silhouettes of a :class:`MaskSource` (ground truth)."""

    name = "ideal"

    def __init__(self, truth: MaskSource) -> None:
        self.truth = truth

    def segment(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The exact silhouette of ``frame``."""
        return self.truth.silhouette(frame)


class NoisySegmenter:
    """Ideal masks with every pixel flipped independently with probability ``p``
    (HEAPGrasp Table V)."""

    name = "noisy"

    def __init__(self, truth: MaskSource, p: float, seed: int = 0) -> None:
        self.truth = truth
        if not (0.0 <= p <= 0.5):
            raise ValueError(f"noise probability p must be in [0, 0.5], got {p}")
        self.p = float(p)
        self.rng = np.random.default_rng(seed)

    def segment(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The exact silhouette XOR Bernoulli(p) noise."""
        mask = self.truth.silhouette(frame)
        if self.p == 0.0:
            return mask
        flips = self.rng.random(mask.shape) < self.p
        return np.logical_xor(mask, flips)
