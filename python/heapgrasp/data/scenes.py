"""What the networks' datasets share about a scene: the object splits, the loop's run
settings, and the captures of HEAPGrasp's Algorithm 1."""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "VAL_FRACTION",
    "capture_random_views",
    "dataset_objects",
    "object_split",
    "run_config",
    "split_models",
]

F64 = npt.NDArray[np.float64]

VAL_FRACTION = 0.2
"""Share of the library's train objects held out for validation (:func:`object_split`)."""


def object_split(name: str, library_split: str) -> str:
    """``train``, ``val`` or ``test`` for an object of the library's ``train`` or
    ``test`` split: the test split stays the benchmark's held-out objects; a stable hash
    of the name moves :data:`VAL_FRACTION` of the train objects to ``val``."""
    if library_split == "test":
        return "test"
    digest = hashlib.sha256(f"heapgrasp-val:{name}".encode()).digest()
    return "val" if int.from_bytes(digest[:8], "big") / 2**64 < VAL_FRACTION else "train"


def split_models(library: Any, split: str) -> list[Any]:
    """The library's objects of the dataset split ``split`` (:func:`object_split`)."""
    library_split = "test" if split == "test" else "train"
    models = [
        m for m in library.models(split=library_split) if object_split(m.name, m.split) == split
    ]
    if not models:
        raise ValueError(f"the object library has no {split!r} objects")
    return models


def dataset_objects(split: str) -> list[str]:
    """The names of the objects of the dataset split ``split``, sorted."""
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.sim.build import object_library

    return sorted(m.name for m in split_models(object_library(RunConfig()), split))


def run_config(split: str, start: str, L: int, method: str = "heapgrasp") -> Any:
    """The loop's settings of a dataset's scene: ``method`` from ``start`` with ``L``
    view waypoints, everything else the defaults (the oracle view planner, which needs
    no weights, where ``method`` plans views; no grasp critic; no look again, so that a
    phase plans grasps once, on the grid the dataset records)."""
    from heapgrasp.loop.config import RunConfig

    return RunConfig(
        method=method,
        view_planner="oracle",
        split="test" if split == "test" else "train",
        start=start,
        L=L,
        grasp_critic="none",
        look_again=0,
        fine_width=False,
    )


def capture_random_views(pipeline: Any, rng: np.random.Generator, k: int) -> F64:
    """Algorithm 1's captures on ``pipeline`` (a silhouette
    :class:`~heapgrasp.loop.phase.Pipeline`): a fresh phase's first frame at ``p⁰``,
    then ``k`` view waypoints drawn from ``rng`` without replacement from the ``U × V``
    candidates, captured continuously along the loop's timed paths; returns the camera
    pose at the last one."""
    from heapgrasp.geometry.motion import plan_waypoints

    perception = pipeline.perception
    arm = pipeline.robot.arm
    arm.park()
    perception.reset()
    first = arm.look(pipeline.initial_pose())
    perception.update([first])
    current: F64 = first.cam2world
    u_count, v_count = pipeline.candidates.shape[:2]
    picks = rng.choice(u_count * v_count, size=k, replace=False)
    for flat in picks:
        goal = pipeline.candidates[flat // v_count, flat % v_count]
        (path,) = plan_waypoints(
            current, [goal], pipeline.sphere, pipeline.limits, pipeline.config.fps
        )
        cap = arm.follow(path)
        perception.update(cap.frames[1:])
        current = cap.poses[-1]
    return current
