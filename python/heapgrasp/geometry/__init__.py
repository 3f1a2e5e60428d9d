"""Geometry and motion: no simulation, no hardware.

* :mod:`~heapgrasp.geometry.camera` — pinhole intrinsics (:class:`CameraSpec`);
* :mod:`~heapgrasp.geometry.grid` — the scene cube and its voxel grid (:class:`GridFrame`);
* :mod:`~heapgrasp.geometry.gripper` — the gripper's geometry, in one place;
* :mod:`~heapgrasp.geometry.motion` — the view sphere (eq. 12), the interpolation ``f``
  of eq. 8 and ruckig timing.
"""
