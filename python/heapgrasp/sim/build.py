"""A run's configuration made into simulated parts: the object library, the robot (the
free-flying hand or the Panda arm with its hand-eye camera), the scene truth, and the
loop's pipeline on them."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.methods import method_of
from heapgrasp.loop.observe import PhaseObserver
from heapgrasp.loop.phase import Pipeline
from heapgrasp.loop.stages import build_pipeline, make_segmenter
from heapgrasp.perception.segmenters import IdealSegmenter
from heapgrasp.planning.critic import GraspCritic
from heapgrasp.planning.views import ViewScorer
from heapgrasp.planning.volumes import GraspPlanner
from heapgrasp.sim.object_model import ObjectModel, default_cache_dir
from heapgrasp.sim.objects import ObjectLibrary, user_models
from heapgrasp.sim.optics import DepthModel
from heapgrasp.sim.robot import Robot, SimCamera, SimRobot
from heapgrasp.sim.truth import SimTruth
from heapgrasp.sim.world import SimWorld, WorldConfig

__all__ = [
    "make_body",
    "object_library",
    "scene_world",
    "sim_camera",
    "sim_pipeline",
    "table_capacity",
]


def object_library(
    config: RunConfig, *, on_skip: Callable[[str], None] | None = None
) -> ObjectLibrary:
    """The object library of ``config.object_set`` (generated once into the cache), or the
    user's objects in ``config.object_dir``, all of them in ``config.split``
    (:func:`~heapgrasp.sim.objects.user_models`; ``on_skip`` is told of each subfolder
    that holds no object and of each object that cannot be used, by name and problem, which
    is left out; default: nothing is said).

    Raises
    ------
    ConfigError
        Naming the directory, or each object file and its problem, when
        ``config.object_dir`` is missing, holds no object, or holds no object that can be
        used (each has no visual mesh, a mesh that does not load, or is larger than the
        workspace cube).
    """
    if config.object_dir is not None:
        try:
            return ObjectLibrary(_user_objects(config, on_skip or (lambda message: None)))
        except (OSError, ValueError) as exc:
            raise ConfigError(f"object_dir: {exc}") from None
    if config.object_set == "procedural":
        return ObjectLibrary.default(random_urdfs=0, mug=False, procedural_per_kind=16)
    return ObjectLibrary.default()


#: The user's objects this process has loaded, by directory, cache, split, cube and the
#: directory's files (path, size, modification time): every scene of a run builds its
#: library, and reading a few dozen scanned meshes again would take seconds each time.
_USER_OBJECTS: dict[tuple[object, ...], list[ObjectModel]] = {}


def _user_objects(config: RunConfig, on_skip: Callable[[str], None]) -> list[ObjectModel]:
    folder = Path(str(config.object_dir))
    files = sorted(p for p in folder.rglob("*") if p.is_file()) if folder.is_dir() else []
    stats = [(str(p), p.stat().st_size, p.stat().st_mtime_ns) for p in files]
    cache = default_cache_dir()
    key = (str(folder.absolute()), str(cache), config.split, config.cube_size, tuple(stats))
    if key not in _USER_OBJECTS:
        bad: list[str] = []

        def skip_bad(name: str, problem: str) -> None:
            bad.append(problem)
            on_skip(f"skipped {name}: {problem}")

        models = user_models(
            folder,
            cache,
            test_fraction=1.0 if config.split == "test" else 0.0,
            max_extent=config.cube_size,
            on_skip=on_skip,
            on_bad=skip_bad,
        )
        if not models:  # refused only when nothing usable is left
            raise ValueError(
                f"none of the {len(bad)} objects in {folder} can be used:\n  " + "\n  ".join(bad)
            )
        _USER_OBJECTS.clear()  # one run, one directory: keep the latest only
        _USER_OBJECTS[key] = models
    return _USER_OBJECTS[key]


def table_capacity(config: RunConfig, library: ObjectLibrary | None = None) -> int:
    """The most objects of ``config``'s split that could stand side by side on the
    table under the scene cube: its area over the smallest footprint (x by y extent) of
    the split's objects. A scene of more cannot be placed (piles place far fewer: the
    rest roll off the table and are removed)."""
    models = (library or object_library(config)).models(split=config.split)
    if not models:
        return 0
    smallest = min(m.extents[0] * m.extents[1] for m in models)
    return int(config.cube_size * config.cube_size / smallest)


@contextmanager
def scene_world(
    config: RunConfig,
    seed: int,
    category: str,
    *,
    library: ObjectLibrary | None = None,
    gui: bool = False,
) -> Iterator[SimWorld]:
    """A world holding the scene of ``seed`` (``config``'s layout, objects and split, the
    scene group ``category``), settled; closed on exit. ``library`` defaults to
    :func:`object_library`."""
    with SimWorld(
        library if library is not None else object_library(config),
        config=WorldConfig(cube_size=config.cube_size),
        depth_model=DepthModel(ideal=config.ideal_depth),
        gui=gui,
        seed=seed,
    ) as world:
        world.reset(
            layout=config.layout,  # type: ignore[arg-type]
            n_objects=config.objects,
            category=category,
            seed=seed,
            split=config.split,  # type: ignore[arg-type]
        )
        yield world


def sim_camera(config: RunConfig, *, rgb: bool = False) -> SimCamera:
    """The method's camera: VGN's 640×480 depth camera (HEAPGrasp §VI-B), else the
    320×240 RGB camera of continuous capture; ``rgb`` renders colour images too (slow,
    for recordings: the loop's segmenters read the scene truth)."""
    if method_of(config).depth:
        return SimCamera(CameraSpec.still(), depth=True, rgb=rgb)
    return SimCamera(CameraSpec.continuous(), depth=False, rgb=rgb)


def make_body(config: RunConfig, world: SimWorld) -> Robot:
    """The free-flying hand or the Panda arm (``config.mount``)."""
    if config.mount == "arm":
        from heapgrasp.sim.arm import PandaArm
        from heapgrasp.sim.arm_config import ArmConfig

        # The arm picks the camera roll about the viewing axis: paths leaving the top of
        # the view sphere would otherwise spin the wrist past its limits.
        return PandaArm(world, ArmConfig(camera_roll="free"))
    from heapgrasp.sim.gripper import PandaHand

    return PandaHand(world)


def sim_pipeline(
    config: RunConfig,
    world: SimWorld,
    *,
    seed: int = 0,
    body: Robot | None = None,
    grasp_planner: GraspPlanner | None = None,
    view_scorer: ViewScorer | None = None,
    critic: GraspCritic | None = None,
    observer: PhaseObserver | None = None,
    rgb: bool = False,
) -> Pipeline:
    """The pipeline of ``config`` in ``world`` (after ``world.reset``): the simulated robot
    (``body``, default :func:`make_body`), its scene truth, and the segmenter reading
    exact (or noisy) silhouettes from it; any stage passed replaces the configured one.
    ``rgb``: the camera renders colour images too (:func:`sim_camera`)."""
    camera = sim_camera(config, rgb=rgb or method_of(config).rgb)
    robot = SimRobot(body if body is not None else make_body(config, world), camera)
    truth = SimTruth(world, robot.body)
    return build_pipeline(
        config,
        robot,
        segmenter=make_segmenter(config, truth, seed),
        # with pixel-flip noise, the noise-free grid of the same frames (Table V)
        reference_segmenter=IdealSegmenter(truth) if config.noise > 0 else None,
        truth=truth,
        grasp_planner=grasp_planner,
        view_scorer=view_scorer,
        critic=critic,
        observer=observer,
        seed=seed,
    )
