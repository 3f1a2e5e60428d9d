"""The gripper's geometry, in one place: its collision model in the TCP frame, its widest
opening and how deep its fingers reach. The grasp planners, the view planner's regions,
the grasp execution sequence and the simulator all read it from here.

The shipped networks and the analytic planner's defaults are for the Franka Panda hand
(:data:`PANDA_HAND`, 8 cm opening, as VGN).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from heapgrasp.geometry.checks import finite, positive

__all__ = [
    "GRASP_DEPTH_RANGE",
    "GRIPPERS",
    "PANDA_HAND",
    "ROBOTIQ_2F140",
    "GripperGeometry",
    "gripper_named",
]

#: VGN's grasp depths, in finger depths: how far in front of the surface point a grasp's
#: palm face is placed (``[−ε, 1 + ε]``, ε = 0.1), for its data and its detection.
GRASP_DEPTH_RANGE = (-0.1, 1.1)


@dataclass(frozen=True)
class GripperGeometry:
    """Collision model of a parallel-jaw gripper in its TCP frame (metres).

    The TCP frame is ``panda_grasptarget``: z is the approach direction (fingertips at
    positive z), the fingers close along y, x runs across the finger width. The
    defaults are the collision meshes of the Franka Panda hand
    (``pybullet_data/franka_panda/meshes/collision``).

    Parameters
    ----------
    finger_width
        Finger extent along x.
    finger_tip
        z of the fingertips (0.7 cm beyond the TCP).
    finger_base
        z where the fingers leave the hand.
    finger_split
        z where the finger changes from its thin tip to its thicker base.
    tip_thickness, base_thickness
        Finger extent along y (from the inner pad outwards) of the tip and base parts.
    palm_front
        z of the hand's face toward the fingertips.
    palm_split
        z where the hand's narrow front part meets its wider back part.
    palm_back
        z of the back of the hand.
    palm_front_half, palm_back_half
        ``(x, y)`` half extents of the hand's front and back parts.
    max_opening
        Widest opening between the fingers (the Panda's 8 cm).
    """

    finger_width: float = 0.021
    finger_tip: float = 0.0072
    finger_base: float = -0.0466
    finger_split: float = -0.02
    tip_thickness: float = 0.016
    base_thickness: float = 0.026
    palm_front: float = -0.039
    palm_split: float = -0.075
    palm_back: float = -0.131
    palm_front_half: tuple[float, float] = (0.022, 0.101)
    palm_back_half: tuple[float, float] = (0.032, 0.104)
    max_opening: float = 0.08

    def __post_init__(self) -> None:
        for name in ("finger_width", "tip_thickness", "base_thickness", "max_opening"):
            positive(f"GripperGeometry.{name}", getattr(self, name))
        for name in (
            "finger_tip",
            "finger_base",
            "finger_split",
            "palm_front",
            "palm_split",
            "palm_back",
        ):
            finite(f"GripperGeometry.{name}", getattr(self, name))
        for name in ("palm_front_half", "palm_back_half"):
            half = tuple(getattr(self, name))
            if len(half) != 2:
                raise ValueError(f"GripperGeometry.{name} must be 2 numbers, got {half}")
            for h in half:
                positive(f"GripperGeometry.{name}", h)
            object.__setattr__(self, name, (float(half[0]), float(half[1])))
        if not self.finger_base < self.finger_split < self.finger_tip:
            raise ValueError(
                "GripperGeometry.finger_base < finger_split < finger_tip is required, got "
                f"{self.finger_base}, {self.finger_split}, {self.finger_tip}"
            )
        if not self.palm_back < self.palm_split < self.palm_front < self.finger_tip:
            raise ValueError(
                "GripperGeometry.palm_back < palm_split < palm_front < finger_tip is "
                f"required, got {self.palm_back}, {self.palm_split}, {self.palm_front}"
            )

    def inflated(self, margin: float) -> GripperGeometry:
        """The hand grown by ``margin`` (m) outward: the palm on every side, the fingers
        on every side but their inner pads (so the opening is unchanged); for collision
        checks against sampled points, which a thin overlap can pass between."""
        m = float(margin)
        if not (math.isfinite(m) and m >= 0.0):
            raise ValueError(f"margin must be finite and >= 0, got {margin!r}")
        fx, fy = self.palm_front_half
        bx, by = self.palm_back_half
        return dataclasses.replace(
            self,
            finger_width=self.finger_width + 2 * m,
            finger_tip=self.finger_tip + m,
            tip_thickness=self.tip_thickness + m,
            base_thickness=self.base_thickness + m,
            palm_front=self.palm_front + m,
            palm_back=self.palm_back - m,
            palm_front_half=(fx + m, fy + m),
            palm_back_half=(bx + m, by + m),
        )

    @property
    def finger_depth(self) -> float:
        """How far the fingertips reach beyond the palm's face (m)."""
        return self.finger_tip - self.palm_front


#: The Franka Panda hand (VGN's gripper; the simulator's).
PANDA_HAND = GripperGeometry()

#: The Robotiq 2F-140 adaptive gripper with its standard fingers, fingers open, in the
#: same TCP convention (z the approach, the fingers closing along y, x across them): the
#: TCP is the centre of the fingertip pads.
ROBOTIQ_2F140 = GripperGeometry(
    finger_width=0.030,
    finger_tip=0.0325,
    finger_base=-0.125,
    finger_split=-0.046,
    tip_thickness=0.018,
    base_thickness=0.036,
    palm_front=-0.115,
    palm_split=-0.177,
    palm_back=-0.189,
    palm_front_half=(0.0375, 0.045),
    palm_back_half=(0.0375, 0.0375),
    max_opening=0.14,
)
"""The Robotiq 2F-140 (:mod:`heapgrasp.robot.robotiq` drives it), fingers fully open.

Sources: Robotiq's 2F-140 specification (140 mm stroke), Robotiq's knowledge-base note
on the 2F-85/2F-140's vertical finger motion (the fingertips move along the approach as
they close), and ROS-Industrial's ``robotiq_2f_140_gripper_visualization`` URDF
(``robotiq_arg2f_140_model_macro.xacro``): its finger pads are 27 x 65 x 7.5 mm boxes
(30 x 70 x 7.5 mm for collision), and its joint origins, chained with the fingers open,
put the pads' centre 177 mm from the housing's base, the pads between 144.5 and 209.5 mm,
the knuckle pivots 55-61 mm from the base at y = ±30.6 mm, and the outer linkage at most
95 mm from the axis (at 131 mm).

Exact: ``max_opening`` (the stroke) and the pad length (``finger_tip`` is half of it,
the TCP being the pads' centre). From the URDF's kinematics (about ±3 mm):
``finger_split`` (the distal joint), ``finger_base``, ``palm_front`` (the housing's face
near the knuckles) and ``palm_split`` (the housing's base). Approximate (about ±5 mm,
no drawing at hand): ``finger_width`` (the pad's collision box), ``tip_thickness`` (the
7.5 mm pad and the distal phalanx), ``base_thickness`` (the open linkage reaching
outward of the pad plane), the housing's half extents ``palm_front_half``, and the
coupling to the flange (``palm_back``, ``palm_back_half``: a 75 mm disc, 12 mm thick).
The model is of the open hand: closing fully brings the fingertips about 24 mm further
out along z (URDF), which no static box model shows.
"""

#: The grippers described here, by the name data and training options take.
GRIPPERS: dict[str, GripperGeometry] = {"panda": PANDA_HAND, "robotiq-2f140": ROBOTIQ_2F140}


def gripper_named(name: str) -> GripperGeometry:
    """The gripper called ``name`` in :data:`GRIPPERS`; ValueError naming the choices."""
    try:
        return GRIPPERS[name]
    except KeyError:
        raise ValueError(f"unknown gripper {name!r}; choose among {', '.join(GRIPPERS)}") from None
