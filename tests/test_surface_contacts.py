"""Antipodal contacts on a TSDF's normals (heapgrasp.planning.surface_contacts)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.planning.surface_contacts import TsdfContactCheck

FRAME = GridFrame((0.0, 0.0, 0.0), 0.3, 40)  # 7.5 mm voxels
CENTRE = np.array([0.15, 0.15, 0.15])
TRUNCATION = 0.03


def plate_tsdf(tilt_deg: float, thickness: float = 0.06) -> tuple[np.ndarray, np.ndarray]:
    """A TSDF of a wide plate through the cube's centre whose normal is y turned by
    ``tilt_deg`` about x, seen everywhere."""
    t = math.radians(tilt_deg)
    normal = np.array([0.0, math.cos(t), math.sin(t)])
    idx = np.indices((40, 40, 40)).reshape(3, -1).T
    centres = FRAME.centers(idx)
    d = np.abs((centres - CENTRE) @ normal) - thickness / 2
    values = np.clip(d / TRUNCATION, -1.0, 1.0).reshape(40, 40, 40).astype(np.float32)
    return values, np.ones_like(values)


def grasp_closing_along_y() -> np.ndarray:
    """A top-down grasp (approach -z) at the centre whose fingers close along world y."""
    pose = np.eye(4)
    pose[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]).T
    pose[:3, 3] = CENTRE
    return pose[None]


@pytest.mark.parametrize(("tilt", "rejected"), [(0, False), (30, False), (60, True), (75, True)])
def test_contacts_outside_the_friction_cone_are_rejected(tilt: float, rejected: bool) -> None:
    values, weights = plate_tsdf(tilt)
    check = TsdfContactCheck(values, weights, FRAME, friction=1.0)  # a 45° cone
    assert check(grasp_closing_along_y()).tolist() == [rejected]


def test_more_friction_widens_the_cone() -> None:
    values, weights = plate_tsdf(60)
    assert not TsdfContactCheck(values, weights, FRAME, friction=2.0)(grasp_closing_along_y())[0]


def test_fingers_that_meet_nothing_are_left_to_the_collision_check() -> None:
    values, weights = plate_tsdf(0)
    free = np.ones_like(values)  # free space everywhere
    assert not TsdfContactCheck(free, weights, FRAME)(grasp_closing_along_y())[0]
    assert TsdfContactCheck(values, weights, FRAME)(np.zeros((0, 4, 4))).shape == (0,)


def test_bad_input_is_named() -> None:
    values, weights = plate_tsdf(0)
    with pytest.raises(ValueError, match="values and weights"):
        TsdfContactCheck(values[:-1], weights, FRAME)
    with pytest.raises(ValueError, match="friction"):
        TsdfContactCheck(values, weights, FRAME, friction=-1.0)
    with pytest.raises(ValueError, match="tcp2world"):
        TsdfContactCheck(values, weights, FRAME)(np.eye(4))
