"""The supervised viewsphere policies' dataset (Natarajan et al. §4.3.1, after Calli et al. 2018a):
random exploration from random starts, labelled with the first direction of the
shortest path that found a grasp.

For every scene (a generator seeded by the dataset's root seed and the scene's index,
so a shard re-run gives the same bytes):

1. an object of ``objects`` (in turn; by default the 20 × 6 × 5 and 6 × 6 × 6 cm
   prisms: the supervised policies never see a test object) at a random yaw,
   and a random start on the viewsphere (azimuth uniform, polar angle uniform over
   ``[0, max_polar]``);
2. a scene whose start view already yields a grasp has nothing to decide: dropped;
3. for each of the 8 directions (one whose step falls back onto another's is left
   out), ``tries`` paths: that step first, then uniformly random ones, at most
   ``path_steps`` moves in all, each stopped at the first set of views that yields a
   grasp (:class:`~heapgrasp.viewsphere.grasps.ViewsphereGrasps`, the start's unexplored
   region) or once it is longer than the shortest found so far;
4. the label: the first direction of the shortest path that found a grasp (ties drawn
   at random, so no direction is favoured by the order of the search); a scene where
   no path found one is dropped.

Each shard holds, with the sample axis first: ``state`` (float32 ``(N, 52)``,
:func:`~heapgrasp.viewsphere.learned.state_features` of the start view),
``label`` (int64), ``lengths`` (int64 ``(N, 8)``: each direction's shortest path, 0
where none was found or the direction is not a step), ``object`` (int64, an index of
``objects``), ``yaw`` and ``start`` (radians; ``start`` is ``(azimuth, polar)``),
``k`` (the scene index) and the counts ``scenes`` and ``dropped``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from heapgrasp.data.shards import DatasetSpec, ShardedConfig
from heapgrasp.viewsphere.grasps import ViewsphereConfig

__all__ = ["FORMAT", "SPEC", "ViewspherePathsConfig", "scene_sample"]

FORMAT = "heapgrasp-viewsphere-paths"
VERSION = 1
#: The training objects of the supervised policies. The paper's are the 10 × 8 × 4 and
#: 20 × 6 × 5 cm prisms; lying flat, the first has no grasp for the 8 cm hand (its 8 cm
#: side is the opening and the 4 cm one stands on the table), so every scene of it was
#: dropped after the longest search: the 6 × 6 × 6 cm prism takes its place.
SUPERVISED_OBJECTS = ("prism_20x6x5", "prism_6x6x6")


def _settings() -> dict[str, Any]:
    from heapgrasp.viewsphere.learned import GRID, N_FEATURES

    return {"viewsphere": ViewsphereConfig().to_dict(), "grid": GRID, "n_features": N_FEATURES}


SPEC = DatasetSpec(FORMAT, VERSION, "viewsphere paths dataset", _settings)
"""What the manifest says of the dataset."""


@dataclass(frozen=True)
class ViewspherePathsConfig(ShardedConfig):
    """What a dataset holds (module doc)."""

    shard_size: int = 20
    objects: tuple[str, ...] = SUPERVISED_OBJECTS
    """Stand-ins of the training shapes (or of the test objects with ``split="test"``,
    for measuring only)."""
    tries: int = 3
    """Random paths per direction."""
    path_steps: int = 5
    """Moves per path, at most."""

    spec: ClassVar[DatasetSpec] = SPEC

    def __post_init__(self) -> None:
        super().__post_init__()
        self.positive("tries", "path_steps")
        from heapgrasp.viewsphere.objects import TEST_OBJECTS, TRAIN_OBJECTS

        allowed = TEST_OBJECTS if self.split == "test" else TRAIN_OBJECTS
        bad = [o for o in self.objects if o not in allowed]
        if bad or not self.objects:
            raise ValueError(
                f"objects of the {self.split} split must be among {', '.join(allowed)}; "
                f"got {', '.join(bad) or 'none'}"
            )

    def object_names(self) -> list[str]:
        return list(self.objects)

    def run_shard(self, shard: int) -> dict[str, Any]:
        """The arrays of ``shard`` (module doc)."""
        scenes = self.shard_scenes(shard)
        samples = [s for s in (scene_sample(self, i) for i in scenes) if s is not None]
        keys = ("state", "label", "lengths", "object", "yaw", "start", "k")
        dtypes = {
            "state": np.float32,
            "label": np.int64,
            "lengths": np.int64,
            "object": np.int64,
            "yaw": np.float64,
            "start": np.float64,
            "k": np.int64,
        }
        out: dict[str, Any] = {}
        for key in keys:
            values = [s[key] for s in samples]
            empty = {"state": (0, _n_features()), "lengths": (0, 8), "start": (0, 2)}
            out[key] = (
                np.asarray(values, dtype=dtypes[key])
                if values
                else np.zeros(empty.get(key, (0,)), dtype=dtypes[key])
            )
        out["scenes"] = len(scenes)
        out["dropped"] = len(scenes) - len(samples)
        return out


def _n_features() -> int:
    from heapgrasp.viewsphere.learned import N_FEATURES

    return N_FEATURES


def scene_sample(config: ViewspherePathsConfig, index: int) -> dict[str, Any] | None:
    """Scene ``index``'s sample (module doc), or None when it is dropped."""
    from heapgrasp.viewsphere.learned import state_features
    from heapgrasp.viewsphere.objects import stand_ins
    from heapgrasp.viewsphere.sphere import DIRECTIONS, SpherePose
    from heapgrasp.viewsphere.world import ViewsphereWorld

    rng = np.random.default_rng([config.root_seed, index])
    name = config.objects[index % len(config.objects)]
    yaw = float(rng.uniform(0.0, 2 * math.pi))
    vs = ViewsphereConfig()
    world = ViewsphereWorld(
        list(stand_ins([name])[0].posed(yaw)), config=vs, seed=config.root_seed * 100_003 + index
    )
    sphere = world.sphere
    start = SpherePose(
        float(rng.uniform(0.0, 2 * math.pi)), float(rng.uniform(0.0, sphere.max_polar))
    )
    if world.grasp([start]) is not None:
        return None
    n = len(DIRECTIONS)
    best = config.path_steps + 1
    lengths = np.zeros(n, dtype=np.int64)
    for d in range(n):
        taken, first = sphere.move(start, d)
        if taken != d:
            continue
        for _ in range(config.tries):
            poses = [start, first]
            while len(poses) - 1 <= min(best, config.path_steps):
                if world.grasp(poses) is not None:
                    found = len(poses) - 1
                    best = min(best, found)
                    if lengths[d] == 0 or found < lengths[d]:
                        lengths[d] = found
                    break
                if len(poses) - 1 == min(best, config.path_steps):
                    break
                poses.append(sphere.move(poses[-1], int(rng.integers(n)))[1])
    reached = lengths[lengths > 0]
    if len(reached) == 0:
        return None
    shortest = int(reached.min())
    ties = np.flatnonzero(lengths == shortest)
    label = int(rng.choice(ties))
    obj, unexplored = world.grasps.fused([start])
    scorer = vs.view_scorer(sphere, world.camera)
    state: npt.NDArray[np.float32] = state_features(obj, scorer.targets(unexplored), start, sphere)
    return {
        "state": state,
        "label": label,
        "lengths": lengths,
        "object": config.objects.index(name),
        "yaw": yaw,
        "start": (start.azimuth, start.polar),
        "k": index,
    }
