"""A RealSense in the simulator: the colour stream a RealSense driver delivers, rendered
where the rehearsal's hand-eye camera truly is.

:class:`SimRealSense` has the life cycle and the reads of
:class:`heapgrasp.robot.realsense.RealSenseCamera` (``start``, ``stop``, ``poll``,
``wait``, ``spec``, ``depth``, ``distortion``, ``describe``) and stamps its frames on the
rehearsal controller's clock, one every ``1/fps`` s of simulated time, so the arm driver
pairs frames and poses as on hardware. The true camera pose is the TCP (the simulator's
hand) times the rehearsal's *true* extrinsic, which ``robot calibrate --sim`` has to
measure like a real one. It renders the simulator's RGB (the optics of transparent and
specular objects included), with depth where ``[camera] depth`` asks; on the calibration
table it renders the ChArUco board instead (:func:`heapgrasp.robot.calibration.render_board`).

Every frame's exact silhouette, rendered at the true pose, is kept by timestamp
(:class:`Silhouettes`): the simulator's segmenters read it, and the run records it
beside the frame so that ``heapgrasp robot replay`` can segment the recording the same way.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.perception.frames import Frame
from heapgrasp.robot.calibration import CharucoBoard, render_board
from heapgrasp.robot.errors import DeviceError
from heapgrasp.robot.realsense import CameraFrame, RealSenseSettings

if TYPE_CHECKING:
    from heapgrasp.sim.world import SimWorld

__all__ = ["Silhouettes", "SimRealSense", "rehearsal_spec"]

F64 = npt.NDArray[np.float64]

#: Focal length over image width of the rehearsal's colour stream: the simulator's
#: continuous camera (270 px at 320 px wide; about the RealSense D435's colour stream).
FOCAL_PER_WIDTH = 270.0 / 320.0

#: How many frames' silhouettes are kept (a phase sees a few hundred).
SILHOUETTES_KEPT = 4000


def rehearsal_spec(settings: RealSenseSettings) -> CameraSpec:
    """The intrinsics of the rehearsal's colour stream at ``[camera]``'s size and rate."""
    f = FOCAL_PER_WIDTH * settings.width
    return CameraSpec(
        width=settings.width,
        height=settings.height,
        fx=f,
        fy=f,
        cx=(settings.width - 1) / 2,
        cy=(settings.height - 1) / 2,
        fps=float(settings.fps),
    )


class Silhouettes:
    """Each rendered frame's exact silhouette by its timestamp (a
    :class:`~heapgrasp.perception.segmenters.MaskSource`)."""

    def __init__(self, kept: int = SILHOUETTES_KEPT) -> None:
        self.kept = kept
        self._masks: OrderedDict[float, tuple[tuple[int, int], npt.NDArray[np.uint8]]] = (
            OrderedDict()
        )

    def add(self, time: float, mask: npt.NDArray[np.bool_]) -> None:
        """Keeps ``mask`` (``(H, W)``) as the silhouette of the frame stamped ``time``."""
        shape = (int(mask.shape[0]), int(mask.shape[1]))
        self._masks[time] = (shape, np.packbits(mask.reshape(-1)))
        while len(self._masks) > self.kept:
            self._masks.popitem(last=False)

    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The exact silhouette of the rendered frame stamped ``frame.time``."""
        try:
            shape, bits = self._masks[frame.time]
        except KeyError:
            raise DeviceError(
                f"no silhouette for the frame at {frame.time:.4f} s: not rendered by this "
                "rehearsal, or too long ago"
            ) from None
        return np.unpackbits(bits, count=shape[0] * shape[1]).reshape(shape).astype(bool)


class SimRealSense:
    """The rehearsal's camera (see the module docstring)."""

    def __init__(
        self,
        world: SimWorld,
        settings: RealSenseSettings,
        *,
        cam2world: Callable[[], F64],
        clock: Callable[[], float],
        advance: Callable[[float], None],
        silhouettes: Silhouettes,
        board: tuple[CharucoBoard, F64] | None = None,
    ) -> None:
        self.world = world
        self.settings = settings
        self._spec = rehearsal_spec(settings)
        self._cam2world = cam2world
        self._clock = clock
        self._advance = advance
        self.silhouettes = silhouettes
        self.board = board
        """The calibration board and its pose (``board2world``), where it lies on the
        table; frames then show it."""
        self.started = False
        self.frames = 0
        self._due = clock()

    @property
    def spec(self) -> CameraSpec:
        return self._spec

    @property
    def depth(self) -> bool:
        return self.settings.depth

    @property
    def distortion(self) -> npt.NDArray[np.float64]:
        """No distortion (the renderer is a pinhole)."""
        return np.zeros(5)

    def describe(self) -> dict[str, Any]:
        return {"name": "rehearsal camera (simulated RealSense)", "serial": "sim"}

    def start(self) -> None:
        self.started = True
        self._due = self._clock()

    def stop(self) -> None:
        self.started = False

    def _shot(self, t: float) -> CameraFrame:
        if not self.started:
            raise DeviceError("the camera is not started")
        pose = self._cam2world()
        depth: npt.NDArray[np.float32] | None = None
        if self.board is not None:
            board, board2world = self.board
            board2cam = np.linalg.inv(pose) @ board2world
            grey = render_board(board, self._spec, board2cam, noise=2.0, seed=self.frames)
            rgb = np.repeat(grey[..., None], 3, axis=2)
            mask = np.zeros(grey.shape, dtype=bool)
        else:
            shot = self.world.capture(pose, self._spec, depth=self.depth, rgb=True)
            assert shot.rgb is not None
            rgb, mask = shot.rgb, shot.mask
            depth = shot.depth
        self.silhouettes.add(t, mask)
        self.frames += 1
        return CameraFrame(t, rgb, depth, self.frames)

    def poll(self) -> list[CameraFrame]:
        """The frame due since the last read, rendered now and stamped now (none where
        no frame is due)."""
        now = self._clock()
        if self._due > now:
            return []
        while self._due <= now:
            self._due += 1.0 / self.settings.fps
        return [self._shot(now)]

    def wait(self, timeout: float | None = None) -> CameraFrame:
        """The next frame: the world runs on to when it is due."""
        left = self._due - self._clock()
        if left > 0:
            self._advance(left)
        now = self._clock()
        self._due = max(self._due, now) + 1.0 / self.settings.fps
        return self._shot(now)
