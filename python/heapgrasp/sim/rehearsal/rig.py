"""The rehearsal rig: a UR5e, a RealSense and a gripper in the simulator, behind the real
drivers' interfaces.

:class:`Rehearsal` builds a simulated world — a pile of objects from a seed, or the
ChArUco board on the table for ``robot calibrate`` — with the simulator's hand where
the arm stands, and hands out :class:`~heapgrasp.robot.hardware.Drivers` whose arm
(:mod:`heapgrasp.sim.rehearsal.controller`), camera (:mod:`heapgrasp.sim.rehearsal.camera`) and
gripper (:mod:`heapgrasp.sim.rehearsal.gripper`) are the simulator's. The real-robot
commands run unchanged on them: ``robot.toml`` is read and checked, the arm driver
checks and streams every motion, the camera's frames are paired with the arm's pose
record, and the run writes the folder a real run writes.

The rig has its own truth, which the commands must find as on hardware: the arm's base
stands at :data:`BASE2WORLD` and the camera sits on the TCP at :data:`TRUE_CAM2TCP`.
``robot calibrate --sim --execute`` measures both with the board (the guess it starts
from is 3° and 9 mm off); a run before that is refused for want of ``[calibration]``, as
on the arm, and a run with a calibration that is off sees the scene where the
calibration says. Views out of the UR5e's reach from that base are refused by its
kinematics, as the controller would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from heapgrasp.geometry.gripper import PANDA_HAND
from heapgrasp.loop.config import RunConfig
from heapgrasp.perception.frames import Frame
from heapgrasp.robot.calibration import CharucoBoard, world_in_board
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.hardware import Drivers
from heapgrasp.robot.realsense import RealSenseSettings
from heapgrasp.robot.ur import pose_from_rtde
from heapgrasp.sim.build import object_library
from heapgrasp.sim.gripper import PandaHand
from heapgrasp.sim.rehearsal.camera import Silhouettes, SimRealSense
from heapgrasp.sim.rehearsal.controller import SimControl, SimController, SimReceive
from heapgrasp.sim.rehearsal.gripper import SimRobotiq
from heapgrasp.sim.rehearsal.ur5e import UR5e
from heapgrasp.sim.world import SimWorld, WorldConfig

__all__ = ["BASE2WORLD", "START_CAMERA", "TRUE_CAM2TCP", "Rehearsal"]

F64 = npt.NDArray[np.float64]


def _pose(rotation: F64, translation: tuple[float, float, float]) -> F64:
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = translation
    return m


#: Where the rehearsal's UR5e stands (its base frame in the workspace frame): behind the
#: scene's -x side, turned 120° so that ``robot init``'s ``[arm] park`` holds the hand
#: beside the scene, over the bin's side, inside ``[workspace]``.
BASE2WORLD = _pose(Rotation.from_euler("z", 120, degrees=True).as_matrix(), (-0.30, 0.0, 0.0))

#: The camera on the TCP as the rehearsal built it (``robot calibrate`` starts from a
#: guess: 10 cm behind the TCP, 6 cm beside it; this is 3° and about 9 mm off it).
TRUE_CAM2TCP = _pose(
    Rotation.from_rotvec(math.radians(3.0) * np.array([0.6, 0.8, 0.0])).as_matrix(),
    (0.004, 0.066, -0.105),
)

#: Where the camera is when a command starts (the operator has jogged the arm there):
#: 0.45 m above the scene's centre, looking down, image x along the workspace's x.
START_CAMERA = _pose(np.diag([1.0, -1.0, -1.0]), (0.15, 0.12, 0.45))


@dataclass(frozen=True)
class _Board:
    board: CharucoBoard
    board2world: F64


class Rehearsal:
    """A simulated world and the drivers onto it (see the module docstring); close it
    (or use it as a context manager) to release the simulator."""

    def __init__(
        self,
        robot: RobotConfig,
        config: RunConfig,
        *,
        seed: int = 0,
        objects: int = 5,
        board: bool = False,
    ) -> None:
        if objects < 0 or (objects == 0 and not board):
            raise ValueError(f"objects must be at least 1, got {objects}")
        if not board:  # the simulator's bounds on a scene (RunConfig's), named
            config = config.replace({"objects": objects}, source="--objects")
        self.robot = robot
        self.config = config
        self.seed = seed
        self.world = SimWorld(
            object_library(config),
            config=WorldConfig(cube_size=config.cube_size),
            seed=seed,
        )
        try:
            self.board: _Board | None = None
            if board:
                b = CharucoBoard()
                self.board = _Board(b, np.asarray(np.linalg.inv(world_in_board(b))))
                self.world.reset(n_objects=0, seed=seed)
            else:
                self.world.reset(
                    layout=config.layout,  # type: ignore[arg-type]
                    n_objects=objects,
                    category=config.category,
                    seed=seed,
                    split=config.split,  # type: ignore[arg-type]
                )
            self.requested = objects
            self.placed = {oid: str(o.category) for oid, o in self.world.objects.items()}
            self.removed: list[int] = []
            self.hand = PandaHand(self.world)
            self.hand.reset(START_CAMERA @ np.linalg.inv(TRUE_CAM2TCP))
            world2base = np.asarray(np.linalg.inv(BASE2WORLD), dtype=np.float64)
            self.controller = SimController(
                self.hand, world2base, UR5e(pose_from_rtde(robot.arm.tcp))
            )
            self.silhouettes = Silhouettes()
            self.camera: SimRealSense | None = None
        except BaseException:
            self.world.close()
            raise

    # ---------------------------------------------------------------- drivers
    def drivers(self) -> Drivers:
        """The simulator's devices as the real drivers' factories."""
        ctl = self.controller

        def arm(host: str, tcp: Any) -> tuple[SimControl, SimReceive]:
            ctl.connected = True
            control = SimControl(ctl)
            control.setTcp(list(tcp))
            return control, SimReceive(ctl)

        def camera(settings: RealSenseSettings) -> SimRealSense:
            if self.camera is None or self.camera.settings != settings:
                self.camera = SimRealSense(
                    self.world,
                    settings,
                    cam2world=self.true_camera,
                    clock=lambda: ctl.clock,
                    advance=ctl.advance,
                    silhouettes=self.silhouettes,
                    board=None
                    if self.board is None
                    else (self.board.board, self.board.board2world),
                )
            return self.camera

        def gripper(config: RobotConfig) -> SimRobotiq:
            return SimRobotiq(self.hand, self.config.cube_size, self._released)

        return Drivers(
            arm=arm,
            camera=camera,
            gripper=gripper,
            clock=lambda: ctl.clock,
            sleep=ctl.advance,
            hand=PANDA_HAND,
            scene=self,
        )

    def true_camera(self) -> F64:
        """Where the camera truly is (world): the TCP times the true extrinsic."""
        return np.asarray(self.hand.tcp @ TRUE_CAM2TCP, dtype=np.float64)

    def _released(self, object_id: int) -> None:
        self.world.remove(object_id)
        self.removed.append(object_id)

    # ---------------------------------------------------------------- truth
    def silhouette(self, frame: Frame) -> npt.NDArray[np.bool_]:
        """The exact silhouette of a frame the rehearsal's camera rendered."""
        return self.silhouettes.silhouette(frame)

    def report(self) -> dict[str, Any]:
        """What the simulator saw become of the objects."""
        left = {oid: str(o.category) for oid, o in self.world.objects.items()}
        return {
            "seed": self.seed,
            "objects_requested": self.requested,
            "objects_placed": len(self.placed),
            "objects_removed": len(self.removed),
            "objects_left": len(left),
            "removed_categories": [self.placed[i] for i in self.removed],
            "left_categories": sorted(left.values()),
            "simulated_time_s": self.world.time,
        }

    # ---------------------------------------------------------------- lifecycle
    def close(self) -> None:
        """Releases the simulator."""
        self.world.close()

    def __enter__(self) -> Rehearsal:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
