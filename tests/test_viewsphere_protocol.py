"""Seed 001's test protocol (viewsphere.protocol): the yaw lists and resting poses."""

from __future__ import annotations

import math

import pytest
from heapgrasp.viewsphere.protocol import REST_POSES, YAWS_DEG, protocol_yaws


@pytest.mark.parametrize("top", [89, 179, 359])
def test_each_list_holds_100_yaws_in_its_range_starting_with_the_multiples_of_45(top):
    yaws = YAWS_DEG[top]
    assert len(yaws) == 100 and min(yaws) >= 0 and max(yaws) <= top
    multiples = list(range(0, top + 1, 45))
    assert list(yaws[: len(multiples)]) == multiples


def test_the_published_lists_as_given():
    # A few entries and sums, so that a changed digit is caught.
    assert YAWS_DEG[89][:8] == (0, 45, 33, 50, 15, 28, 1, 77) and sum(YAWS_DEG[89]) == 4617
    assert YAWS_DEG[179][-3:] == (138, 173, 125) and sum(YAWS_DEG[179]) == 8544
    assert YAWS_DEG[359][8:12] == (101, 255, 294, 273) and sum(YAWS_DEG[359]) == 17438


def test_the_twelve_test_objects_and_their_yaws():
    assert len(REST_POSES) == 12
    assert all(p.yaw_range in YAWS_DEG for p in REST_POSES.values())
    pudding = REST_POSES["008_pudding_box"]
    assert (pudding.z, pudding.roll, pudding.pitch) == (0.06, -1.468, 1.0788)
    yaws = protocol_yaws(179, poses=5)
    assert yaws == tuple(math.radians(d) for d in (0, 45, 90, 135, 103))
    assert len(protocol_yaws(359)) == 100
    with pytest.raises(ValueError, match="yaw_range must be one of 89, 179, 359"):
        protocol_yaws(90)
    with pytest.raises(ValueError, match=r"poses must be an int in \[1, 100\]"):
        protocol_yaws(89, poses=101)
