"""The real-robot commands rehearsed against the simulator (``heapgrasp robot ... --sim``).

:class:`~heapgrasp.sim.rehearsal.rig.Rehearsal` puts a UR5e controller, a RealSense and a
gripper into the simulator behind the interfaces the real drivers use, so ``robot
check``, ``robot calibrate``, a dry ``robot run``, ``robot run --execute``, ``replay`` and
``show`` can all be tried on a laptop, on the same ``robot.toml`` (docs/real_robot.md,
"Rehearse without a robot").
"""

from heapgrasp.sim.rehearsal.rig import Rehearsal

__all__ = ["Rehearsal"]
