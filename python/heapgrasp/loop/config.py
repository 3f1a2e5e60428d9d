"""Run configuration: Table I, the run, our extensions; a TOML file and CLI overrides.

Every setting of a closed-loop run lives in :class:`RunConfig`, in three groups: the run
(method, scenes, seeds), the method's parameters (HEAPGrasp's Table I: cube 0.30 m, 40³
grid, r = 0.33 m, θ_max = π/5, U×V = 40×20, L = 3, λ = 0.9, ε, γ1 = 0.2, γ2 = 0.0 for the
first waypoint then 0.35; VGN's smoothing and NMS; the camera's motion limits) and our
extensions, which are not in the paper. The defaults are Table I plus the extensions
measured to help (roof trimming, the learned critic, the failed-grasp memory, the target
column, the look again before giving up); the ``paper`` preset is Table I with nothing
added. A TOML file holds any subset of the settings at top level, e.g.::

    method = "heapgrasp"
    L = 3
    gamma2 = 0.35
    noise = 0.05

Unknown keys and values of the wrong type or range raise :class:`ConfigError` naming
the key, the value and the file.

Presets are such files shipped with the package (:data:`PRESETS_DIR`), named by their
stem: ``--config short-path`` (:func:`presets`, :meth:`RunConfig.load`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

__all__ = [
    "CATEGORIES",
    "GRASP_PLANNERS",
    "GROUPS",
    "LAYOUTS",
    "METHODS",
    "MOUNTS",
    "OBJECT_SETS",
    "PAPER_EXTENSIONS",
    "PATH_SETTINGS",
    "PRESETS_DIR",
    "SEGMENTERS",
    "STARTS",
    "VIEW_PLANNERS",
    "ConfigError",
    "ConfigFile",
    "RunConfig",
    "compose",
    "parse_sets",
    "presets",
]

#: ``--method`` values: the proposed method and the baselines of HEAPGrasp §VI-B.
METHODS = ("heapgrasp", "no-vp", "vgn", "hemisphere6")
#: ``--view-planner`` values (used by ``heapgrasp``; the baselines fix their own views).
VIEW_PLANNERS = ("oracle", "network", "circle", "hemisphere6")
#: ``segmenter`` values: the simulator's exact silhouettes, or the segmentation network.
SEGMENTERS = ("truth", "network")
#: ``--grasp-planner`` values.
GRASP_PLANNERS = ("antipodal", "network")
LAYOUTS = ("pile", "packed")
CATEGORIES = ("transparent", "specular", "opaque", "mixed")
MOUNTS = ("free", "arm")
OBJECT_SETS = ("procedural", "all")
#: Settings that name a file or folder (stored absolute, :class:`RunConfig`).
PATH_SETTINGS = ("grasp_weights", "view_weights", "seg_weights", "object_dir", "grasp_critic")
#: The shipped presets: ``NAME.toml`` files of :class:`RunConfig` fields.
PRESETS_DIR = Path(__file__).resolve().parent / "presets"


def presets() -> dict[str, Path]:
    """The shipped presets by name (a file's stem), e.g. ``{"short-path": …}``."""
    return {p.stem: p for p in sorted(PRESETS_DIR.glob("*.toml"))}


class ConfigError(ValueError):
    """A configuration value (or file) is invalid."""


#: The groups of :class:`RunConfig`'s settings.
GROUPS = ("run", "method", "extension")
#: The start poses of :attr:`RunConfig.start`: (distance from the scene's bottom centre
#: (m), polar angle (rad), azimuth (rad)).
STARTS = {"side": (0.5, 0.9, -math.pi / 2), "above": (0.6, 0.0, -math.pi / 2)}


def _setting(group: str, default: Any, source: str) -> Any:
    return field(default=default, metadata={"group": group, "source": source})


def _run(default: Any, source: str) -> Any:
    return _setting("run", default, source)


def _method(default: Any, source: str) -> Any:
    return _setting("method", default, source)


def _ext(default: Any, source: str) -> Any:
    return _setting("extension", default, source)


@dataclass(frozen=True)
class RunConfig:
    """All settings of a run, in three groups (:data:`GROUPS`; ``docs/running.md`` lists
    each with its default and its source):

    * ``run`` — what to run and on which scenes;
    * ``method`` — the method's parameters: HEAPGrasp's Table I, VGN's, and the camera
      motion's;
    * ``extension`` — ours, not in the paper: each is on in the defaults or in a shipped
      preset (the ``paper`` preset turns every one off).
    """

    # ------------------------------------------------------------------ run
    method: str = _run("heapgrasp", "§VI-B")
    """``heapgrasp`` (view planning), ``no-vp`` (once around a circle of L waypoints, SfS),
    ``vgn`` (circle, depth → TSDF) or ``hemisphere6`` (GraspNeRF's six views, SfS)."""
    view_planner: str = _run("network", "§IV-B")
    """View planner of ``heapgrasp``: ``network`` (the view network of eq. 13, the shipped
    weights or ``view_weights``; runs on a robot), ``oracle`` (exact eq. 14 from the true
    meshes: an upper bound that needs the simulator), ``circle`` or ``hemisphere6``."""
    grasp_planner: str = _run("auto", "ours")
    """``antipodal`` (analytic, no training), ``network`` (VGN weights; its grasps are
    checked against the hull, or for ``vgn`` against the TSDF's observed shells,
    :mod:`heapgrasp.planning.hull_check`) or ``auto``: the network for ``vgn`` (VGN's
    own planner, §VI-B), the analytic planner for the silhouette methods (see
    :attr:`grasp_planner_in_use`)."""
    grasp_weights: str | None = _run(None, "ours")
    """Path of the grasp network's ONNX file (``grasp_planner = "network"``)."""
    view_weights: str | None = _run(None, "ours")
    """Path of the view network's ONNX file (``view_planner = "network"``); None: the
    shipped ``weights/view_network.onnx``."""
    net_device: str = _run("cpu", "ours")
    """Where the networks run (onnxruntime): ``cpu``, ``cuda``, ``cuda:N`` or ``auto``."""
    layout: str = _run("pile", "VGN")
    """``pile`` or ``packed`` scenes."""
    category: str = _run("mixed", "§VI-C")
    """Scene group: ``transparent``, ``specular``, ``opaque`` or ``mixed``."""
    objects: int = _run(5, "Table I")
    """Objects per scene (N_ob)."""
    scenes: int = _run(1, "ours")
    """Scenes to run (scene ``i`` has seed ``seed + i``)."""
    seed: int = _run(0, "ours")
    """Seed of scene 0."""
    split: str = _run("test", "ours")
    """Objects drawn from the ``test`` (held-out) or ``train`` split."""
    object_set: str = _run("procedural", "ours")
    """``procedural``: boxes, cylinders, bottles, cups and bowls sized for the 8 cm
    gripper (the benchmark's set); ``all``: also pybullet_data's random_urdfs and the mug."""
    object_dir: str | None = _run(None, "ours")
    """The user's objects instead of ``object_set``: a directory whose subfolders each hold
    a PyBullet object (``model.urdf`` and its meshes, in metres), or of mesh / URDF files
    (:func:`heapgrasp.sim.objects.user_models`). Scenes draw from these objects only, every
    one of them in ``split``."""
    mount: str = _run("free", "VGN")
    """``free`` (free-flying camera and hand, VGN's simulation) or ``arm`` (Panda arm,
    hand-eye camera)."""
    noise: float = _run(0.0, "Table V")
    """Probability that each mask pixel is flipped."""
    segmenter: str = _run("truth", "§V")
    """``truth`` (the simulator's exact silhouettes, with ``noise`` pixel flips) or
    ``network`` (the 4-class segmentation network of ``seg_weights`` on RGB frames)."""
    seg_weights: str | None = _run(None, "ours")
    """Path of the segmentation network's ONNX file (``segmenter = "network"``;
    ``heapgrasp seg train`` writes one)."""
    ideal_depth: bool = _run(False, "Table II")
    """Give the VGN baseline ideal depth (the paper's simulation, Table II) instead of the
    per-category sensor model (transparent / specular failures, Table III)."""
    max_attempts: int = _run(20, "ours")
    """Safety cap on grasp attempts per scene (the protocol normally stops first)."""
    # ------------------------------------------------------------------ method
    cube_size: float = _method(0.30, "Table I")
    """Side l of the scene cube (m)."""
    resolution: int = _method(40, "Table I")
    """N_x = N_y = N_z."""
    lam: float = _method(0.9, "Table I")
    """Occupancy threshold λ of the high-confidence grid."""
    epsilon: float | None = _method(None, "Table I")
    """Grasp score threshold ε; None = the grasp planner's own (Table I's 0.8 for the VGN
    network; the analytic planner's scores have another scale, see its docs)."""
    sigma: float | None = _method(None, "VGN")
    """Gaussian smoothing of the grasp scores (voxels); None = the grasp planner's own."""
    nms_window: int = _method(4, "VGN")
    """Non-maximum suppression window (voxels)."""
    gamma1: float = _method(0.2, "Table I")
    """Weight of the orientation term of dist (eq. 17)."""
    radius: float = _method(0.33, "Table I")
    """Radius r of the view sphere (m)."""
    theta_max: float = _method(math.pi / 5, "Table I")
    """Maximum polar angle θ_max of the candidates (rad)."""
    U: int = _method(40, "Table I")
    """Azimuth divisions of the candidates."""
    V: int = _method(20, "Table I")
    """Polar divisions of the candidates."""
    L: int = _method(3, "Table I")
    """Number of view waypoints."""
    gamma2_first: float = _method(0.0, "Table I")
    """γ2 of eq. 18 for the first view waypoint."""
    gamma2: float = _method(0.35, "Table I")
    """γ2 of eq. 18 for the following view waypoints."""
    fps: float = _method(30.0, "§V")
    """Camera frame rate during continuous capture (Hz)."""
    max_velocity: float = _method(0.25, "ours")
    """Camera speed limit of the timed paths (m/s, ruckig)."""
    max_acceleration: float = _method(1.0, "ours")
    """Acceleration limit (m/s², ruckig)."""
    max_jerk: float = _method(5.0, "ours")
    """Jerk limit (m/s³, ruckig)."""
    # ------------------------------------------------------------------ extensions
    start: str = _ext("side", "ours")
    """Initial camera pose p⁰ of every phase: ``side`` (0.5 m from the scene's bottom
    centre on its -y side at polar angle 0.9 rad, where the hand is after placing: §III,
    footnote 1) or ``above`` (0.6 m straight above the scene)."""
    roof_radius: float = _ext(0.0225, "ours")
    """Disc radius ρ (m) with which the roofs of the silhouette hull are trimmed before
    grasp planning, then checked against the phase's silhouettes
    (:mod:`heapgrasp.perception.roofs`); 0 gives the planner ``Ŝ≥λ`` as it is (the paper)."""
    grasp_critic: str = _ext("auto", "ours")
    """Learned critic that re-scores the grasp candidates (:mod:`heapgrasp.planning.critic`;
    silhouette methods): ``auto`` (the shipped weights wherever they apply: a silhouette
    method with the antipodal planner), ``none``, ``default`` (the shipped weights, an
    error where they cannot apply) or the path of a critic file."""
    failed_grasp_radius: float = _ext(0.02, "ours")
    """After a failed grasp, candidates within this distance of it (m) are not tried again
    until a grasp succeeds; 0 allows the repeat."""
    target_radius: float = _ext(0.08, "ours")
    """Radius (m) of the column around the target grasp on which the oracle counts eq. 14
    from the second waypoint on; 0 counts the whole grid (the paper's eq. 14)."""
    scene_memory: bool = _ext(False, "ours")
    """Silhouette methods: each phase starts from what the previous phases carved."""
    stop_below: float = _ext(0.0, "ours")
    """Early stop (:class:`heapgrasp.loop.extensions.EarlyStop`): from the second view
    waypoint on, stop viewing where no candidate's eq. 14 score on the target's column,
    less its detour, reaches this; ``L`` becomes the most waypoints. 0: never."""
    stop_detour_weight: float = _ext(0.0, "ours")
    """Early stop: weight (per metre) of the path a look adds on the way to the grasp."""
    stop_confidence: float = _ext(0.0, "ours")
    """Early stop and rim sweep: the target grasp's score (with the critic: probability of
    success) at which a phase may stop looking."""
    move_weight: float = _ext(0.0, "ours")
    """Eq. 18 maximises ``s + γ2 h`` less this weight (per metre) times the move's length."""
    sweep_degrees: float = _ext(0.0, "ours")
    """Rim sweep (:class:`heapgrasp.loop.extensions.RimSweep`): a phase that took all ``L``
    waypoints without stopping early goes on along the rim of the candidates by at most
    this many degrees, until a grasp reaches ``stop_confidence``. 0: never."""
    sweep_step: float = _ext(45.0, "ours")
    """Azimuth (degrees) between the rim sweep's waypoints."""
    look_again: int = _ext(2, "ours")
    """Where a phase finds no grasp candidate, look again up to this many times before
    the protocol stops on "no candidate" (rule iii): from the start pose turned about
    the scene (180°, then 90°, then 270°: :data:`heapgrasp.loop.phase.LOOK_AGAIN_TURNS`),
    viewing as the phase did and carving the same grid. 0: stop at once (the paper)."""
    fine_width: bool = _ext(True, "ours")
    """Where a phase still finds no grasp after its looks again: the analytic planner
    plans once more, on the phase's silhouettes carved into a grid 6 cm wider on every
    side, measuring each grasp's opening at the extreme voxel centres rather than their
    outer faces (one voxel wider), first at the grid's voxel with the critic, then at
    half of it without; a candidate is taken only when the hand, fully open, clears the
    silhouettes carved again three times finer around it
    (:meth:`heapgrasp.loop.phase.Pipeline.fine_width_grasp`). Silhouette methods with
    the analytic planner; False: the phase ends (the paper)."""

    def __post_init__(self) -> None:
        # Files as absolute paths: a saved run is resumed, shown and replayed from
        # anywhere (a relative path held the folder the run happened to start in).
        for name in PATH_SETTINGS:
            value = getattr(self, name)
            keyword = name == "grasp_critic" and value in ("auto", "none", "default")
            if isinstance(value, str) and value.strip() and not keyword:
                object.__setattr__(self, name, str(Path(value).expanduser().absolute()))

        def choice(name: str, options: tuple[str, ...]) -> None:
            value = getattr(self, name)
            if value not in options:
                raise ConfigError(f"{name}: must be one of {', '.join(options)}; got {value!r}")

        choice("method", METHODS)
        choice("view_planner", VIEW_PLANNERS)
        choice("grasp_planner", ("auto", *GRASP_PLANNERS))
        # The form only: heapgrasp.training.resolve_device checks the device against
        # PyTorch when a network is built (this module does not import PyTorch).
        if not (
            isinstance(self.net_device, str)
            and re.fullmatch(r"cpu|auto|cuda(:\d+)?", self.net_device) is not None
        ):
            raise ConfigError(
                f"net_device: must be cpu, cuda, cuda:N or auto; got {self.net_device!r}"
            )
        choice("layout", LAYOUTS)
        choice("category", CATEGORIES)
        choice("split", ("train", "test"))
        choice("object_set", OBJECT_SETS)
        if self.object_dir is not None and not (
            isinstance(self.object_dir, str) and self.object_dir.strip()
        ):
            raise ConfigError(f"object_dir: must be a directory path; got {self.object_dir!r}")
        choice("mount", MOUNTS)
        choice("segmenter", SEGMENTERS)
        if self.seg_weights is not None and not (
            isinstance(self.seg_weights, str) and self.seg_weights.strip()
        ):
            raise ConfigError(f"seg_weights: must be a file path; got {self.seg_weights!r}")
        if self.segmenter == "network":
            if self.seg_weights is None:
                raise ConfigError(
                    "seg_weights: segmenter = 'network' needs the segmentation network's "
                    "ONNX file (heapgrasp seg train writes OUT/segmentation.onnx)"
                )
            if not Path(self.seg_weights).is_file():
                raise ConfigError(f"seg_weights: file not found: {self.seg_weights}")
            if self.method == "vgn":
                raise ConfigError(
                    "segmenter: 'network' needs a silhouette method (vgn reads depth)"
                )
            if self.noise > 0:
                raise ConfigError("noise: pixel flips apply to segmenter = 'truth' only")
        if self.start not in STARTS:
            raise ConfigError(f"start: must be one of {', '.join(STARTS)}; got {self.start!r}")
        if not isinstance(self.grasp_critic, str) or not self.grasp_critic:
            raise ConfigError(
                "grasp_critic: must be 'auto', 'none', 'default' or a file path; "
                f"got {self.grasp_critic!r}"
            )
        if self.grasp_critic not in ("auto", "none") and self.method == "vgn":
            raise ConfigError("grasp_critic: needs a silhouette method (not vgn)")

        for name in PATH_SETTINGS:  # a file or folder's path, or none
            value = getattr(self, name)
            if value is not None and not isinstance(value, str):
                raise ConfigError(f"{name}: must be a path (a string); got {value!r}")

        def between(name: str, lo: float, hi: float) -> None:
            value = getattr(self, name)
            number = isinstance(value, int | float) and not isinstance(value, bool)
            if not (number and math.isfinite(value) and lo <= value <= hi):
                raise ConfigError(f"{name}: must be in [{lo}, {hi}]; got {value!r}")

        def positive(name: str) -> None:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{name}: must be > 0; got {value!r}")

        def at_least(name: str, lo: int) -> None:
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= lo):
                raise ConfigError(f"{name}: must be an integer >= {lo}; got {value!r}")

        between("lam", 0.0, 1.0)
        if self.epsilon is not None:
            between("epsilon", 0.0, 1.0)
        between("noise", 0.0, 0.5)
        between("failed_grasp_radius", 0.0, 1.0)
        between("target_radius", 0.0, 1.0)
        between("roof_radius", 0.0, 1.0)
        between("theta_max", 0.0, math.pi / 2)
        for name in ("gamma1", "gamma2", "gamma2_first"):
            between(name, 0.0, 100.0)
        between("stop_below", 0.0, 1.0)
        between("stop_confidence", 0.0, 1.0)
        between("stop_detour_weight", 0.0, 100.0)
        between("sweep_degrees", 0.0, 360.0)
        between("sweep_step", 1.0, 180.0)
        between("move_weight", 0.0, 100.0)
        if not (
            isinstance(self.look_again, int)
            and not isinstance(self.look_again, bool)
            and 0 <= self.look_again <= 3
        ):
            raise ConfigError(f"look_again: must be an integer in [0, 3]; got {self.look_again!r}")
        if self.sigma is not None:
            between("sigma", 0.0, 100.0)
        for name in (
            "cube_size",
            "radius",
            "fps",
            "max_velocity",
            "max_acceleration",
            "max_jerk",
        ):
            positive(name)
        at_least("objects", 1)
        at_least("scenes", 1)
        at_least("seed", 0)
        at_least("resolution", 8)
        if self.resolution > 512:
            raise ConfigError(f"resolution: must be <= 512; got {self.resolution}")
        for name in (
            "U",
            "V",
            "L",
            "nms_window",
            "max_attempts",
        ):
            at_least(name, 1)
        # What the method can do in a phase and a run: past these a run would not end
        # in any useful time (L = 10⁸ waypoints ran for ever).
        for name, most in (
            ("scenes", 1_000_000),
            ("L", 50),
            ("U", 360),
            ("V", 180),
            ("max_attempts", 1000),
            ("objects", 100),
            ("nms_window", self.resolution),
        ):
            if getattr(self, name) > most:
                raise ConfigError(f"{name}: must be <= {most}; got {getattr(self, name)}")
        for name, most_f in (
            ("fps", 240.0),
            ("max_velocity", 5.0),
            ("max_acceleration", 50.0),
            ("max_jerk", 1000.0),
            ("cube_size", 2.0),
            ("radius", 2.0),
        ):
            if getattr(self, name) > most_f:
                raise ConfigError(f"{name}: must be <= {most_f:g}; got {getattr(self, name)!r}")

    @property
    def grasp_planner_in_use(self) -> str:
        """The grasp planner this run uses (one of :data:`GRASP_PLANNERS`):
        ``grasp_planner = "auto"`` resolves to ``network`` for ``vgn``, whose baseline is
        VGN's network on the TSDF, and to ``antipodal`` for the silhouette methods, where
        the analytic planner with the critic holds more grasps than the occupancy network
        (docs/benchmarks.md, "Closed loop: the grasp networks against the analytic
        planner")."""
        if self.grasp_planner == "auto":
            return "network" if self.method == "vgn" else "antipodal"
        return self.grasp_planner

    @property
    def critic(self) -> str | None:
        """The critic this run uses: ``"default"`` (the shipped weights), a file path, or
        None. ``grasp_critic = "auto"`` resolves to the shipped weights for a silhouette
        method with the antipodal planner and to None otherwise."""
        if self.grasp_critic == "none":
            return None
        if self.grasp_critic == "auto":
            applies = self.method != "vgn" and self.grasp_planner_in_use == "antipodal"
            return "default" if applies else None
        return self.grasp_critic

    # ------------------------------------------------------------------ building
    @classmethod
    def field_names(cls, group: str | None = None) -> list[str]:
        """Names of all settings, or of one group's (:data:`GROUPS`)."""
        return [f.name for f in fields(cls) if group is None or f.metadata["group"] == group]

    @classmethod
    def source(cls, name: str) -> str:
        """Where a setting's default comes from (``Table I``, ``VGN``, ``ours``, ...)."""
        return str({f.name: f for f in fields(cls)}[name].metadata["source"])

    def group(self, name: str) -> dict[str, Any]:
        """One group's settings (:data:`GROUPS`) as plain data."""
        if name not in GROUPS:
            raise ConfigError(f"group: must be one of {', '.join(GROUPS)}; got {name!r}")
        return {n: getattr(self, n) for n in self.field_names(name)}

    def paper_only(self) -> RunConfig:
        """This run with every extension at its "off" value: Table I and nothing added
        (the ``paper`` preset)."""
        return dataclasses.replace(self, **PAPER_EXTENSIONS)

    @property
    def start_pose(self) -> tuple[float, float, float]:
        """``(distance, polar, azimuth)`` of the start pose p⁰ (:data:`STARTS`)."""
        return STARTS[self.start]

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, source: str = "config") -> RunConfig:
        """A config from plain data; unknown keys raise :class:`ConfigError`."""
        return cls().replace(data, source=source)

    @classmethod
    def from_toml(cls, path: str | Path) -> RunConfig:
        """Reads a TOML file of parameters (top-level keys, and the ``[methods.NAME]``
        table of the file's own method: :class:`ConfigFile`)."""
        return ConfigFile.read(path).resolve()

    @classmethod
    def load(cls, spec: str | Path) -> RunConfig:
        """``--config``: a TOML file, or the name of a shipped preset (:func:`presets`).
        A file of that name wins over a preset."""
        return ConfigFile.load(spec).resolve()

    def replace(self, changes: Mapping[str, Any], *, source: str = "config") -> RunConfig:
        """A copy with ``changes`` applied (``None`` values are ignored)."""
        known = {f.name: f for f in fields(self)}
        clean: dict[str, Any] = {}
        for key, value in changes.items():
            if key not in known:
                close = [n for n in known if n.lower() == key.lower().replace("-", "_")]
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ConfigError(f"{source}: unknown parameter {key!r}{hint}")
            if value is None:
                continue
            default = getattr(RunConfig(), key)
            if (
                isinstance(default, float)
                and isinstance(value, int)
                and not isinstance(value, bool)
            ):
                value = float(value)
            if (
                key in ("sigma", "epsilon")
                and isinstance(value, int)
                and not isinstance(value, bool)
            ):
                value = float(value)
            if default is not None and not isinstance(value, type(default)):
                raise ConfigError(
                    f"{source}: {key} must be of type {type(default).__name__}, got {value!r}"
                )
            clean[key] = value
        try:
            return dataclasses.replace(self, **clean)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from None

    def to_dict(self) -> dict[str, Any]:
        """All parameters as plain data (JSON/TOML-ready)."""
        return dataclasses.asdict(self)

    def changes_to(self, other: RunConfig) -> str:
        """The settings ``other`` changes, as ``"key: mine -> theirs, ..."`` ("" if none)."""
        mine, theirs = self.to_dict(), other.to_dict()
        return ", ".join(f"{k}: {mine[k]!r} -> {theirs[k]!r}" for k in mine if mine[k] != theirs[k])


@dataclass(frozen=True)
class ConfigFile:
    """A ``--config`` file or preset: :class:`RunConfig` fields at top level, for every
    method, and optional tables ``[methods.NAME]`` whose fields apply on top of them when
    the run's method is ``NAME``, e.g. a preset's baseline run as it was measured::

        scene_memory = true

        [methods.no-vp]
        scene_memory = false

    Precedence: defaults < top level < the method's table < flags < ``--set``."""

    top_level: Mapping[str, Any]
    methods: Mapping[str, Mapping[str, Any]]
    source: str

    @classmethod
    def read(cls, path: str | Path) -> ConfigFile:
        """Parses and checks a TOML file; every error names the file and the key."""
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text())
        except FileNotFoundError:
            raise ConfigError(f"config file not found: {p}") from None
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{p}: not valid TOML: {exc}") from None
        tables = data.pop("methods", {})
        if not isinstance(tables, dict) or not all(isinstance(t, dict) for t in tables.values()):
            raise ConfigError(f"{p}: 'methods' must hold tables [methods.NAME]; got {tables!r}")
        unknown = [m for m in tables if m not in METHODS]
        if unknown:
            raise ConfigError(
                f"{p}: [methods.{unknown[0]}]: unknown method; choose among {', '.join(METHODS)}"
            )
        loaded = cls(data, tables, str(p))
        loaded.resolve()  # every error now, before anything runs
        for method in tables:
            loaded.resolve(method)
        return loaded

    @classmethod
    def load(cls, spec: str | Path) -> ConfigFile:
        """A TOML file, or the name of a shipped preset (:func:`presets`); a file of that
        name wins over a preset."""
        path = Path(spec)
        if path.exists() or path.suffix == ".toml" or len(path.parts) > 1:
            return cls.read(path)
        shipped = presets()
        if str(spec) in shipped:
            return cls.read(shipped[str(spec)])
        raise ConfigError(
            f"config: {str(spec)!r} is neither a file nor a preset (presets: {', '.join(shipped)})"
        )

    def resolve(self, method: str | None = None) -> RunConfig:
        """The config for ``method`` (default: the file's own): the top level, then that
        method's table. The method itself is not set (flags and ``--set`` may still)."""
        config = RunConfig.from_mapping(self.top_level, source=self.source)
        name = config.method if method is None else method
        table = self.methods.get(name, {})
        return config.replace(table, source=f"{self.source} [methods.{name}]")


#: The value of each extension that turns it off (the paper's behaviour).
PAPER_EXTENSIONS: dict[str, Any] = {
    "start": "side",
    "roof_radius": 0.0,
    "grasp_critic": "none",
    "failed_grasp_radius": 0.0,
    "target_radius": 0.0,
    "scene_memory": False,
    "stop_below": 0.0,
    "stop_detour_weight": 0.0,
    "stop_confidence": 0.0,
    "move_weight": 0.0,
    "sweep_degrees": 0.0,
    "sweep_step": 45.0,
    "look_again": 0,
    "fine_width": False,
}


def _parse_value(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def parse_sets(items: list[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` items as a mapping (VALUE parsed as JSON, else a string)."""
    extra: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
        extra[key.strip()] = _parse_value(value.strip())
    return extra


def compose(
    loaded: ConfigFile | None,
    flags: Mapping[str, Any],
    sets: Mapping[str, Any],
    method: str | None = None,
) -> RunConfig:
    """A run's :class:`RunConfig`: defaults < ``loaded`` (its top level, then its table
    for ``method``, by default the method that ``flags`` or ``sets`` name) < ``flags``
    (``None`` = not given) < ``sets`` (``--set``, see :func:`parse_sets`)."""
    if method is None:
        named = sets.get("method", flags.get("method"))
        method = named if isinstance(named, str) else None
    config = loaded.resolve(method) if loaded is not None else RunConfig()
    config = config.replace(flags, source="command line")
    return config.replace(sets, source="--set")
