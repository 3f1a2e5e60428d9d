"""Hand-eye calibration (issue 41) on synthetic ChArUco images rendered at known poses:
board detection, the rendering's pixel convention, the arm poses, every
``cv2.calibrateHandEye`` method against the issue's target (extrinsic to ≤ 1 mm and
≤ 0.1°), and the errors bad input gives."""

from __future__ import annotations

import json
import math
import sys
import types
from typing import Any

import cv2
import numpy as np
import pytest
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.robot.calibration import (
    HAND_EYE_METHODS,
    CharucoBoard,
    HandEyeResult,
    calibrate,
    calibration_poses,
    detect_board,
    render_board,
    solve_hand_eye,
)
from scipy.spatial.transform import Rotation

CAMERA = CameraSpec.still()  # 640x480, fx = fy = 540
BOARD = CharucoBoard()
F64 = np.ndarray[Any, np.dtype[np.float64]]


def pose(rotvec: list[float], t: list[float]) -> F64:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    out[:3, 3] = t
    return out


def errors(a: F64, b: F64) -> tuple[float, float]:
    """Translation (mm) and rotation (degrees) between two poses."""
    d = np.linalg.inv(a) @ b
    mm = 1000.0 * float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    return mm, float(np.degrees(Rotation.from_matrix(d[:3, :3]).magnitude()))


# The true extrinsic: the camera 3 cm to the side of and 6 cm ahead of the flange, turned
# by 0.1 rad about every axis; the guess knows only the translation roughly.
CAM2TCP = pose([0.1, -0.1, 0.1], [0.03, -0.02, 0.06])
GUESS = pose([0.0, 0.0, 0.0], [0.03, 0.0, 0.05])
# The board face up on the table (its z into the table), turned by 0.3 rad.
BOARD2BASE = pose([math.pi, 0.0, 0.3], [0.45, -0.12, 0.01])


def view(tcp2base: F64) -> F64:
    """board2cam seen from the TCP pose through the true extrinsic."""
    return np.linalg.inv(tcp2base @ CAM2TCP) @ BOARD2BASE


@pytest.fixture(scope="module")
def rehearsal() -> tuple[list[F64], list[np.ndarray[Any, np.dtype[np.uint8]]]]:
    """15 arm poses and the images the wrist camera takes there."""
    tcps = calibration_poses(BOARD2BASE, GUESS, n=15, seed=3)
    return tcps, [render_board(BOARD, CAMERA, view(t)) for t in tcps]


# --------------------------------------------------------------------------- the board


def test_board_validation_names_the_value() -> None:
    with pytest.raises(ValueError, match=r"marker \(0\.04\).*square \(0\.04\)"):
        CharucoBoard(marker=0.04)
    with pytest.raises(ValueError, match="squares_y must be an integer >= 3, got 2"):
        CharucoBoard(squares_y=2)
    with pytest.raises(ValueError, match="DICT_5X5_9"):
        CharucoBoard(dictionary="DICT_5X5_9")
    with pytest.raises(ValueError, match=r"holds 50 markers.*needs 60"):
        CharucoBoard(squares_x=11, squares_y=11, dictionary="DICT_4X4_50")
    with pytest.raises(ValueError, match="square must be finite and > 0"):
        CharucoBoard(square=-0.04)


def test_board_image_and_frame() -> None:
    img = BOARD.image(pixels_per_square=40, margin=10)
    assert img.dtype == np.uint8 and img.shape == (5 * 40 + 20, 7 * 40 + 20)
    assert img[:10].min() == 255 and img[:, :10].min() == 255  # white margin
    assert img[10:50, 10:50].max() == 0  # the square at the origin is black
    assert img[10:50, 50:90].mean() > 100  # the next one along x holds a marker
    # The documented frame: inner corner (i, j) at (i, j) squares.
    corners = BOARD.cv().getChessboardCorners()
    assert np.allclose(corners[0], [0.04, 0.04, 0.0]) and np.allclose(corners[1], [0.08, 0.04, 0])
    assert np.allclose(BOARD.center, [0.14, 0.10, 0.0])


# --------------------------------------------------------------------------- detection


def facing(rotvec: list[float], distance: float, shift: tuple[float, float] = (0, 0)) -> F64:
    """board2cam with the board's centre ``distance`` ahead of the camera (+ ``shift``)."""
    out = pose(rotvec, [0.0, 0.0, 0.0])
    out[:3, 3] = [shift[0], shift[1], distance] - out[:3, :3] @ BOARD.center
    return out


@pytest.mark.parametrize(
    "board2cam",
    [
        facing([0.0, 0.0, 0.0], 0.40),  # frontal
        facing([0.45, -0.3, 0.2], 0.45, (0.02, -0.01)),  # tilted
        facing([-0.3, 0.4, 2.5], 0.55),  # rolled upside down, far
    ],
)
def test_detect_recovers_board_pose(board2cam: F64) -> None:
    img = render_board(BOARD, CAMERA, board2cam)
    obs = detect_board(img, BOARD, CAMERA)
    assert obs is not None and obs.corners == 24
    mm, deg = errors(obs.board2cam, board2cam)
    assert mm < 0.5 and deg < 0.1, (mm, deg)
    assert obs.reprojection_px < 0.15
    # The rendering is exact with the pixel convention (centres at integers): the
    # corners OpenCV finds lie where the true pose projects them.
    corners, ids, _, _ = cv2.aruco.CharucoDetector(BOARD.cv()).detectBoard(img)
    obj = BOARD.cv().getChessboardCorners()[ids.ravel()].astype(np.float64)
    cam = obj @ board2cam[:3, :3].T + board2cam[:3, 3]
    uv = np.column_stack(
        [
            CAMERA.fx * cam[:, 0] / cam[:, 2] + CAMERA.cx,
            CAMERA.fy * cam[:, 1] / cam[:, 2] + CAMERA.cy,
        ]
    )
    offset = corners.reshape(-1, 2) - uv
    assert np.abs(offset.mean(axis=0)).max() < 0.05  # no half-pixel bias
    assert np.abs(offset).max() < 0.25


def test_detect_colour_and_noise() -> None:
    board2cam = pose([0.3, 0.2, -0.4], [-0.13, -0.09, 0.42])
    grey = render_board(BOARD, CAMERA, board2cam, noise=3.0, seed=1)
    colour = np.repeat(grey[:, :, None], 3, axis=2)
    a, b = detect_board(grey, BOARD, CAMERA), detect_board(colour, BOARD, CAMERA)
    assert a is not None and b is not None
    assert np.allclose(a.board2cam, b.board2cam)
    mm, deg = errors(a.board2cam, board2cam)
    assert mm < 1.0 and deg < 0.1, (mm, deg)


def test_board_not_in_view_is_none() -> None:
    blank = np.full((CAMERA.height, CAMERA.width), 200, np.uint8)
    assert detect_board(blank, BOARD, CAMERA) is None
    aside = pose([0.0, 0.0, 0.0], [0.5, 0.0, 0.4])  # far off to the right
    img = render_board(BOARD, CAMERA, aside)
    assert img.min() == 200  # nothing of the board drawn
    assert detect_board(img, BOARD, CAMERA) is None
    # Only a corner of the board in view: fewer than 6 corners.
    edge = pose([0.0, 0.0, 0.0], [0.156, 0.104, 0.35])
    assert detect_board(render_board(BOARD, CAMERA, edge), BOARD, CAMERA) is None


def test_detect_and_render_bad_input() -> None:
    img = render_board(BOARD, CAMERA, pose([0, 0, 0], [-0.14, -0.1, 0.4]))
    with pytest.raises(ValueError, match=r"uint8.*float64"):
        detect_board(img.astype(np.float64), BOARD, CAMERA)
    with pytest.raises(ValueError, match="320x240, the camera's 640x480"):
        detect_board(img[::2, ::2], BOARD, CAMERA)
    with pytest.raises(ValueError, match=r"\(H, W\) or \(H, W, 3\)"):
        detect_board(np.zeros((480, 640, 2), np.uint8), BOARD, CAMERA)
    with pytest.raises(ValueError, match="distortion"):
        detect_board(img, BOARD, CAMERA, distortion=[0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="behind the camera"):
        render_board(BOARD, CAMERA, pose([0, 0, 0], [-0.14, -0.1, -0.4]))
    with pytest.raises(ValueError, match="board2cam is not rigid"):
        render_board(BOARD, CAMERA, np.diag([1.0, 2.0, 1.0, 1.0]))


# --------------------------------------------------------------------------- arm poses


def test_calibration_poses_look_at_the_board() -> None:
    tcps = calibration_poses(BOARD2BASE, GUESS, n=12, distance=(0.3, 0.6), max_tilt_deg=30)
    assert len(tcps) == 12
    again = calibration_poses(BOARD2BASE, GUESS, n=12, distance=(0.3, 0.6), max_tilt_deg=30)
    assert all(np.array_equal(a, b) for a, b in zip(tcps, again, strict=True))
    other = calibration_poses(BOARD2BASE, GUESS, n=12, distance=(0.3, 0.6), seed=1)
    assert not np.allclose(tcps[5], other[5])
    centre = BOARD2BASE[:3, :3] @ BOARD.center + BOARD2BASE[:3, 3]
    normal = BOARD2BASE[:3, 2]  # into the table
    axes = []
    for t in tcps:
        cam = t @ GUESS
        to_centre = centre - cam[:3, 3]
        dist = float(np.linalg.norm(to_centre))
        assert 0.3 - 1e-9 <= dist <= 0.6 + 1e-9
        assert np.allclose(cam[:3, 2], to_centre / dist)  # optical axis on the centre
        assert math.degrees(math.acos(min(1.0, float(cam[:3, 2] @ normal)))) <= 30 + 1e-9
        assert np.allclose(cam[:3, :3].T @ cam[:3, :3], np.eye(3))
        axes.append(Rotation.from_matrix(cam[:3, :3] @ tcps[0][:3, :3].T).as_rotvec())
    # Rotation diversity: the relative rotation axes span all three directions.
    assert np.linalg.svd(np.array(axes[1:]), compute_uv=False)[2] > 0.05
    with pytest.raises(ValueError, match="n must be an integer >= 3, got 2"):
        calibration_poses(BOARD2BASE, GUESS, n=2)
    with pytest.raises(ValueError, match="distance"):
        calibration_poses(BOARD2BASE, GUESS, distance=(0.5, 0.3))
    with pytest.raises(ValueError, match="max_tilt_deg"):
        calibration_poses(BOARD2BASE, GUESS, max_tilt_deg=95)


# --------------------------------------------------------------------------- hand-eye


def test_calibrate_recovers_extrinsic(
    rehearsal: tuple[list[F64], list[np.ndarray[Any, np.dtype[np.uint8]]]],
) -> None:
    tcps, images = rehearsal
    result, observations = calibrate(images, tcps, BOARD, CAMERA)
    assert all(o is not None for o in observations)
    mm, deg = errors(result.cam2tcp, CAM2TCP)
    assert mm <= 1.0 and deg <= 0.1, (mm, deg)  # the target
    mm, deg = errors(result.board2base, BOARD2BASE)
    assert mm <= 1.0 and deg <= 0.1, (mm, deg)
    assert set(result.methods) == set(HAND_EYE_METHODS)
    assert result.method in HAND_EYE_METHODS
    best = result.methods[result.method]["mean_mm"]
    assert best == min(s["mean_mm"] for s in result.methods.values())
    assert result.residuals_mm.shape == result.residuals_deg.shape == (15,)
    assert np.isclose(result.residuals_mm.mean(), best)
    assert result.residuals_mm.max() < 1.0 and result.residuals_deg.max() < 0.1
    # Every method, on its own, meets the target on this set.
    board2cam = [o.board2cam for o in observations if o is not None]
    for method in HAND_EYE_METHODS:
        alone = solve_hand_eye(tcps, board2cam, method=method)
        assert alone.method == method and set(alone.methods) == {method}
        mm, deg = errors(alone.cam2tcp, CAM2TCP)
        assert mm <= 1.0 and deg <= 0.1, (method, mm, deg)


def test_residuals_flag_a_bad_pose(
    rehearsal: tuple[list[F64], list[np.ndarray[Any, np.dtype[np.uint8]]]],
) -> None:
    tcps, _ = rehearsal
    board2cam = [view(t) for t in tcps]
    wrong = list(tcps)
    wrong[4] = wrong[4] @ pose([0.0, 0.0, 0.0], [0.01, 0.0, 0.0])  # the arm 1 cm off
    result = solve_hand_eye(wrong, board2cam, method="park")
    assert int(np.argmax(result.residuals_mm)) == 4
    exact = solve_hand_eye(tcps, board2cam, method="park")  # noiseless board poses
    mm, deg = errors(exact.cam2tcp, CAM2TCP)
    assert mm < 1e-3 and deg < 1e-4


def test_calibrate_drops_images_without_the_board(
    rehearsal: tuple[list[F64], list[np.ndarray[Any, np.dtype[np.uint8]]]],
) -> None:
    tcps, images = rehearsal
    blank = np.full_like(images[0], 200)
    some = [blank, *images[1:5], blank]
    result, observations = calibrate(some, tcps[:6], BOARD, CAMERA, method="tsai")
    assert observations[0] is None and observations[5] is None
    assert all(o is not None for o in observations[1:5])
    assert result.residuals_mm.shape == (4,)
    with pytest.raises(ValueError, match="detected in 2 of 4 images"):
        calibrate([blank, images[1], images[2], blank], tcps[:4], BOARD, CAMERA)
    with pytest.raises(ValueError, match="3 images but 4 tcp2base"):
        calibrate(images[:3], tcps[:4], BOARD, CAMERA)


def test_solve_hand_eye_bad_input(
    rehearsal: tuple[list[F64], list[np.ndarray[Any, np.dtype[np.uint8]]]],
) -> None:
    tcps, _ = rehearsal
    board2cam = [view(t) for t in tcps]
    with pytest.raises(ValueError, match="at least 3 poses, got 2"):
        solve_hand_eye(tcps[:2], board2cam[:2])
    sheared = [*tcps[:5]]
    sheared[3] = sheared[3].copy()
    sheared[3][0, 1] += 0.01
    with pytest.raises(ValueError, match=r"tcp2base\[3\] is not rigid"):
        solve_hand_eye(sheared, board2cam[:5])
    bad = [*board2cam[:5]]
    bad[2] = bad[2].copy()
    bad[2][1, 3] = np.nan
    with pytest.raises(ValueError, match=r"board2cam\[2\] must be finite"):
        solve_hand_eye(tcps[:5], bad)
    with pytest.raises(ValueError, match=r"board2cam\[0\].*shape \(3, 3\)"):
        solve_hand_eye(tcps[:3], [np.eye(3)] * 3)
    with pytest.raises(ValueError, match="5 tcp2base poses but 4 board2cam"):
        solve_hand_eye(tcps[:5], board2cam[:4])
    with pytest.raises(ValueError, match="'lsq'"):
        solve_hand_eye(tcps, board2cam, method="lsq")


def test_result_round_trip(
    rehearsal: tuple[list[F64], list[np.ndarray[Any, np.dtype[np.uint8]]]],
) -> None:
    tcps, _ = rehearsal
    result = solve_hand_eye(tcps[:6], [view(t) for t in tcps[:6]])
    data = json.loads(json.dumps(result.to_dict()))
    back = HandEyeResult.from_dict(data)
    assert back.method == result.method and back.methods == result.methods
    for name in ("cam2tcp", "board2base", "residuals_mm", "residuals_deg"):
        assert np.array_equal(getattr(back, name), getattr(result, name))
    del data["cam2tcp"]
    with pytest.raises(ValueError, match="lacks 'cam2tcp'"):
        HandEyeResult.from_dict(data)
    with pytest.raises(ValueError, match="cam2tcp is not rigid"):
        HandEyeResult.from_dict({**result.to_dict(), "cam2tcp": np.full((4, 4), 0.5).tolist()})


def test_opencv_missing_or_5x(monkeypatch: pytest.MonkeyPatch) -> None:
    tcps = calibration_poses(BOARD2BASE, GUESS, n=3)
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 -> ImportError
    with pytest.raises(ImportError, match=r"pip install 'heapgrasp\[robot\]'"):
        solve_hand_eye(tcps, [view(t) for t in tcps])
    monkeypatch.setitem(sys.modules, "cv2", types.SimpleNamespace(__version__="5.0.0"))
    with pytest.raises(ImportError, match=r"4\.x.*found cv2 5\.0\.0.*lacks calibrateHandEye"):
        solve_hand_eye(tcps, [view(t) for t in tcps])
