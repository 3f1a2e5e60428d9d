"""Seed 001's discrete viewsphere (viewsphere.sphere): steps, fallbacks, the polar limit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from heapgrasp.viewsphere.sphere import (
    DIRECTIONS,
    START,
    DiscreteViewsphere,
    SpherePose,
    fallback_order,
)

SPHERE = DiscreteViewsphere()
STEP = math.radians(20.0)


def _poses(n: int, seed: int = 0) -> list[SpherePose]:
    rng = np.random.default_rng(seed)
    return [
        SpherePose(float(a), float(p))
        for a, p in zip(rng.uniform(0, 2 * math.pi, n), rng.uniform(0.05, 1.45, n), strict=True)
    ]


def test_the_defaults_are_seed_001s():
    assert SPHERE.radius == 0.40 and math.isclose(SPHERE.step, STEP)
    assert math.isclose(SPHERE.max_polar, math.radians(85.0))
    assert START == SpherePose(math.pi, math.pi / 7)
    assert DIRECTIONS == ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


@pytest.mark.parametrize("direction", range(8))
def test_every_step_is_20_degrees_of_arc_on_the_sphere(direction):
    for pose in _poses(50, seed=direction):
        nxt = SPHERE.step_from(pose, direction)
        assert math.isclose(SPHERE.arc(pose, nxt), STEP, abs_tol=1e-9)
        assert math.isclose(
            float(np.linalg.norm(SPHERE.position(nxt))), SPHERE.radius, rel_tol=1e-12
        )


def test_the_eight_directions_are_45_degrees_apart_clockwise_from_north():
    pose = SpherePose(0.7, 1.0)
    here = SPHERE.position(pose)
    moves = [SPHERE.position(SPHERE.step_from(pose, d)) - here for d in range(8)]
    # Headings in the tangent plane: north toward the pole, east toward more azimuth.
    north = SPHERE.position(SpherePose(0.7, 1.0 - 1e-6)) - here
    east = SPHERE.position(SpherePose(0.7 + 1e-6, 1.0)) - here
    north /= np.linalg.norm(north)
    east /= np.linalg.norm(east)
    headings = [math.degrees(math.atan2(m @ east, m @ north)) % 360 for m in moves]
    np.testing.assert_allclose(headings, [0, 45, 90, 135, 180, 225, 270, 315], atol=0.5)


def test_north_and_south_follow_the_meridian_and_east_the_equator():
    n = SPHERE.step_from(SpherePose(1.0, 1.0), 0)
    assert math.isclose(n.azimuth, 1.0) and math.isclose(n.polar, 1.0 - STEP)
    s = SPHERE.step_from(SpherePose(1.0, 1.0), 4)
    assert math.isclose(s.azimuth, 1.0) and math.isclose(s.polar, 1.0 + STEP)
    e = SPHERE.step_from(SpherePose(1.0, math.pi / 2), 2)
    assert math.isclose(e.azimuth, 1.0 + STEP) and math.isclose(e.polar, math.pi / 2)


def test_a_step_across_the_pole_comes_down_on_the_other_side():
    near = SpherePose(0.3, math.radians(10.0))
    over = SPHERE.step_from(near, 0)
    assert math.isclose(over.polar, math.radians(10.0), abs_tol=1e-9)
    assert math.isclose(over.azimuth, 0.3 + math.pi, abs_tol=1e-9)
    # Onto the pole exactly, and on: the meridian is kept.
    on = SPHERE.step_from(SpherePose(0.3, STEP), 0)
    assert on.polar == 0.0 and on.azimuth == 0.3
    beyond = SPHERE.step_from(on, 0)
    assert math.isclose(beyond.polar, STEP) and math.isclose(beyond.azimuth, 0.3 + math.pi)
    assert np.isfinite(SPHERE.position(SPHERE.step_from(on, 3))).all()


def test_the_polar_limit_and_the_fallback_order():
    assert fallback_order(0) == (0, 1, 7, 2, 6, 3, 5, 4)
    assert fallback_order(5) == (5, 6, 4, 7, 3, 0, 2, 1)
    low = SpherePose(2.0, math.radians(80.0))
    assert not SPHERE.valid(SPHERE.step_from(low, 4))  # S: 100°
    taken, nxt = SPHERE.move(low, 4)
    # S, SW and SE go below 85°; W (d+2) is the first that stays above it.
    assert taken == 6 and SPHERE.valid(nxt)
    for d in (5, 3):
        assert not SPHERE.valid(SPHERE.step_from(low, d))
    assert SPHERE.move(START, 1) == (1, SPHERE.step_from(START, 1))
    tight = DiscreteViewsphere(max_polar=math.radians(1.0))
    with pytest.raises(ValueError, match="no step from"):
        tight.move(SpherePose(0.0, 0.0), 0)


def test_the_camera_looks_at_the_centre():
    sphere = DiscreteViewsphere(centre=(0.5, -0.1, 0.02))
    for pose in _poses(10):
        cam = sphere.camera_pose(pose)
        to_centre = np.asarray(sphere.centre) - cam[:3, 3]
        np.testing.assert_allclose(cam[:3, 2], to_centre / np.linalg.norm(to_centre), atol=1e-12)
        back = sphere.pose_of(cam[:3, 3])
        assert math.isclose(back.polar, pose.polar, abs_tol=1e-9)
        assert math.isclose(back.azimuth, pose.azimuth, abs_tol=1e-9)


def test_bad_values_are_named():
    with pytest.raises(ValueError, match="direction must be an int in"):
        SPHERE.step_from(START, 8)
    with pytest.raises(ValueError, match="direction must be an int in"):
        fallback_order(-1)
    with pytest.raises(ValueError, match="radius"):
        DiscreteViewsphere(radius=0.0)
    with pytest.raises(ValueError, match="step must be in"):
        DiscreteViewsphere(step=4.0)
    with pytest.raises(ValueError, match="max_polar must be in"):
        DiscreteViewsphere(max_polar=-1.0)
    with pytest.raises(ValueError, match="centre must be 3 numbers"):
        DiscreteViewsphere(centre=(0.0, 0.0))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="position must differ from the centre"):
        SPHERE.pose_of(SPHERE.centre)
