"""What the loop reads of a method (heapgrasp.loop.methods): one place maps the names."""

from __future__ import annotations

from pathlib import Path

import pytest
from heapgrasp.loop.config import RunConfig
from heapgrasp.loop.methods import method_of


@pytest.mark.parametrize(
    ("settings", "depth", "grid", "views", "view_planner"),
    [
        ({"method": "heapgrasp"}, False, "occupancy", "planned", "network"),
        (
            {"method": "heapgrasp", "view_planner": "oracle"},
            False,
            "occupancy",
            "planned",
            "oracle",
        ),
        ({"method": "heapgrasp", "view_planner": "circle"}, False, "occupancy", "circle", "circle"),
        (
            {"method": "heapgrasp", "view_planner": "hemisphere6"},
            False,
            "occupancy",
            "hemisphere6",
            "hemisphere6",
        ),
        ({"method": "no-vp"}, False, "occupancy", "circle", None),
        ({"method": "hemisphere6"}, False, "occupancy", "hemisphere6", None),
        ({"method": "vgn"}, True, "tsdf", "circle", None),
    ],
)
def test_each_method_is_what_its_name_says(
    settings: dict[str, str], depth: bool, grid: str, views: str, view_planner: str | None
) -> None:
    m = method_of(RunConfig(**settings))
    assert (m.name, m.depth, m.grid, m.views, m.view_planner) == (
        settings["method"],
        depth,
        grid,
        views,
        view_planner,
    )
    assert m.oracle_views == (settings.get("view_planner") == "oracle")
    assert m.true_silhouettes == (not depth)  # the default segmenter reads the scene truth
    assert not m.rgb


def test_the_segmentation_network_reads_colour_and_not_the_truth(tmp_path: Path) -> None:
    weights = tmp_path / "seg.onnx"
    weights.write_bytes(b"")  # never opened: method_of reads names only
    m = method_of(RunConfig(method="no-vp", segmenter="network", seg_weights=str(weights)))
    assert m.rgb and not m.true_silhouettes
    # the depth baseline segments nothing, whatever the setting says
    assert not method_of(RunConfig(method="vgn")).rgb
