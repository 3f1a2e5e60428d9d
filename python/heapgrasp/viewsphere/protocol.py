"""Natarajan et al.'s test protocol: the objects' resting poses and the 100 yaws of each.

The public code of seed ``001_95c7dd5c6a7c3646.txt`` places each test object at the
table's centre in a fixed resting pose (a height, a roll and a pitch, for its YCB mesh)
and turns it about the vertical by 100 yaws, in a fixed order (§5.1: "100 poses per
object"). Which list an object uses depends on its symmetry: the range of yaws that
differ (0–89°, 0–179° or 0–359°). Each list starts with the multiples of 45° below its
range's maximum, then a seeded sequence, repeats included; the lists are the protocol's,
copied as published.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["REST_POSES", "YAWS_DEG", "RestPose", "protocol_yaws"]

#: The 100 yaws (degrees) of each range, keyed by the range's maximum, as published.
_PUBLISHED = {
    89: (
        "0,45,33,50,15,28,1,77,80,55,65,60,5,35,60,6,32,11,70,30,38,31,80,38,87,70,13,"
        "85,49,70,3,76,33,23,76,64,88,4,46,25,86,31,67,74,32,50,35,40,32,42,17,87,8,38,"
        "73,57,43,61,69,0,42,22,52,50,67,42,47,30,75,21,68,85,69,14,77,32,12,40,29,32,"
        "50,45,56,83,30,21,29,58,87,8,46,60,66,51,73,28,59,72,43,47"
    ),
    179: (
        "0,45,90,135,103,106,170,178,155,20,85,115,100,146,32,124,0,154,50,132,34,22,84,"
        "90,47,119,17,75,51,90,2,55,7,1,2,53,32,66,43,157,44,103,52,59,136,165,82,144,"
        "155,125,91,29,11,82,41,147,137,62,16,94,167,67,123,16,50,19,94,136,12,104,121,"
        "66,115,73,91,178,89,148,154,30,115,162,3,82,142,91,72,104,35,99,30,122,92,128,"
        "124,34,58,138,173,125"
    ),
    359: (
        "0,45,90,135,180,225,270,315,101,255,294,273,208,252,206,81,329,131,310,140,51,"
        "291,130,40,185,299,243,119,266,247,143,45,252,196,68,90,25,279,320,291,85,132,"
        "208,0,316,49,348,153,114,81,260,338,42,90,67,5,221,278,57,298,176,40,220,282,"
        "54,13,294,215,179,301,341,319,183,154,126,225,171,6,305,94,211,251,242,252,181,"
        "3,298,239,60,50,78,157,335,203,9,39,169,107,19,275"
    ),
}
YAWS_DEG: dict[int, tuple[int, ...]] = {
    top: tuple(int(d) for d in text.split(",")) for top, text in _PUBLISHED.items()
}


@dataclass(frozen=True)
class RestPose:
    """How an object rests for the protocol: the height of its origin above the table
    (m, for the YCB mesh), its roll and pitch (radians) and the range of its yaws
    (the key of :data:`YAWS_DEG`)."""

    z: float
    roll: float
    pitch: float
    yaw_range: int


#: The 12 test objects (YCB ids), as the protocol places them.
REST_POSES: dict[str, RestPose] = {
    "003_cracker_box": RestPose(0.106, 0.0, 0.0, 359),
    "005_tomato_soup_can": RestPose(0.05, 0.0, 0.0, 89),
    "006_mustard_bottle": RestPose(0.079, 0.0, 0.0, 179),
    "008_pudding_box": RestPose(0.06, -1.468, 1.0788, 179),
    "010_potted_meat_can": RestPose(0.04, 0.0, 0.0, 179),
    "013_apple": RestPose(0.04, 0.0, 0.0, 89),
    "021_bleach_cleanser": RestPose(0.1, 0.0, 0.0, 179),
    "024_bowl": RestPose(0.03, 0.0, 0.0, 89),
    "025_mug": RestPose(0.03, 0.0, 0.0, 89),
    "035_power_drill": RestPose(0.11, 1.596, 0.026, 179),
    "055_baseball": RestPose(0.036, 0.0, 0.0, 89),
    "072-a_toy_airplane": RestPose(0.092, 0.0, 0.0, 359),
}


def protocol_yaws(yaw_range: int, poses: int = 100) -> tuple[float, ...]:
    """The first ``poses`` yaws (radians) of the range ``yaw_range`` (89, 179 or 359)."""
    if yaw_range not in YAWS_DEG:
        raise ValueError(
            f"yaw_range must be one of {', '.join(map(str, YAWS_DEG))}, got {yaw_range!r}"
        )
    if not (isinstance(poses, int) and 1 <= poses <= len(YAWS_DEG[yaw_range])):
        raise ValueError(f"poses must be an int in [1, 100], got {poses!r}")
    return tuple(math.radians(d) for d in YAWS_DEG[yaw_range][:poses])
