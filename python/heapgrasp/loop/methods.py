"""What the loop needs to know of a method (§VI-B): :class:`Method`, read from a
:class:`~heapgrasp.loop.config.RunConfig`'s names once by :func:`method_of`.

HEAPGrasp (``heapgrasp``: silhouettes, eq. 14-19's planned views), its ablations
(``no-vp``: the fixed circle; ``hemisphere6``: six fixed views) and the VGN baseline
(``vgn``: depth, a TSDF, the circle) differ in what they sense, the grid they grasp on
and how they choose views; the pipeline, the simulator's camera and the robot's set-up
read those fields, never the names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from heapgrasp.loop.config import RunConfig

__all__ = ["Method", "method_of"]


@dataclass(frozen=True)
class Method:
    """What the loop needs to know of a method (§VI-B), read from the configuration once
    by :func:`method_of`."""

    name: str
    """The method's name (``RunConfig.method``), for records and labels only."""
    depth: bool
    """It senses depth and fuses a TSDF (the VGN baseline), else silhouettes (eq. 10)."""
    grid: Literal["occupancy", "tsdf"]
    """The grid its grasp planner reads."""
    views: Literal["planned", "circle", "hemisphere6"]
    """``planned``: eq. 14-19 with a view scorer at every waypoint; else the fixed
    waypoints of that pattern (:func:`~heapgrasp.planning.views.fixed_waypoints`)."""
    view_planner: str | None
    """The view planner named in the configuration, where the method has one (HEAPGrasp);
    for records and labels only."""
    rgb: bool
    """Its segmenter reads colour frames (the segmentation network)."""
    oracle_views: bool
    """Its view scorer reads the true meshes (the oracle): simulation only."""
    true_silhouettes: bool
    """Its silhouettes come from the scene truth (the simulator's segmenters)."""


def method_of(config: RunConfig) -> Method:
    """The :class:`Method` of ``config`` (its ``method``, ``view_planner`` and
    ``segmenter``)."""
    name = config.method
    depth = name == "vgn"
    views: Literal["planned", "circle", "hemisphere6"]
    if name == "heapgrasp":
        vp = config.view_planner
        if vp in ("oracle", "network"):
            views = "planned"
        else:
            views = "hemisphere6" if vp == "hemisphere6" else "circle"
    else:
        views = "hemisphere6" if name == "hemisphere6" else "circle"
    segments = not depth
    return Method(
        name=name,
        depth=depth,
        grid="tsdf" if depth else "occupancy",
        views=views,
        view_planner=config.view_planner if name == "heapgrasp" else None,
        rgb=segments and config.segmenter == "network",
        oracle_views=views == "planned" and config.view_planner == "oracle",
        true_silhouettes=segments and config.segmenter == "truth",
    )
