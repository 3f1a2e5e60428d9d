"""The supervised viewsphere policies' dataset (Natarajan et al. §4.3.1, after Calli et al. 2018a):
random exploration from random starts, labelled with the first direction of the
shortest path that found a grasp; or, beyond the paper, every first move of a shortest
path found by breadth-first search (``labels="bfs"``), on states a policy meets after
some moves (``prefix_steps``) and on procedural objects of many shapes
(``procedural``).

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

With ``labels="bfs"``, steps 3–4 are exact instead (:func:`optimal_first_moves`): from
the state (the start, then 0 to ``prefix_steps`` random moves, a scene whose views
yield a grasp on the way being dropped) a breadth-first search over the sets of views
finishes the first level at which any continuation yields a grasp, and every first
direction of those continuations is optimal: ``lengths`` holds that level for them (0
for the others) and the label is one of them at random. A scene whose search finds
nothing within ``max_steps`` levels or the ``bfs_max_sets`` budget is dropped. With
``procedural > 0`` the scenes draw, in turn, from ``objects`` and that many procedural
objects of each kind (:func:`heapgrasp.sim.procedural.procedural_mesh`, generator seed
:data:`PROCEDURAL_SEED`, none of the benchmark's), each resting in its most stable pose.

Each shard holds, with the sample axis first: ``state`` (float32 ``(N, 52)``,
:func:`~heapgrasp.viewsphere.learned.state_features` of the start view),
``label`` (int64), ``lengths`` (int64 ``(N, 8)``: each direction's shortest path, 0
where none was found or the direction is not a step), ``object`` (int64, an index of
:meth:`ViewspherePathsConfig.object_names`), ``yaw`` and ``start`` (radians; ``start``
is the state's pose, ``(azimuth, polar)``), ``prefix`` (int64, the moves taken before
the state), ``k`` (the scene index) and the counts ``scenes`` and ``dropped``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from heapgrasp.data.shards import DatasetSpec, ShardedConfig
from heapgrasp.viewsphere.grasps import ViewsphereConfig

__all__ = [
    "FORMAT",
    "LABELS",
    "PROCEDURAL_SEED",
    "SPEC",
    "ViewspherePathsConfig",
    "optimal_first_moves",
    "scene_sample",
]

FORMAT = "heapgrasp-viewsphere-paths"
VERSION = 1
#: The training objects of the supervised policies. The paper's are the 10 × 8 × 4 and
#: 20 × 6 × 5 cm prisms; lying flat, the first has no grasp for the 8 cm hand (its 8 cm
#: side is the opening and the 4 cm one stands on the table), so every scene of it was
#: dropped after the longest search: the 6 × 6 × 6 cm prism takes its place.
SUPERVISED_OBJECTS = ("prism_20x6x5", "prism_6x6x6")
#: How states are labelled (module doc).
LABELS = ("paths", "bfs")
#: The procedural objects' generator seed (the benchmark library's is 0).
PROCEDURAL_SEED = 1001


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
    labels: str = "paths"
    """``paths`` (the paper's random paths) or ``bfs`` (every optimal first move)."""
    prefix_steps: int = 0
    """Random moves before the state, at most (``bfs`` labels only)."""
    procedural: int = 0
    """Procedural objects per kind beside ``objects``."""
    bfs_max_sets: int = 300
    """Syntheses per state for ``bfs`` labels, at most (two levels take about 60)."""

    spec: ClassVar[DatasetSpec] = SPEC

    def __post_init__(self) -> None:
        super().__post_init__()
        self.positive("tries", "path_steps", "bfs_max_sets")
        if self.labels not in LABELS:
            raise ValueError(f"labels must be one of {', '.join(LABELS)}, got {self.labels!r}")
        for name in ("prefix_steps", "procedural"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{name} must be an int >= 0, got {value!r}")
        if self.prefix_steps and self.labels != "bfs":
            raise ValueError("prefix_steps needs labels='bfs' (the paper's labels start fresh)")
        from heapgrasp.viewsphere.objects import TEST_OBJECTS, TRAIN_OBJECTS

        allowed = TEST_OBJECTS if self.split == "test" else TRAIN_OBJECTS
        bad = [o for o in self.objects if o not in allowed]
        if bad or not self.objects:
            raise ValueError(
                f"objects of the {self.split} split must be among {', '.join(allowed)}; "
                f"got {', '.join(bad) or 'none'}"
            )

    def object_names(self) -> list[str]:
        from heapgrasp.sim.procedural import PROCEDURAL_KINDS

        extra = [
            f"procedural/{k}_{i:02d}" for k in PROCEDURAL_KINDS for i in range(self.procedural)
        ]
        return [*self.objects, *extra]

    def run_shard(self, shard: int) -> dict[str, Any]:
        """The arrays of ``shard`` (module doc)."""
        scenes = self.shard_scenes(shard)
        samples = [s for s in (scene_sample(self, i) for i in scenes) if s is not None]
        keys = ("state", "label", "lengths", "object", "yaw", "start", "prefix", "k")
        dtypes = {
            "state": np.float32,
            "label": np.int64,
            "lengths": np.int64,
            "object": np.int64,
            "yaw": np.float64,
            "start": np.float64,
            "prefix": np.int64,
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


def _object_meshes(name: str) -> list[tuple[Any, Any]]:
    """The resting meshes of a stand-in or of ``procedural/<kind>_<ii>``."""
    from heapgrasp.viewsphere.objects import placement, stand_ins

    if not name.startswith("procedural/"):
        return list(stand_ins([name])[0].meshes)
    from heapgrasp.sim.procedural import procedural_mesh

    kind, index = name.split("/", 1)[1].rsplit("_", 1)
    mesh = procedural_mesh(kind, int(index), PROCEDURAL_SEED)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    f = np.asarray(mesh.faces, dtype=np.int64)
    v = v @ placement(v, f, None).rotation.T
    lo, hi = v.min(axis=0), v.max(axis=0)
    return [(v - np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]), f)]


def optimal_first_moves(
    world: Any, poses: list[Any], *, max_steps: int, max_sets: int
) -> tuple[int, list[int]] | None:
    """The fewest further moves from ``poses`` (the views so far, the current pose last)
    to views that yield a grasp, and every first direction of a path that few moves long
    (breadth-first over the sets of views, the level finished once one is found); None
    when none is found within ``max_steps`` moves or ``max_sets`` syntheses. A level cut
    short by the budget gives the first directions found in it (each optimal, perhaps
    not all)."""
    from heapgrasp.viewsphere.policies import pose_key
    from heapgrasp.viewsphere.sphere import DIRECTIONS

    sphere = world.sphere
    frontier: list[tuple[tuple[Any, ...], int]] = [(tuple(poses), -1)]
    seen: set[tuple[Any, frozenset[Any], int]] = set()
    asked = 0
    for depth in range(1, max_steps + 1):
        winners: set[int] = set()
        nxt: list[tuple[tuple[Any, ...], int]] = []
        for path, first in frontier:
            for d in range(len(DIRECTIONS)):
                taken, pose = sphere.move(path[-1], d)
                if taken != d:  # the fallback leads where another direction does
                    continue
                head = d if first < 0 else first
                new = (*path, pose)
                state = (pose_key(pose), frozenset(pose_key(p) for p in new), head)
                if state in seen or head in winners:
                    continue
                seen.add(state)
                asked += 1
                if asked > max_sets:
                    return (depth, sorted(winners)) if winners else None
                if world.grasp(list(new)) is not None:
                    winners.add(head)
                else:
                    nxt.append((new, head))
        if winners:
            return depth, sorted(winners)
        frontier = nxt
    return None


def _bfs_sample(
    config: ViewspherePathsConfig, world: Any, start: Any, rng: np.random.Generator
) -> tuple[list[Any], npt.NDArray[np.int64], int] | None:
    """The state's views (after the random prefix), each direction's length and the
    label, by :func:`optimal_first_moves`; None to drop the scene."""
    from heapgrasp.viewsphere.sphere import DIRECTIONS

    poses = [start]
    for _ in range(int(rng.integers(0, config.prefix_steps + 1))):
        poses.append(world.sphere.move(poses[-1], int(rng.integers(len(DIRECTIONS))))[1])
        if world.grasp(poses) is not None:
            return None
    vs = world.config
    best = optimal_first_moves(world, poses, max_steps=vs.max_steps, max_sets=config.bfs_max_sets)
    if best is None:
        return None
    depth, winners = best
    lengths = np.zeros(len(DIRECTIONS), dtype=np.int64)
    lengths[winners] = depth
    return poses, lengths, int(rng.choice(winners))


def scene_sample(config: ViewspherePathsConfig, index: int) -> dict[str, Any] | None:
    """Scene ``index``'s sample (module doc), or None when it is dropped."""
    from heapgrasp.viewsphere.learned import state_features
    from heapgrasp.viewsphere.sphere import DIRECTIONS, SpherePose
    from heapgrasp.viewsphere.world import ViewsphereWorld

    rng = np.random.default_rng([config.root_seed, index])
    names = config.object_names()
    name = names[index % len(names)]
    yaw = float(rng.uniform(0.0, 2 * math.pi))
    c, s = math.cos(yaw), math.sin(yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    vs = ViewsphereConfig()
    world = ViewsphereWorld(
        [(v @ turn.T, f) for v, f in _object_meshes(name)],
        config=vs,
        seed=config.root_seed * 100_003 + index,
    )
    sphere = world.sphere
    start = SpherePose(
        float(rng.uniform(0.0, 2 * math.pi)), float(rng.uniform(0.0, sphere.max_polar))
    )
    if world.grasp([start]) is not None:
        return None
    scorer = vs.view_scorer(sphere, world.camera)
    if config.labels == "bfs":
        labelled = _bfs_sample(config, world, start, rng)
        if labelled is None:
            return None
        poses, bfs_lengths, bfs_label = labelled
        obj, unexplored = world.grasps.fused(poses)
        return {
            "state": state_features(obj, scorer.targets(unexplored), poses[-1], sphere),
            "label": bfs_label,
            "lengths": bfs_lengths,
            "object": names.index(name),
            "yaw": yaw,
            "start": (poses[-1].azimuth, poses[-1].polar),
            "prefix": len(poses) - 1,
            "k": index,
        }
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
    state: npt.NDArray[np.float32] = state_features(obj, scorer.targets(unexplored), start, sphere)
    return {
        "state": state,
        "label": label,
        "lengths": lengths,
        "object": names.index(name),
        "yaw": yaw,
        "start": (start.azimuth, start.polar),
        "prefix": 0,
        "k": index,
    }
