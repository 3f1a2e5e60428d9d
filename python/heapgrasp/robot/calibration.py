"""Hand-eye calibration of the wrist camera with a ChArUco board (eye-in-hand).

HEAPGrasp's camera rides on the arm (HEAPGrasp §I, "hand-eye camera"): every silhouette
is carved along the ray of a pixel from the camera pose ``tcp2base @ cam2tcp``, so the
extrinsic ``cam2tcp`` (the camera pose in the TCP frame) has to be known to about a
millimetre. This module measures it from images of a ChArUco board lying fixed on the
table, taken from a set of arm poses:

* :class:`CharucoBoard` — the board (squares, marker size, ArUco dictionary), its
  printable image and OpenCV's ``cv2.aruco.CharucoBoard``;
* :func:`detect_board` — the board's pose in one image (``cv2.aruco.CharucoDetector``,
  ``matchImagePoints``, ``cv2.solvePnP`` refined by Levenberg–Marquardt);
* :func:`render_board` — a synthetic image of the board seen from a known pose, exact
  with the package's pixel convention (tests, and the dry rehearsal without hardware);
* :func:`calibration_poses` — TCP poses that look at the board from varied directions;
* :func:`solve_hand_eye` — ``cv2.calibrateHandEye`` with every method compared, the
  board's pose in the base frame (the workspace frame's reference) and the residual
  of every pose;
* :func:`calibrate` — detection and solution together.

Frames: poses are ``(4, 4)`` rigid transforms named ``a2b`` (maps frame ``a``
coordinates to frame ``b``); the camera frame has OpenCV axes (x right, y down, z
forward) and pixel centres at integer coordinates (:mod:`heapgrasp.geometry.camera`).
The board frame is OpenCV's ChArUco object frame (see :class:`CharucoBoard`).

OpenCV is an optional dependency (``pip install 'heapgrasp[robot]'``), imported only when
a function needs it; it must be 4.x (OpenCV 5.0 has no ``calibrateHandEye``).
"""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec

__all__ = [
    "HAND_EYE_METHODS",
    "BoardObservation",
    "CharucoBoard",
    "HandEyeResult",
    "calibrate",
    "calibration_poses",
    "detect_board",
    "render_board",
    "require_opencv",
    "solve_hand_eye",
    "world_in_board",
]

F64 = npt.NDArray[np.float64]

HAND_EYE_METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis")
"""The methods of ``cv2.calibrateHandEye``, in the order they are tried."""

MIN_CORNERS = 6
"""Fewest ChArUco corners :func:`detect_board` accepts for a pose."""

MIN_POSES = 3
"""Fewest poses :func:`solve_hand_eye` accepts (``cv2.calibrateHandEye``'s minimum)."""

_RIGID_TOLERANCE = 1e-6

# OpenCV's predefined ArUco dictionaries and how many markers each holds.
_DICTIONARIES: dict[str, int] = {
    **{f"DICT_{b}X{b}_{n}": n for b in (4, 5, 6, 7) for n in (50, 100, 250, 1000)},
    "DICT_ARUCO_ORIGINAL": 1024,
    "DICT_APRILTAG_16h5": 30,
    "DICT_APRILTAG_25h9": 35,
    "DICT_APRILTAG_36h10": 2320,
    "DICT_APRILTAG_36h11": 587,
    "DICT_ARUCO_MIP_36h12": 250,
}

_INSTALL = (
    "pip install 'heapgrasp[robot]' (opencv-python-headless>=4.8,<5; "
    "OpenCV 5.0 lacks calibrateHandEye, 4.x is needed)"
)


def require_opencv() -> None:
    """Raises the ImportError naming the extra to install where OpenCV 4.x (>= 4.7) is
    missing: for a command to say so before it starts anything."""
    _cv2()


def _cv2() -> Any:
    """The ``cv2`` module, checked to be a 4.x with ChArUco detection and hand-eye
    calibration; an ImportError naming the extra to install otherwise."""
    try:
        cv2: Any = importlib.import_module("cv2")
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ImportError(f"hand-eye calibration needs OpenCV: {_INSTALL}") from exc
    version = str(getattr(cv2, "__version__", "0"))
    try:
        major, minor = (int(x) for x in version.split(".")[:2])
    except ValueError:  # pragma: no cover - a malformed build
        major, minor = 0, 0
    if major != 4 or minor < 7:
        raise ImportError(
            f"hand-eye calibration needs OpenCV 4.x (>= 4.7), found cv2 {version}: {_INSTALL}"
        )
    if not hasattr(cv2, "calibrateHandEye") or not hasattr(
        getattr(cv2, "aruco", None), "CharucoDetector"
    ):  # pragma: no cover - a build without the contrib/aruco modules
        raise ImportError(
            f"cv2 {version} lacks aruco.CharucoDetector or calibrateHandEye: {_INSTALL}"
        )
    return cv2


# --------------------------------------------------------------------------- checks


def _as_pose(name: str, pose: npt.ArrayLike) -> F64:
    """``pose`` as a float64 ``(4, 4)`` rigid transform, or a ValueError naming ``name``."""
    try:
        arr = np.asarray(pose, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a (4, 4) rigid transform: {exc}") from None
    if arr.shape != (4, 4):
        raise ValueError(f"{name} must be a (4, 4) rigid transform, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    if not np.allclose(arr[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=_RIGID_TOLERANCE):
        raise ValueError(f"{name} is not rigid: last row {arr[3].tolist()} != [0, 0, 0, 1]")
    rot = arr[:3, :3]
    ortho = float(np.abs(rot.T @ rot - np.eye(3)).max())
    det = float(np.linalg.det(rot))
    if ortho > _RIGID_TOLERANCE or abs(det - 1.0) > _RIGID_TOLERANCE:
        raise ValueError(
            f"{name} is not rigid: its rotation block is not orthonormal with det +1 "
            f"(|RᵀR − I| = {ortho:.2g}, det = {det:.6g})"
        )
    out = arr.copy()
    out[3] = [0.0, 0.0, 0.0, 1.0]
    return out


def _as_poses(name: str, poses: Sequence[npt.ArrayLike]) -> list[F64]:
    if isinstance(poses, np.ndarray) and poses.ndim == 2:
        raise ValueError(f"{name} must be a sequence of (4, 4) poses, got one of shape (4, 4)")
    return [_as_pose(f"{name}[{i}]", p) for i, p in enumerate(poses)]


def _int_at_least(name: str, value: int, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return v


def _project_rotation(rot: npt.ArrayLike) -> F64:
    """The rotation matrix nearest ``rot`` (SVD projection onto SO(3))."""
    u, _, vt = np.linalg.svd(np.asarray(rot, dtype=np.float64))
    d = np.sign(np.linalg.det(u @ vt))
    return np.asarray(u @ np.diag([1.0, 1.0, d]) @ vt, dtype=np.float64)


def _pose(rot: npt.ArrayLike, trans: npt.ArrayLike) -> F64:
    out = np.eye(4)
    out[:3, :3] = np.asarray(rot, dtype=np.float64)
    out[:3, 3] = np.asarray(trans, dtype=np.float64).reshape(3)
    return out


def _inv(pose: F64) -> F64:
    rot = pose[:3, :3]
    return _pose(rot.T, -rot.T @ pose[:3, 3])


def _angle_deg(rot: F64) -> float:
    """The angle of rotation matrix ``rot``, degrees."""
    c = (float(np.trace(rot)) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _camera_matrix(camera: CameraSpec) -> F64:
    return np.array(
        [[camera.fx, 0.0, camera.cx], [0.0, camera.fy, camera.cy], [0.0, 0.0, 1.0]],
        dtype=np.float64,
    )


def _distortion(distortion: npt.ArrayLike | None) -> F64:
    if distortion is None:
        return np.zeros(5)
    try:
        d = np.asarray(distortion, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"distortion must be a list of numbers: {exc}") from None
    if d.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(d)):
        raise ValueError(
            "distortion must hold 4, 5, 8, 12 or 14 finite OpenCV coefficients "
            f"(k1, k2, p1, p2[, k3, ...]), got {d.tolist()}"
        )
    return d


# --------------------------------------------------------------------------- the board


@dataclass(frozen=True)
class CharucoBoard:
    """A ChArUco board: a chessboard with an ArUco marker in every white square.

    The defaults (7 × 5 squares of 4 cm, 3 cm markers, ``DICT_5X5_100``) make a
    28 × 20 cm board that prints on A4 (at 100 %, check the square size with a ruler)
    and is detected well from 0.3 to 0.6 m.

    **Board frame** (OpenCV's ChArUco object frame, OpenCV >= 4.6): the origin is the
    outer corner of the board at the top left of :meth:`image`, x runs along the
    ``squares_x`` squares (to the right in the image), y along the ``squares_y``
    squares (down in the image), and z = x × y points *into* the board, away from
    whoever looks at its printed face. The square at the origin is black; inner corner
    ``(i, j)`` lies at ``(i * square, j * square, 0)``. A board lying face up on the
    table therefore has z pointing down, into the table.

    Parameters
    ----------
    squares_x, squares_y
        Number of squares along x and y (>= 3 each).
    square
        Side of a square, metres (as printed).
    marker
        Side of an ArUco marker, metres (< ``square``).
    dictionary
        Name of an OpenCV predefined ArUco dictionary (``"DICT_5X5_100"``, ...) holding
        at least ``squares_x * squares_y // 2`` markers.
    """

    squares_x: int = 7
    squares_y: int = 5
    square: float = 0.04
    marker: float = 0.03
    dictionary: str = "DICT_5X5_100"

    def __post_init__(self) -> None:
        for name in ("squares_x", "squares_y"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 3:
                raise ValueError(f"CharucoBoard.{name} must be an integer >= 3, got {value!r}")
        _positive("CharucoBoard.square", self.square)
        _positive("CharucoBoard.marker", self.marker)
        if not self.marker < self.square:
            raise ValueError(
                f"CharucoBoard.marker ({self.marker!r}) must be smaller than "
                f"CharucoBoard.square ({self.square!r})"
            )
        if self.dictionary not in _DICTIONARIES:
            raise ValueError(
                f"CharucoBoard.dictionary {self.dictionary!r} is not an OpenCV predefined "
                f"ArUco dictionary; one of {sorted(_DICTIONARIES)}"
            )
        needed = self.squares_x * self.squares_y // 2
        if needed > _DICTIONARIES[self.dictionary]:
            raise ValueError(
                f"CharucoBoard.dictionary {self.dictionary!r} holds "
                f"{_DICTIONARIES[self.dictionary]} markers, a {self.squares_x}x"
                f"{self.squares_y} board needs {needed}"
            )

    @property
    def size(self) -> tuple[float, float]:
        """Board width (along x) and height (along y), metres."""
        return (self.squares_x * self.square, self.squares_y * self.square)

    @property
    def center(self) -> F64:
        """The board's centre in the board frame, metres."""
        w, h = self.size
        return np.array([w / 2.0, h / 2.0, 0.0])

    def cv(self) -> Any:
        """OpenCV's ``cv2.aruco.CharucoBoard`` for this board."""
        return _cv_board(self)

    def image(self, pixels_per_square: int = 100, margin: int = 0) -> npt.NDArray[np.uint8]:
        """The printable board, ``(squares_y * pixels_per_square + 2 * margin,
        squares_x * pixels_per_square + 2 * margin)`` grey pixels with ``margin`` white
        pixels around. Square edges fall exactly on pixel boundaries: pixel ``(r, c)``
        covers board coordinates ``x ∈ [c − margin, c − margin + 1] * square /
        pixels_per_square`` (and likewise y from ``r``)."""
        p = _int_at_least("pixels_per_square", pixels_per_square, 10)
        m = _int_at_least("margin", margin, 0)
        size = (self.squares_x * p + 2 * m, self.squares_y * p + 2 * m)
        img = self.cv().generateImage(size, marginSize=m, borderBits=1)
        return np.ascontiguousarray(img, dtype=np.uint8)


@functools.lru_cache(maxsize=8)
def _cv_board(board: CharucoBoard) -> Any:
    cv2 = _cv2()
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, board.dictionary))
    return cv2.aruco.CharucoBoard(
        (board.squares_x, board.squares_y), board.square, board.marker, dictionary
    )


@functools.lru_cache(maxsize=4)
def _board_image(board: CharucoBoard, pixels_per_square: int, margin: int) -> Any:
    img = board.image(pixels_per_square, margin)
    img.setflags(write=False)
    return img


# --------------------------------------------------------------------------- detection


@dataclass(frozen=True)
class BoardObservation:
    """The board's pose seen in one image."""

    board2cam: F64
    """The board's pose in the camera frame, ``(4, 4)``."""
    corners: int
    """How many ChArUco (inner chessboard) corners the pose was solved from."""
    reprojection_px: float
    """RMS reprojection error of those corners, pixels."""


def _grey(image: npt.ArrayLike, camera: CameraSpec) -> npt.NDArray[np.uint8]:
    arr = np.asarray(image)
    if arr.dtype != np.uint8:
        raise ValueError(f"image must be uint8 (grey, BGR or RGB), got dtype {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim == 3 and arr.shape[2] == 3:
        # The plain channel mean: the same grey for BGR and RGB (the board is black
        # and white, so luma weights would add nothing).
        arr = np.round(arr.astype(np.float32).mean(axis=2)).astype(np.uint8)
    if arr.ndim != 2:
        raise ValueError(f"image must be (H, W) or (H, W, 3), got shape {arr.shape}")
    if arr.shape != (camera.height, camera.width):
        raise ValueError(
            f"image is {arr.shape[1]}x{arr.shape[0]}, the camera's {camera.width}x{camera.height}"
        )
    return np.ascontiguousarray(arr)


def detect_board(
    image: npt.NDArray[np.uint8],
    board: CharucoBoard,
    camera: CameraSpec,
    distortion: npt.ArrayLike | None = None,
) -> BoardObservation | None:
    """The board's pose in ``image``, or None where fewer than 6 of its corners are seen
    (or those seen are collinear, or ``cv2.solvePnP`` fails).

    The ChArUco corners come from ``cv2.aruco.CharucoDetector`` (sub-pixel refined by
    OpenCV); the pose from ``cv2.solvePnP`` (``SOLVEPNP_ITERATIVE``) refined by
    ``cv2.solvePnPRefineLM``, with ``K`` from ``camera`` and OpenCV ``distortion``
    coefficients (none by default: a RealSense colour stream is rectified).

    Parameters
    ----------
    image
        ``(H, W)`` grey or ``(H, W, 3)`` colour ``uint8`` image of the camera's size.
    """
    grey = _grey(image, camera)
    dist = _distortion(distortion)
    cv2 = _cv2()
    k = _camera_matrix(camera)

    charuco_params = cv2.aruco.CharucoParameters()
    charuco_params.tryRefineMarkers = True
    detector_params = cv2.aruco.DetectorParameters()
    detector = cv2.aruco.CharucoDetector(board.cv(), charuco_params, detector_params)
    corners, ids, _, _ = detector.detectBoard(grey)
    if corners is None or ids is None or len(ids) < MIN_CORNERS:
        return None
    obj, img = board.cv().matchImagePoints(corners, ids)
    obj = np.asarray(obj, dtype=np.float64).reshape(-1, 3)
    img = np.asarray(img, dtype=np.float64).reshape(-1, 2)
    if len(obj) < MIN_CORNERS:  # pragma: no cover - matchImagePoints keeps every id
        return None
    spread = np.linalg.svd(obj[:, :2] - obj[:, :2].mean(axis=0), compute_uv=False)
    if spread[1] < 0.5 * board.square:  # all on one row or column: pose ill-posed
        return None
    ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:  # pragma: no cover - ITERATIVE on a planar target with >= 6 points
        return None
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, k, dist, rvec, tvec)
    projected, _ = cv2.projectPoints(obj, rvec, tvec, k, dist)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img) ** 2, axis=1))))
    rot, _ = cv2.Rodrigues(rvec)
    board2cam = _pose(_project_rotation(rot), tvec)
    if not np.all(np.isfinite(board2cam)) or board2cam[2, 3] <= 0:  # pragma: no cover
        return None
    return BoardObservation(board2cam=board2cam, corners=len(obj), reprojection_px=rms)


# --------------------------------------------------------------------------- rendering


def world_in_board(board: CharucoBoard) -> F64:
    """``world2board``: the workspace frame in the board frame — turned face up (z out of
    the table), origin at the board's bottom-left outer corner as printed."""
    m = np.diag([1.0, -1.0, -1.0, 1.0])
    m[1, 3] = board.squares_y * board.square
    return m


def render_board(
    board: CharucoBoard,
    camera: CameraSpec,
    board2cam: F64,
    *,
    supersample: int = 4,
    background: int = 200,
    paper_margin: float = 0.5,
    noise: float = 0.0,
    seed: int = 0,
) -> npt.NDArray[np.uint8]:
    """A synthetic ``(height, width)`` grey image of the board seen by the pinhole
    ``camera`` (no distortion) from ``board2cam``.

    The printed board (with a white paper margin of ``paper_margin`` squares around it)
    is warped by the plane's homography onto a ``supersample``-times finer pixel grid and
    box-filtered down, so edges are anti-aliased; outside the paper the image is
    ``background`` (light grey). ``noise`` adds Gaussian sensor noise of that standard
    deviation (grey levels, drawn from ``seed``) before rounding. Exact with the
    package's convention: the board point ``X`` is drawn at ``u = fx * x / z + cx``
    with pixel centres at integers, so :func:`detect_board` recovers ``board2cam`` to a
    small fraction of a pixel.

    Raises ValueError if any part of the paper lies at or behind the camera plane.
    """
    pose = _as_pose("board2cam", board2cam)
    s = _int_at_least("supersample", supersample, 1)
    if isinstance(background, bool) or not 0 <= int(background) <= 255:
        raise ValueError(f"background must be a grey level in 0..255, got {background!r}")
    if not (math.isfinite(float(paper_margin)) and paper_margin >= 0):
        raise ValueError(f"paper_margin must be >= 0 squares, got {paper_margin!r}")
    if not (math.isfinite(float(noise)) and noise >= 0):
        raise ValueError(f"noise must be >= 0 grey levels, got {noise!r}")

    w, h = board.size
    edge = paper_margin * board.square
    outline = np.array(
        [
            [-edge, -edge, 0.0],
            [w + edge, -edge, 0.0],
            [w + edge, h + edge, 0.0],
            [-edge, h + edge, 0.0],
        ]
    )
    cam_pts = outline @ pose[:3, :3].T + pose[:3, 3]
    z_min = float(cam_pts[:, 2].min())
    if z_min <= 1e-3:
        raise ValueError(
            f"board2cam puts part of the board at or behind the camera (z = {z_min:.4g} m)"
        )

    # Board-image resolution: about one source pixel per supersampled pixel where the
    # board is nearest (finer only costs memory; bilinear sampling keeps square edges,
    # which fall on source pixel boundaries, exactly in place).
    nearest = board.square * max(camera.fx, camera.fy) * s / z_min
    pps = int(np.clip(20 * math.ceil(nearest / 20), 20, 800))  # steps of 20: cache hits
    margin_px = math.ceil(paper_margin * pps)
    src = _board_image(board, pps, margin_px)

    # Source pixel (a, b) -> board (X, Y): X = (a + 0.5 - margin_px) * square / pps.
    sc = board.square / pps
    off = (0.5 - margin_px) * sc
    src2board = np.array([[sc, 0.0, off], [0.0, sc, off], [0.0, 0.0, 1.0]])
    board2img = _camera_matrix(camera) @ np.column_stack([pose[:3, 0], pose[:3, 1], pose[:3, 3]])
    # Image coordinate u -> supersampled coordinate s * (u + 0.5) - 0.5.
    c = (s - 1) / 2.0
    img2ss = np.array([[s, 0.0, c], [0.0, s, c], [0.0, 0.0, 1.0]])
    homography = img2ss @ board2img @ src2board

    cv2 = _cv2()
    fine = cv2.warpPerspective(
        src,
        homography,
        (camera.width * s, camera.height * s),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=int(background),
    )
    blocks = np.asarray(fine, dtype=np.float32).reshape(camera.height, s, camera.width, s)
    out: F64 = blocks.mean(axis=(1, 3), dtype=np.float64)
    if noise > 0:
        out = out + np.random.default_rng(seed).normal(0.0, float(noise), out.shape)
    grey: npt.NDArray[np.uint8] = np.clip(np.round(out), 0, 255).astype(np.uint8)
    return grey


# --------------------------------------------------------------------------- arm poses


def calibration_poses(
    board2base: F64,
    cam2tcp_guess: F64,
    *,
    n: int = 15,
    distance: tuple[float, float] = (0.35, 0.5),
    max_tilt_deg: float = 35.0,
    max_roll_deg: float = 45.0,
    board: CharucoBoard | None = None,
    seed: int = 0,
) -> list[F64]:
    """``n`` TCP poses (base frame) from which the camera, mounted at ``cam2tcp_guess``,
    looks at the board's centre from varied directions, distances and rolls.

    Pose 0 looks straight down the board's normal; the others are tilted away from it
    by ``0.3–1 × max_tilt_deg`` towards azimuths spread by the golden angle, at
    distances spread over ``distance`` (metres, camera to board centre), and rolled
    about the optical axis by up to ``±max_roll_deg`` (roll 0: the image x axis along the
    board's x). Spread rotation axes are what the linear hand-eye methods (Tsai, ...)
    need. Deterministic given ``seed``. Check reachability and collisions before moving
    there (a guessed extrinsic off by a few centimetres only shifts the board in the
    image).

    Parameters
    ----------
    board2base
        Where the board lies, base frame (its z points into the table, see
        :class:`CharucoBoard`).
    cam2tcp_guess
        The extrinsic as far as it is known (CAD drawing, tape measure).
    board
        The board (its centre is the look-at point); the default board if None.
    """
    b2b = _as_pose("board2base", board2base)
    c2t = _as_pose("cam2tcp_guess", cam2tcp_guess)
    count = _int_at_least("n", n, MIN_POSES)
    try:
        near, far = (float(d) for d in distance)
    except (TypeError, ValueError):
        raise ValueError(
            f"distance must be a (near, far) pair of metres, got {distance!r}"
        ) from None
    if not (math.isfinite(near) and math.isfinite(far) and 0 < near <= far):
        raise ValueError(f"distance must satisfy 0 < near <= far, got {distance!r}")
    tilt_max = float(max_tilt_deg)
    if not (math.isfinite(tilt_max) and 0 <= tilt_max < 80):
        raise ValueError(f"max_tilt_deg must be in [0, 80), got {max_tilt_deg!r}")
    roll_max = float(max_roll_deg)
    if not (math.isfinite(roll_max) and 0 <= roll_max <= 180):
        raise ValueError(f"max_roll_deg must be in [0, 180], got {max_roll_deg!r}")
    the_board = CharucoBoard() if board is None else board

    rng = np.random.default_rng(seed)
    golden = math.pi * (3.0 - math.sqrt(5.0))
    phase = rng.uniform(0.0, 2.0 * math.pi)
    dists = np.linspace(near, far, count)
    rng.shuffle(dists)
    centre = the_board.center
    tcp2cam = _inv(c2t)
    poses: list[F64] = []
    for i in range(count):
        if i == 0:
            tilt, azimuth, roll = 0.0, 0.0, 0.0
        else:
            tilt = math.radians(tilt_max) * rng.uniform(0.3, 1.0)
            azimuth = phase + i * golden
            roll = math.radians(roll_max) * rng.uniform(-1.0, 1.0)
        # Optical axis (camera z) in the board frame: into the board, tilted.
        z = np.array(
            [math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)]
        )
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        cr, sr = math.cos(roll), math.sin(roll)
        x, y = cr * x + sr * y, -sr * x + cr * y
        cam2board = _pose(np.column_stack([x, y, z]), centre - dists[i] * z)
        poses.append(b2b @ cam2board @ tcp2cam)
    return poses


# --------------------------------------------------------------------------- hand-eye


def _method_flags(cv2: Any) -> dict[str, int]:
    return {
        "tsai": cv2.CALIB_HAND_EYE_TSAI,
        "park": cv2.CALIB_HAND_EYE_PARK,
        "horaud": cv2.CALIB_HAND_EYE_HORAUD,
        "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
        "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
    }


def _matrix(name: str, value: Any, shape: tuple[int, ...] | None) -> F64:
    """``value`` as finite float64 numbers of ``shape`` (None: any 1-D length)."""
    want = "a list" if shape is None else f"shape {shape}"
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be numbers of {want}: {exc}") from None
    bad_shape = arr.ndim != 1 if shape is None else arr.shape != shape
    if bad_shape or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite numbers of {want}, got shape {arr.shape}")
    return arr


@dataclass(frozen=True)
class HandEyeResult:
    """A solved eye-in-hand calibration and how well the poses agree with it."""

    cam2tcp: F64
    """The extrinsic: the camera's pose in the TCP frame, ``(4, 4)``."""
    board2base: F64
    """The board's pose in the base frame (the workspace frame's reference), the mean
    over poses of ``tcp2base @ cam2tcp @ board2cam`` (rotations averaged by
    quaternions)."""
    method: str
    """The ``cv2.calibrateHandEye`` method that gave ``cam2tcp``."""
    residuals_mm: F64
    """Per pose used (in order; :func:`calibrate` uses those where the board was
    detected): distance of its ``board2base`` origin from the mean's, millimetres."""
    residuals_deg: F64
    """Per pose used: angle between its ``board2base`` rotation and the mean's, degrees."""
    methods: dict[str, dict[str, float]] = field(default_factory=dict)
    """Every method tried → ``mean_mm``, ``max_mm``, ``mean_deg``, ``max_deg`` of its
    residuals (a method OpenCV failed on is left out)."""

    def to_dict(self) -> dict[str, Any]:
        """Plain lists, floats and strings (JSON and TOML writable)."""
        return {
            "method": self.method,
            "cam2tcp": [[float(x) for x in row] for row in self.cam2tcp],
            "board2base": [[float(x) for x in row] for row in self.board2base],
            "residuals_mm": [float(x) for x in self.residuals_mm],
            "residuals_deg": [float(x) for x in self.residuals_deg],
            "methods": {m: {k: float(v) for k, v in s.items()} for m, s in self.methods.items()},
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> HandEyeResult:
        """The inverse of :meth:`to_dict`; a ValueError naming a missing or bad key."""
        if not isinstance(data, Mapping):
            raise ValueError(f"hand-eye result must be a mapping, got {type(data).__name__}")
        for key in ("method", "cam2tcp", "board2base", "residuals_mm", "residuals_deg"):
            if key not in data:
                raise ValueError(f"hand-eye result lacks {key!r}")
        method = data["method"]
        if method not in HAND_EYE_METHODS:
            raise ValueError(f"hand-eye result: method {method!r} not in {HAND_EYE_METHODS}")
        cam2tcp = _as_pose("cam2tcp", _matrix("cam2tcp", data["cam2tcp"], (4, 4)))
        board2base = _as_pose("board2base", _matrix("board2base", data["board2base"], (4, 4)))
        res_mm = _matrix("residuals_mm", data["residuals_mm"], None)
        res_deg = _matrix("residuals_deg", data["residuals_deg"], res_mm.shape)
        methods_in = data.get("methods", {})
        if not isinstance(methods_in, Mapping):
            raise ValueError(f"hand-eye result: methods must be a mapping, got {methods_in!r}")
        methods: dict[str, dict[str, float]] = {}
        for name, stats in methods_in.items():
            if name not in HAND_EYE_METHODS or not isinstance(stats, Mapping):
                raise ValueError(f"hand-eye result: bad methods entry {name!r}: {stats!r}")
            methods[str(name)] = {str(k): float(v) for k, v in stats.items()}
        return cls(
            cam2tcp=cam2tcp,
            board2base=board2base,
            method=str(method),
            residuals_mm=res_mm,
            residuals_deg=res_deg,
            methods=methods,
        )


def _board2base_spread(
    cam2tcp: F64, tcp2base: Sequence[F64], board2cam: Sequence[F64]
) -> tuple[F64, F64, F64]:
    """The mean board pose in the base frame and every pose's distance (mm) and angle
    (degrees) from it."""
    from scipy.spatial.transform import Rotation

    each = np.stack([t @ cam2tcp @ b for t, b in zip(tcp2base, board2cam, strict=True)])
    mean_rot = Rotation.from_matrix(each[:, :3, :3]).mean().as_matrix()
    mean = _pose(mean_rot, each[:, :3, 3].mean(axis=0))
    mm = 1000.0 * np.linalg.norm(each[:, :3, 3] - mean[:3, 3], axis=1)
    deg = np.array([_angle_deg(mean_rot.T @ r) for r in each[:, :3, :3]])
    return mean, mm, deg


def solve_hand_eye(
    tcp2base: Sequence[F64], board2cam: Sequence[F64], *, method: str = "best"
) -> HandEyeResult:
    """The extrinsic ``cam2tcp`` from pairs of TCP poses (base frame, as the arm
    reports them) and board poses (camera frame, :func:`detect_board`).

    Solved by ``cv2.calibrateHandEye`` (``R_gripper2base, t_gripper2base`` =
    ``tcp2base``; ``R_target2cam, t_target2cam`` = ``board2cam``). ``method="best"``
    tries every one of :data:`HAND_EYE_METHODS` and keeps the one whose poses agree
    best on where the board lies (smallest mean ``residuals_mm``, then
    ``residuals_deg``); a method name uses that one alone.

    Raises ValueError with fewer than 3 poses, a count mismatch, a pose that is not a
    finite rigid ``(4, 4)`` transform (naming its index) or an unknown method.
    """
    if method != "best" and method not in HAND_EYE_METHODS:
        raise ValueError(f"method must be 'best' or one of {HAND_EYE_METHODS}, got {method!r}")
    tcp = _as_poses("tcp2base", tcp2base)
    b2c = _as_poses("board2cam", board2cam)
    if len(tcp) != len(b2c):
        raise ValueError(f"got {len(tcp)} tcp2base poses but {len(b2c)} board2cam poses")
    if len(tcp) < MIN_POSES:
        raise ValueError(f"hand-eye calibration needs at least {MIN_POSES} poses, got {len(tcp)}")

    cv2 = _cv2()
    flags = _method_flags(cv2)
    names = HAND_EYE_METHODS if method == "best" else (method,)
    r_g2b = [p[:3, :3] for p in tcp]
    t_g2b = [p[:3, 3:4] for p in tcp]
    r_t2c = [p[:3, :3] for p in b2c]
    t_t2c = [p[:3, 3:4] for p in b2c]
    solved: dict[str, tuple[F64, F64, F64, F64]] = {}
    failures: dict[str, str] = {}
    for name in names:
        try:
            rot, trans = cv2.calibrateHandEye(r_g2b, t_g2b, r_t2c, t_t2c, method=flags[name])
        except cv2.error as exc:
            failures[name] = str(exc).strip().splitlines()[-1]
            continue
        rot = np.asarray(rot, dtype=np.float64)
        trans = np.asarray(trans, dtype=np.float64)
        if not (np.all(np.isfinite(rot)) and np.all(np.isfinite(trans))):
            failures[name] = "non-finite result"
            continue
        cam2tcp = _pose(_project_rotation(rot), trans)
        mean, mm, deg = _board2base_spread(cam2tcp, tcp, b2c)
        solved[name] = (cam2tcp, mean, mm, deg)
    if not solved:
        raise ValueError(f"cv2.calibrateHandEye failed for every method: {failures}")
    stats = {
        name: {
            "mean_mm": float(mm.mean()),
            "max_mm": float(mm.max()),
            "mean_deg": float(deg.mean()),
            "max_deg": float(deg.max()),
        }
        for name, (_, _, mm, deg) in solved.items()
    }
    best = min(solved, key=lambda m: (stats[m]["mean_mm"], stats[m]["mean_deg"]))
    cam2tcp, mean, mm, deg = solved[best]
    return HandEyeResult(
        cam2tcp=cam2tcp,
        board2base=mean,
        method=best,
        residuals_mm=mm,
        residuals_deg=deg,
        methods=stats,
    )


def calibrate(
    images: Sequence[npt.NDArray[np.uint8]],
    tcp2base: Sequence[F64],
    board: CharucoBoard,
    camera: CameraSpec,
    *,
    method: str = "best",
    distortion: npt.ArrayLike | None = None,
) -> tuple[HandEyeResult, list[BoardObservation | None]]:
    """Eye-in-hand calibration from images of the board taken at the TCP poses
    ``tcp2base`` (one per image).

    Returns the solution (:func:`solve_hand_eye` over the images where the board was
    detected) and every image's observation (None where it was not). Raises ValueError
    if the counts differ or fewer than 3 images show the board.
    """
    if len(images) != len(tcp2base):
        raise ValueError(f"got {len(images)} images but {len(tcp2base)} tcp2base poses")
    tcp = _as_poses("tcp2base", tcp2base)
    observations = [detect_board(img, board, camera, distortion) for img in images]
    kept = [i for i, o in enumerate(observations) if o is not None]
    if len(kept) < MIN_POSES:
        raise ValueError(
            f"the board was detected in {len(kept)} of {len(images)} images; hand-eye "
            f"calibration needs at least {MIN_POSES}"
        )
    result = solve_hand_eye(
        [tcp[i] for i in kept],
        [o.board2cam for o in observations if o is not None],
        method=method,
    )
    return result, observations
