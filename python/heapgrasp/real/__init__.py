"""HEAPGrasp on a real robot: the commands behind ``heapgrasp robot`` (``init``, ``check``,
``board``, ``calibrate``, ``run``, ``replay``).

* :mod:`~heapgrasp.real.stages` — ``robot.toml`` → the loop's settings and a connected
  :class:`~heapgrasp.robot.hardware.HardwareRobot`;
* :mod:`~heapgrasp.real.recording` — every frame a run captures, saved as it is taken;
* :mod:`~heapgrasp.real.session` — the dry run (plans one phase, moves nothing) and the
  executed clutter-removal run (``results.json`` / ``scenes.jsonl`` as the simulator's);
* :mod:`~heapgrasp.real.replay` — perception and planning rerun on a recorded run;
* :mod:`~heapgrasp.real.check` — what each device reports, without motion;
* :mod:`~heapgrasp.real.calibrate` — hand-eye calibration on the arm (or rehearsed on
  rendered board images).

Nothing here imports PyBullet or the simulator (import-linter checks it).
"""
