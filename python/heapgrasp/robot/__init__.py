"""The robot seam: what the loop needs from a robot, and the grasp sequence built on it.

* :mod:`~heapgrasp.robot.interfaces` — :class:`Camera`, :class:`Arm`, :class:`Gripper`,
  :class:`Robot`, and the optional :class:`SceneTruth` that only a simulator provides;
* :mod:`~heapgrasp.robot.grasping` — a grasp, its execution (pre-grasp, approach along
  the grasp's z, close, lift) and placing.

The simulator implements these in :mod:`heapgrasp.sim.robot`; a hardware driver
implements the same protocols.
"""
