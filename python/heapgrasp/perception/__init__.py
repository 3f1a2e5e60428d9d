"""Perception (HEAPGrasp §IV-A): frames, segmenters, Shape from Silhouette, TSDF.

* :mod:`~heapgrasp.perception.frames` — what a camera delivers (:class:`Frame`,
  :class:`Capture`);
* :mod:`~heapgrasp.perception.segmenters` — frame → silhouette;
* :mod:`~heapgrasp.perception.silhouette` — SfS occupancy grid (eq. 9-10) and ``Ŝ≥λ``;
* :mod:`~heapgrasp.perception.roofs` — roof trimming and the silhouette check;
* :mod:`~heapgrasp.perception.depth` — the VGN baseline's depth → TSDF.
"""
