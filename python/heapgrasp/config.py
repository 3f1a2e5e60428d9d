"""Run configuration: HEAPGrasp Table I defaults, a TOML file, and CLI overrides.

Every parameter of a closed-loop run lives in :class:`RunConfig`. Defaults are the
paper's Table I (cube 0.30 m, 40³ grid, r = 0.33 m, θ_max = π/5, U×V = 40×20, L = 3,
λ = 0.9, ε = 0.8, γ1 = 0.2, γ2 = 0.0 for the first waypoint then 0.35). A TOML file
holds any subset of the fields at top level (names as below), e.g.::

    method = "heapgrasp"
    view_planner = "oracle"
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
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from heapgrasp.sim.objects import ObjectLibrary

__all__ = [
    "CATEGORIES",
    "GRASP_PLANNERS",
    "LAYOUTS",
    "METHODS",
    "MOUNTS",
    "OBJECT_SETS",
    "PRESETS_DIR",
    "TARGET_REGIONS",
    "VIEW_PLANNERS",
    "ConfigError",
    "ConfigFile",
    "RunConfig",
    "object_library",
    "presets",
]

#: ``--method`` values: the proposed method and the baselines of HEAPGrasp §VI-B.
METHODS = ("heapgrasp", "no-vp", "vgn", "hemisphere6")
#: ``--view-planner`` values (used by ``heapgrasp``; the baselines fix their own views).
VIEW_PLANNERS = ("oracle", "network", "circle", "hemisphere6")
#: ``--grasp-planner`` values.
GRASP_PLANNERS = ("antipodal", "network")
LAYOUTS = ("pile", "packed")
CATEGORIES = ("transparent", "specular", "opaque", "mixed")
MOUNTS = ("free", "arm")
#: The regions eq. 14 may be counted on around a target grasp
#: (:class:`heapgrasp.viewplan.OracleViewScorer`).
TARGET_REGIONS = ("column", "gripper", "fingers")
OBJECT_SETS = ("procedural", "all")
#: The shipped presets: ``NAME.toml`` files of :class:`RunConfig` fields.
PRESETS_DIR = Path(__file__).resolve().parent / "presets"


def presets() -> dict[str, Path]:
    """The shipped presets by name (a file's stem), e.g. ``{"short-path": …}``."""
    return {p.stem: p for p in sorted(PRESETS_DIR.glob("*.toml"))}


class ConfigError(ValueError):
    """A configuration value (or file) is invalid."""


@dataclass(frozen=True)
class RunConfig:
    """All parameters of a simulated pick-and-place run (HEAPGrasp Table I defaults)."""

    # -- what to run
    method: str = "heapgrasp"
    """``heapgrasp`` (view planning), ``no-vp`` (once around a circle of L waypoints, SfS),
    ``vgn`` (circle, depth → TSDF) or ``hemisphere6`` (GraspNeRF's six views, SfS)."""
    view_planner: str = "oracle"
    """View planner of ``heapgrasp``: ``oracle`` (exact eq. 14 from the true meshes),
    ``network`` (view network weights), ``circle`` or ``hemisphere6``."""
    grasp_planner: str = "antipodal"
    """``antipodal`` (analytic, no training) or ``network`` (VGN weights)."""
    grasp_weights: str | None = None
    """Path of grasp-network weights (``grasp_planner = "network"``)."""
    view_weights: str | None = None
    """Path of view-network weights (``view_planner = "network"``)."""
    net_device: str = "cpu"
    """Where the networks run (``grasp_planner`` or ``view_planner = "network"``):
    ``cpu``, ``cuda``, ``cuda:N`` or ``auto`` (a CUDA device where PyTorch sees one, else
    the CPU). The analytic planners and the oracle ignore it."""
    # -- scenes
    layout: str = "pile"
    category: str = "mixed"
    objects: int = 5
    scenes: int = 1
    seed: int = 0
    split: str = "test"
    object_set: str = "procedural"
    """``procedural``: boxes, cylinders, bottles, cups and bowls sized for the 8 cm
    gripper (the benchmark's set); ``all``: also pybullet_data's random_urdfs (~9 cm
    blobs, many too wide for the gripper) and the mug."""
    # -- perception
    noise: float = 0.0
    """Probability that each mask pixel is flipped (Table V)."""
    ideal_depth: bool = False
    """Give the VGN baseline ideal depth (the paper's simulation, Table II) instead of the
    per-category sensor model (transparent / specular failures, Table III)."""
    cube_size: float = 0.30
    """Side l of the scene cube (m)."""
    resolution: int = 40
    """N_x = N_y = N_z."""
    lam: float = 0.9
    """Occupancy threshold λ of the high-confidence grid."""
    roof_radius: float = 0.0225
    """Disc radius ρ (m) with which the roofs of the silhouette hull are trimmed before
    grasp planning (:func:`heapgrasp.roofs.trim_roofs`; heapgrasp, no-vp and
    hemisphere6); 0 gives the planner ``Ŝ≥λ`` as it is, as in the paper. Views within
    θ_max of the vertical leave a roof on every object, and grasps planned on it close
    above the object (``docs/benchmarks.md``)."""
    silhouette_views: int = 24
    """How many of the phase's frames (evenly spaced) check the trimmed hull against their
    silhouettes: what trimming cut that some silhouette shows to be real (a bowl's rim,
    a bottle's neck, an object's edge) is put back (:func:`heapgrasp.roofs.
    keep_silhouettes`). 0 trims without the check. Only with ``roof_radius`` > 0."""
    scene_memory: bool = False
    """Silhouette methods: each phase starts from what the previous phases carved,
    instead of from nothing (:meth:`heapgrasp.perception.SilhouettePerception.remember`):
    the object taken and anything that moved away are carved by the new frames, and a
    phase whose first silhouettes show something where the memory holds free space
    (``memory_tolerance``) drops the memory. Not in the paper, which measures each phase
    afresh."""
    memory_tolerance: int = 8
    """With ``scene_memory``: the most voxels the first frame of a phase may need beyond
    the remembered hull to explain its silhouette before the memory is dropped."""
    # -- grasp selection (eq. 15-17)
    epsilon: float | None = None
    """Grasp score threshold ε; None = the grasp planner's own (Table I's 0.8 for the VGN
    network; the analytic planner's scores have another scale, see its docs)."""
    sigma: float | None = None
    """Gaussian smoothing of the grasp scores (voxels); None = the grasp planner's own
    recommendation (1.0 for the VGN network, as VGN; see the analytic planner)."""
    nms_window: int = 4
    grasp_critic: str = "auto"
    """Learned critic that re-scores the grasp candidates and drops those unlikely to hold
    an object (:mod:`heapgrasp.grasping.critic`; silhouette methods only): ``auto`` (the
    weights shipped with the package, ``docs/critic.md``, wherever they apply: a
    silhouette method with the antipodal planner they were trained on; none otherwise),
    ``none``, ``default`` (the shipped weights, and an error where they cannot apply) or
    the path of a critic file written by ``heapgrasp critic train``."""
    critic_at_waypoints: bool = True
    """The critic also scores the candidates at HEAPGrasp's view waypoints (the target
    grasp of eq. 16-19); False: at the final grid only."""
    critic_threshold: float | None = None
    """Probability below which the critic drops a candidate (its ε); None = the one
    stored in the critic file."""
    final_grasp: str = "target"
    """Which of the final grid's candidates HEAPGrasp executes: ``target`` (eq. 16 once
    more: the candidate closest to the last waypoint's target grasp, the one its views
    were planned for) or ``best`` (the highest score, the baselines' rule; with the
    critic, the highest probability of success). The fixed-view methods always take the
    best."""
    confirm_below: float = 0.0
    """HEAPGrasp only: when the grasp chosen on the final grid scores below this (with
    the critic: its probability of success), or there is none, the camera takes another
    view waypoint toward it (eq. 18-19 with ``confirm_gamma2``) and grasp planning runs
    again, at most ``confirm_waypoints`` times. 0 never does (the paper: exactly L
    waypoints)."""
    confirm_waypoints: int = 1
    """At most this many extra view waypoints per phase (``confirm_below``)."""
    confirm_gamma2: float = 0.35
    """γ2 of eq. 18 for the extra waypoints (``confirm_below``)."""
    stop_below: float = 0.0
    """HEAPGrasp with a view planner (oracle or network): stop viewing early, at a view
    waypoint where no candidate's eq. 14 score on the target grasp's region
    (``target_region``, radius ``target_radius``) reaches this, i.e. where no further
    waypoint would carve that share of what is measured around the grasp; the phase then
    grasps on the grid it has (its grasps are not planned again). ``L`` becomes the most
    waypoints a phase takes. Applies from the ``stop_after``-th waypoint
    on; 0 never stops (the paper: exactly L waypoints). Not in the paper."""
    sweep_degrees: float = 0.0
    """HEAPGrasp with a view planner: a phase that took all ``L`` view waypoints without
    stopping early (``stop_below``) goes on along the rim of the candidates (the lowest
    views, ``theta = theta_max (V-1)/V``) by this many degrees of azimuth, capturing
    continuously, in the direction that adds the most azimuths its views lack. Such a
    phase has found no grasp it is sure of, and a hull carved from a few nearby
    directions leaves roofs on the side its views did not reach. 0 never sweeps (the
    paper). Not in the paper."""
    sweep_step: float = 45.0
    """Azimuth (degrees) between the waypoints of ``sweep_degrees``' sweep."""
    sweep_stop: bool = False
    """The sweep ends at the first of its waypoints where the grasp planned there
    (with the critic, if any) scores ``stop_confidence`` or more, and a phase whose grasp
    planning found no grasp at all before its last move (the plan at the last view
    waypoint's step, on the grid before that move) does not sweep."""
    stop_confidence: float = 0.0
    """``stop_below`` ends the viewing only where the target grasp scores at least this
    (with the critic: its probability of success); a doubtful target keeps looking."""
    stop_detour_weight: float = 0.0
    """In the ``stop_below`` test, a candidate's score on the target's region is first
    lessened by this weight (per metre) times the path it adds on the way to the grasp
    (:func:`heapgrasp.selection.detour`): a look must be worth its detour."""
    move_weight: float = 0.0
    """Eq. 18's choice of the next view waypoint maximises ``s + γ2 h`` less this weight
    (per metre) times the length of the move to the candidate: a far look must be worth
    its path (eq. 7's ``α d_space``, here per move; not in the paper's eq. 18). 0 (the
    paper) ignores the path."""
    stop_after: int = 1
    """The fewest view waypoints a phase visits before ``stop_below`` may end its
    viewing."""
    failed_grasp_radius: float = 0.02
    """After a failed grasp, candidates within this distance of it (m) are not tried
    again until a grasp succeeds (the scene has then changed). The simulation is
    deterministic and a failed grasp usually leaves the scene as it was, so without this
    the same grasp would be planned and fail again; 0 allows the repeat."""
    gamma1: float = 0.2
    """Weight of the orientation term of dist (eq. 17)."""
    # -- view planning (eq. 12-14, 18-19)
    radius: float = 0.33
    """Radius r of the view sphere (m)."""
    theta_max: float = math.pi / 5
    U: int = 40
    V: int = 20
    L: int = 3
    """Number of view waypoints."""
    gamma2_first: float = 0.0
    """γ2 of eq. 18 for the first view waypoint."""
    gamma2: float = 0.35
    """γ2 of eq. 18 for the following view waypoints."""
    oracle_frames: int = 10
    """Silhouettes per hypothetical path ``f(p̄^ℓ, p̄^{u,v})`` when the oracle scores a
    candidate (eq. 14), evenly spaced along the path. The real capture takes about 30
    per 0.25 m; fewer underestimate how much a long path carves. The oracle's time
    grows in proportion (``docs/benchmarks.md`` measures 10 and 40)."""
    target_radius: float = 0.08
    """Radius (m) of the column around the target grasp on which the oracle counts
    eq. 14 (:func:`heapgrasp.viewplan.target_region`) from the second waypoint on; 0 counts
    the whole grid, as the paper does. Not in the paper: views within θ_max of the
    vertical leave a roof on every object, and the global count does not favour the views
    that carve the target's (``docs/benchmarks.md``)."""
    target_region: str = "column"
    """Shape of that region: ``"column"`` (radius ``target_radius``), ``"gripper"``, the
    box the gripper sweeps at the target grasp (:func:`heapgrasp.viewplan.gripper_region`),
    or ``"fingers"``, what the finger tips would close on
    (:func:`heapgrasp.viewplan.closing_region`); it applies when ``target_radius`` > 0."""
    initial_radius: float = 0.5
    """Distance of the initial camera pose p⁰ from the bottom centre of the scene (m).

    A phase starts where the previous one ended, with the hand above the bin (§III,
    footnote 1): the default p⁰ is the camera there, 0.5 m from the scene on its -y side,
    looking at the centre. Table II's shortest-trajectory ratios imply a similar start,
    about 0.55 m from the grasp (1.87 m / 337 %). ``initial_radius = radius`` with
    ``initial_theta = 0`` starts at the top of the view sphere instead."""
    initial_theta: float = 0.9
    """Polar angle of p⁰ (rad); 0 = above the centre."""
    initial_phi: float = -math.pi / 2
    """Azimuth of p⁰ (rad, from +x toward +y); the circle baselines start their circle
    at this azimuth too."""
    circle_theta: float = math.pi / 5
    """Polar angle of the circle baselines' waypoints (rad)."""
    circle_closed: bool = True
    """The circle baselines (``no-vp``, ``vgn``, ``view_planner = "circle"``) go once
    around the scene: their L waypoints from p⁰'s azimuth, then back to the first.
    Table II's 1.87 m for both baselines needs the full circle (L = 3 waypoints
    without the way back give 1.4 m; ``docs/benchmarks.md``). False stops at the L-th
    waypoint (240° of the circle for L = 3)."""
    hemisphere_radius: float = 0.5
    hemisphere_theta: float = math.pi / 6
    hemisphere_views: int = 6
    # -- camera and motion
    camera: str = "continuous"
    """``continuous`` (320×240, HEAPGrasp) or ``still`` (640×480, fx = 540, VGN)."""
    fps: float = 30.0
    max_velocity: float = 0.25
    max_acceleration: float = 1.0
    max_jerk: float = 5.0
    mount: str = "free"
    """``free`` (free-flying camera and hand) or ``arm`` (Panda arm, hand-eye camera)."""
    # -- protocol
    max_attempts: int = 20
    """Safety cap on grasp attempts per scene (the protocol normally stops first)."""

    def __post_init__(self) -> None:
        def choice(name: str, options: tuple[str, ...]) -> None:
            value = getattr(self, name)
            if value not in options:
                raise ConfigError(f"{name}: must be one of {', '.join(options)}; got {value!r}")

        choice("method", METHODS)
        choice("view_planner", VIEW_PLANNERS)
        choice("grasp_planner", GRASP_PLANNERS)
        # The form only: heapgrasp.nets.resolve_device checks the device against
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
        choice("camera", ("continuous", "still"))
        choice("mount", MOUNTS)
        choice("final_grasp", ("target", "best"))
        choice("target_region", TARGET_REGIONS)
        if not isinstance(self.grasp_critic, str) or not self.grasp_critic:
            raise ConfigError(
                "grasp_critic: must be 'auto', 'none', 'default' or a file path; "
                f"got {self.grasp_critic!r}"
            )
        if self.grasp_critic not in ("auto", "none") and self.method == "vgn":
            raise ConfigError("grasp_critic: needs a silhouette method (not vgn)")

        def between(name: str, lo: float, hi: float) -> None:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
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
        if self.critic_threshold is not None:
            between("critic_threshold", 0.0, 1.0)
        if self.epsilon is not None:
            between("epsilon", 0.0, 1.0)
        between("noise", 0.0, 0.5)
        between("failed_grasp_radius", 0.0, 1.0)
        between("target_radius", 0.0, 1.0)
        between("roof_radius", 0.0, 1.0)
        between("theta_max", 0.0, math.pi / 2)
        between("initial_theta", 0.0, math.pi / 2)
        between("circle_theta", 0.0, math.pi / 2)
        between("hemisphere_theta", 0.0, math.pi / 2)
        for name in ("gamma1", "gamma2", "gamma2_first", "confirm_gamma2"):
            between(name, 0.0, 100.0)
        between("confirm_below", 0.0, 1.0)
        between("stop_below", 0.0, 1.0)
        between("stop_confidence", 0.0, 1.0)
        between("stop_detour_weight", 0.0, 100.0)
        between("sweep_degrees", 0.0, 360.0)
        between("sweep_step", 1.0, 180.0)
        if self.sweep_stop and self.sweep_degrees == 0.0:
            raise ConfigError("sweep_stop needs a sweep: set sweep_degrees > 0")
        between("move_weight", 0.0, 100.0)
        if self.sigma is not None:
            between("sigma", 0.0, 100.0)
        between("initial_phi", -4 * math.pi, 4 * math.pi)
        for name in (
            "cube_size",
            "radius",
            "initial_radius",
            "hemisphere_radius",
            "fps",
            "max_velocity",
            "max_acceleration",
            "max_jerk",
        ):
            positive(name)
        at_least("objects", 1)
        at_least("scenes", 1)
        at_least("silhouette_views", 0)
        at_least("memory_tolerance", 0)
        at_least("confirm_waypoints", 0)
        at_least("stop_after", 1)
        at_least("seed", 0)
        at_least("resolution", 8)
        if self.resolution > 512:
            raise ConfigError(f"resolution: must be <= 512; got {self.resolution}")
        for name in (
            "U",
            "V",
            "L",
            "nms_window",
            "hemisphere_views",
            "max_attempts",
            "oracle_frames",
        ):
            at_least(name, 1)

    @property
    def critic(self) -> str | None:
        """The critic this run uses: ``"default"`` (the shipped weights), a file path, or
        None. ``grasp_critic = "auto"`` resolves to the shipped weights for a silhouette
        method with the antipodal planner and to None otherwise."""
        if self.grasp_critic == "none":
            return None
        if self.grasp_critic == "auto":
            applies = self.method != "vgn" and self.grasp_planner == "antipodal"
            return "default" if applies else None
        return self.grasp_critic

    # ------------------------------------------------------------------ building
    @classmethod
    def field_names(cls) -> list[str]:
        """Names of all parameters."""
        return [f.name for f in fields(cls)]

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
                key in ("sigma", "epsilon", "critic_threshold")
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


def object_library(config: RunConfig) -> ObjectLibrary:
    """The object library of ``config.object_set`` (generated once into the cache)."""
    from heapgrasp.sim.objects import ObjectLibrary

    if config.object_set == "procedural":
        return ObjectLibrary.default(random_urdfs=0, mug=False, procedural_per_kind=16)
    return ObjectLibrary.default()
