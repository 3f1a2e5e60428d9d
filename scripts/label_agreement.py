#!/usr/bin/env python3
"""The exact-geometry grasp labeller against PyBullet physics (issue 38 §1).

For every scene (seed derived from ``--seed`` and the scene's index, so a re-run is
identical): ``n ~ U{1..8}`` objects of the ``train`` or the ``test`` split, ``pile`` or
``packed``, a random scene group, from the benchmark's object set (boxes, cylinders,
bottles, bowls, cups) or, one scene in three, the ``all`` set (also pybullet_data's
random_urdfs blobs and the mug). Grasps are drawn with VGN's scheme (surface points
with ``n_z > −0.1``, the TCP offset along the normal by ``U[−0.1, 1.1]`` × finger depth,
6 yaws in ``[0, π)``; ``--points`` points a scene), each one is

* labelled by :mod:`heapgrasp.sim.grasp_labels` (the exact-geometry labeller), and
* executed in PyBullet with the free-flying Panda hand exactly as the benchmarks do
  (:func:`heapgrasp.sim.gripper.execute_grasp`: pre-grasp 5 cm back, approach aborting
  on contact, close, lift 10 cm, shake), opened to the hand's 8 cm, each grasp in a
  world of its own: the scene built again from its seed (bit for bit the same settled
  poses) and a new hand, as a benchmark's first grasp in that scene.

Restoring the settled scene with ``pybullet.saveState``/``restoreState`` between grasps
(``--restore``: every body's pose and velocity, the hand parked, which resets its
constraint and finger motor targets) costs 2.5 times less CPU but is not the same
physics: state that restoreState leaves as the previous grasp left it (mostly the
broadphase's pair order: with ``deterministicOverlappingPairs`` most of the difference
goes) changes whether a grasp holds for 2.3 % of the grasps that close on an object
(26 of 1,148 in the validation run), never whether the hand collides.
``--execute-from RUN`` executes exactly the grasps of an earlier run (same poses,
strata and weights) in the other mode, which measures how far physics agrees with
itself.

Physics is the truth. Outputs in ``--out``: ``grasps.jsonl`` (one line per grasp),
``scenes.jsonl`` (one line per scene, written after its grasps: a scene there is done,
so a re-run resumes), ``summary.json`` and ``summary.md`` (the confusion matrix,
agreement, the disagreements by kind and by object shape, the cost per grasp). Scenes
run on a process pool, one PyBullet client per worker; a worker that dies (a native
crash) loses only its scene, which is run again alone and recorded as crashed if it
dies again::

    python scripts/label_agreement.py --scenes 100 --workers 2 --out RUN
    python scripts/label_agreement.py --relabel-from RUN --out RUN-relabelled
    python scripts/label_agreement.py --execute-from RUN --restore --workers 2 --out RUN-restored
    python scripts/label_agreement.py --summarize-only --out RUN
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

FORMAT = "heapgrasp-label-agreement"
VERSION = 1

#: Physics outcomes, finer than :class:`heapgrasp.robot.grasping.GraspOutcome`.
KINDS = (
    "success",
    "collision-pregrasp",
    "collision-approach",
    "empty-closed",  # the fingers closed on nothing (or on one side only)
    "dropped-lift",  # held after closing, not after the lift
    "dropped-shake",  # held after the lift, not after the shake
)


# --------------------------------------------------------------------------- config


@dataclass(frozen=True)
class AgreementConfig:
    """What a run samples; everything but ``scenes`` must match to resume."""

    scenes: int = 80
    root_seed: int = 38
    points: int = 240
    """Surface points per scene (VGN draws 120; each gives ``yaws`` grasps), all
    labelled; a stratified subset is executed."""
    yaws: int = 6
    positives: int = 10
    """Grasps the labeller calls successful executed per scene (at most)."""
    negatives: int = 14
    """Grasps the labeller calls failed executed per scene (at most), shared equally
    among its failure reasons (collision, empty, not-antipodal, ...)."""
    restore: bool = False
    """Execute every grasp of a scene in one world restored between grasps (cheaper,
    not the same physics) instead of a freshly built world each."""
    max_objects: int = 8
    all_set_every: int = 3
    """Every this-many-th scene draws from the ``all`` object set (0: never)."""
    test_fraction: float = 0.5
    """Share of scenes drawing the test split's objects."""

    def identity(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d.pop("scenes")
        return d


def scene_spec(config: AgreementConfig, index: int) -> dict[str, Any]:
    """The scene ``index``'s random choices (a function of the root seed and index)."""
    rng = np.random.default_rng(np.random.SeedSequence([config.root_seed, index]))
    seed = int(rng.integers(2**31))
    n = int(rng.integers(1, config.max_objects + 1))
    layout = "pile" if rng.random() < 0.5 else "packed"
    category = ("transparent", "opaque", "specular", "mixed")[int(rng.integers(4))]
    split = "test" if rng.random() < config.test_fraction else "train"
    every = config.all_set_every
    object_set = "all" if every > 0 and index % every == every - 1 else "procedural"
    return {
        "scene": index,
        "scene_seed": seed,
        "n_objects": n,
        "layout": layout,
        "category": category,
        "split": split,
        "object_set": object_set,
        "sample_seed": int(rng.integers(2**31)),
    }


_LIBRARIES: dict[str, Any] = {}


def _library(object_set: str) -> Any:
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.sim.build import object_library

    if object_set not in _LIBRARIES:
        _LIBRARIES[object_set] = object_library(RunConfig(object_set=object_set))
    return _LIBRARIES[object_set]


def build_world(spec: dict[str, Any]) -> Any:
    """The settled scene of ``spec`` in a new :class:`~heapgrasp.sim.world.SimWorld`
    (bit for bit the same on every call: PyBullet is deterministic)."""
    from heapgrasp.sim.world import SimWorld, WorldConfig

    world = SimWorld(_library(spec["object_set"]), config=WorldConfig(), seed=spec["scene_seed"])
    world.reset(
        layout=spec["layout"],
        n_objects=spec["n_objects"],
        category=spec["category"],
        seed=spec["scene_seed"],
        split=spec["split"],
    )
    return world


def shape_of(name: str) -> str:
    """The object's shape family: a procedural kind, ``blob`` (random_urdfs), ``mug``,
    or ``user``."""
    head, _, tail = name.partition("/")
    if head == "procedural":
        return tail.rsplit("_", 1)[0]
    if head == "random_urdfs":
        return "blob"
    if tail == "mug" or head == "mug":
        return "mug"
    return head


# --------------------------------------------------------------------------- sampler


def vgn_frame(point: F64, normal: F64, yaw: float) -> F64:
    """VGN's grasp frame at ``point``: z = −normal, x from world x (world y when the
    normal is along x), turned by ``yaw`` about z."""
    z = -np.asarray(normal, dtype=np.float64)
    z /= np.linalg.norm(z)
    x = np.array([1.0, 0.0, 0.0])
    if abs(float(x @ z)) > 1.0 - 1e-4:
        x = np.array([0.0, 1.0, 0.0])
    y = np.cross(z, x)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    c, s = math.cos(yaw), math.sin(yaw)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, y, z], axis=1) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    pose[:3, 3] = point
    return pose


def sample_python(world: Any, rng: np.random.Generator, points: int, yaws: int) -> list[dict]:
    """VGN's scheme on the true meshes, in NumPy (a stand-in when the core's sampler is
    absent): area-weighted surface points with ``n_z > −0.1``."""
    from heapgrasp.geometry.gripper import PANDA_HAND

    tris, normals, owner = [], [], []
    for oid in world.objects:
        pose = world.object_pose(oid)
        v = world.object_vertices(oid) @ pose[:3, :3].T + pose[:3, 3]
        f = world._mesh(world.objects[oid].model).faces
        t = v[f]
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        tris.append(t)
        normals.append(n)
        owner.append(np.full(len(f), oid))
    t = np.concatenate(tris)
    n = np.concatenate(normals)
    area = np.linalg.norm(n, axis=1)
    ok = area > 0
    n[ok] /= area[ok, None]
    weight = np.where(ok & (n[:, 2] > -0.1), area, 0.0)
    who = np.concatenate(owner)
    out: list[dict] = []
    depth = PANDA_HAND.finger_depth
    for p in range(points):
        i = int(rng.choice(len(t), p=weight / weight.sum()))
        a, b = rng.random(2)
        if a + b > 1:
            a, b = 1 - a, 1 - b
        surface = t[i, 0] + a * (t[i, 1] - t[i, 0]) + b * (t[i, 2] - t[i, 0])
        offset = rng.uniform(-0.1, 1.1) * depth
        centre = surface + offset * n[i]
        for k in range(yaws):
            out.append(
                {
                    "point": p,
                    "yaw_index": k,
                    "pose": vgn_frame(centre, n[i], math.pi * k / yaws),
                    "surface": surface,
                    "normal": n[i],
                    "offset": offset,
                    "target": int(who[i]),
                }
            )
    return out


# --------------------------------------------------------------------------- labeller


def labeller_available() -> bool:
    try:
        import heapgrasp.sim.grasp_labels  # noqa: F401
    except ImportError:
        return False
    return True


def sample_core(world: Any, rng: np.random.Generator, points: int, yaws: int) -> list[dict]:
    """VGN's sampler of :mod:`heapgrasp.sim.grasp_labels`, one dict per grasp."""
    from heapgrasp.sim.grasp_labels import sample_grasps

    s = sample_grasps(world, rng, points, yaws)
    out = []
    for p in range(len(s.points)):
        for k in range(len(s.yaws)):
            out.append(
                {
                    "point": p,
                    "yaw_index": k,
                    "pose": s.poses[p, k],
                    "surface": s.points[p],
                    "normal": s.normals[p],
                    "offset": float(s.depths[p]),
                    "target": int(s.objects[p]),
                }
            )
    return out


def default_sampler() -> Callable[[Any, np.random.Generator, int, int], list[dict]]:
    """The core's sampler where installed, else the NumPy stand-in."""
    return sample_core if labeller_available() else sample_python


def labeller_fingerprint() -> str | None:
    """A digest of the installed core library and labeller module (which labeller)."""
    if not labeller_available():
        return None
    import hashlib

    import heapgrasp._core as core
    import heapgrasp.sim.grasp_labels as gl

    h = hashlib.sha256()
    for path in (core.__file__, gl.__file__):
        h.update(Path(str(path)).read_bytes())
    return h.hexdigest()[:16]


def label_grasps(world: Any, grasps: Sequence[dict]) -> list[dict[str, Any]] | None:
    """The labeller's verdict per grasp, on the scene as it is now (None when the
    labeller is not installed)."""
    if not labeller_available():
        return None
    from heapgrasp.sim.grasp_labels import REASONS, labeller

    if not grasps:
        return []
    poses = np.ascontiguousarray(np.stack([g["pose"] for g in grasps]), dtype=np.float64)
    ok, width, held, reason = labeller(world).label(poses, threads=1)
    return [
        {
            "label": int(bool(ok[i])),
            "label_width": round(float(width[i]), 5),
            "label_object": None if int(held[i]) < 0 else int(held[i]),
            "label_reason": REASONS[int(reason[i])],
        }
        for i in range(len(grasps))
    ]


# --------------------------------------------------------------------------- physics


def _recording_hand(world: Any) -> Any:
    """A :class:`~heapgrasp.sim.gripper.PandaHand` that notes, without changing what it
    does, the width and finger contacts after closing, the held-object checks, and the
    contacts that stopped it."""
    import pybullet as pb
    from heapgrasp.sim.gripper import PandaHand

    class RecordingHand(PandaHand):
        def clear(self) -> None:
            self.log: dict[str, Any] = {"held": [], "stop_contacts": None}

        def close(self, seconds: float = 0.5, width: float = 0.0) -> None:
            super().close(seconds, width)
            self.log["width_closed"] = self.width()
            self.log["held_closed"] = super().held_object()
            self.log["close_contacts"] = self._points(fingers_only=True)

        def held_object(self) -> int | None:
            held = super().held_object()
            self.log["held"].append(held)
            return held

        def contacts(self) -> set[int]:
            found = super().contacts()
            if found:
                self.log["stop_contacts"] = self._points(fingers_only=False)
            return found

        def _points(self, *, fingers_only: bool) -> list[dict[str, Any]]:
            inv = np.linalg.inv(self.tcp)
            out = []
            for p in pb.getContactPoints(bodyA=self.body, physicsClientId=self.client):
                if p[2] == self.body or (fingers_only and p[3] < 0):
                    continue
                on_hand = inv[:3, :3] @ np.asarray(p[5]) + inv[:3, 3]
                normal = inv[:3, :3] @ np.asarray(p[7])  # from B (the other body) to A
                out.append(
                    {
                        "link": {-1: "palm", 0: "left", 1: "right"}.get(int(p[3]), str(p[3])),
                        "body": int(p[2]),
                        "at_tcp": [round(float(x), 5) for x in on_hand],
                        "normal_tcp": [round(float(x), 4) for x in normal],
                        "distance": round(float(p[8]), 6),
                        "force": round(float(p[9]), 3),
                    }
                )
            return out

    hand = RecordingHand(world)
    hand.clear()
    return hand


def _body_label(world: Any, body: int) -> str:
    if body == world.table:
        return "table"
    for oid, obj in world.objects.items():
        if obj.body == body:
            return f"object:{oid}"
    return "other"


def execute_one(world: Any, hand: Any, pose: F64) -> dict[str, Any]:
    """Runs one grasp (the benchmarks' :func:`~heapgrasp.sim.gripper.execute_grasp`,
    opened to 8 cm) and returns the physics record."""
    from heapgrasp.sim.gripper import MAX_OPENING, Grasp, GraspOutcome, execute_grasp

    hand.clear()
    result = execute_grasp(hand, Grasp(pose, MAX_OPENING))
    log = hand.log
    if result.outcome == GraspOutcome.COLLISION:
        kind = f"collision-{result.stage}"
    elif result.outcome == GraspOutcome.SUCCESS:
        kind = "success"
    elif result.outcome == GraspOutcome.EMPTY:
        held = log["held"]
        if log.get("held_closed") is None:
            kind = "empty-closed"
        elif not held or held[0] is None:
            kind = "dropped-lift"
        else:
            kind = "dropped-shake"
    else:
        kind = result.outcome.value
    stop = log["stop_contacts"] if result.outcome == GraspOutcome.COLLISION else None
    for c in stop or []:
        c["body"] = _body_label(world, c["body"])
    close = log.get("close_contacts")
    for c in close or []:
        c["body"] = _body_label(world, c["body"])
    return {
        "physics": kind,
        "physics_success": result.success,
        "physics_object": result.object_id,
        "physics_held_closed": log.get("held_closed"),
        "physics_width_closed": None
        if log.get("width_closed") is None
        else round(float(log["width_closed"]), 5),
        "physics_touched": sorted(_body_label(world, b) for b in result.touched),
        "physics_parts": sorted(result.parts),
        "physics_duration": round(result.duration, 4),
        "stop_contacts": stop,
        "close_contacts": close,
    }


def select(
    strata: Sequence[str], rng: np.random.Generator, positives: int, negatives: int
) -> tuple[list[int], list[float]]:
    """The grasps to execute, stratified by the labeller's verdict: up to ``positives``
    of the stratum ``success`` and ``negatives`` shared equally among the other strata
    (what one stratum lacks goes to the others), each drawn at random within its stratum.
    Returns the indices (sorted) and each one's weight: its stratum's size over the
    number drawn from it, so weighted sums estimate the whole sample's."""
    groups: dict[str, list[int]] = {}
    for i, s in enumerate(strata):
        groups.setdefault(s, []).append(i)
    take = {s: 0 for s in groups}
    if "success" in groups:
        take["success"] = min(positives, len(groups["success"]))
    others = sorted(s for s in groups if s != "success")
    budget = negatives
    while budget > 0:
        open_ = [s for s in others if take[s] < len(groups[s])]
        if not open_:
            break
        share = max(1, budget // len(open_))
        for s in open_:
            add = min(share, len(groups[s]) - take[s], budget)
            take[s] += add
            budget -= add
            if budget == 0:
                break
    chosen: list[tuple[int, float]] = []
    for s, members in groups.items():
        if take[s]:
            picks = rng.choice(len(members), size=take[s], replace=False)
            chosen += [(members[int(j)], len(members) / take[s]) for j in picks]
    chosen.sort()
    return [i for i, _ in chosen], [w for _, w in chosen]


def run_scene(
    config: AgreementConfig,
    index: int,
    *,
    sampler: Callable[[Any, np.random.Generator, int, int], list[dict]] | None = None,
    label: bool = True,
    plan: Sequence[dict[str, Any]] | None = None,
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Scene ``index``: its record and one record per executed grasp (physics and
    labeller). Every sampled grasp is labelled; :func:`select` picks those executed
    (without the labeller: a random subset of the same size). ``plan``: execute these
    grasps instead (records of an earlier run of this scene: their ``grasp`` index,
    ``pose``, ``stratum`` and ``weight``)."""
    import pybullet as pb

    spec = scene_spec(config, index)
    t_start = time.perf_counter()
    with build_world(spec) as world:
        objects = {
            oid: {
                "name": o.model.name,
                "shape": shape_of(o.model.name),
                "split": o.model.split,
                "category": o.category.value,
                "obj2world": world.object_pose(oid)[:3].tolist(),
            }
            for oid, o in world.objects.items()
        }
        scene = {**spec, "objects_left": len(objects), "objects": objects}
        scene["seconds_build"] = round(time.perf_counter() - t_start, 3)
        if not objects:
            return {**scene, "grasps": 0, "status": "no objects"}, []
        hand = _recording_hand(world) if config.restore else None
        saved = pb.saveState(physicsClientId=world.client)
        rng = np.random.default_rng(spec["sample_seed"])
        grasps = (sampler or default_sampler())(world, rng, config.points, config.yaws)
        t0 = time.perf_counter()
        labels = label_grasps(world, grasps) if label else None
        t_label = time.perf_counter() - t0
        strata = ["all"] * len(grasps) if labels is None else [x["label_reason"] for x in labels]
        picked, weights = select(strata, rng, config.positives, config.negatives)
        if labels is None:  # no verdict to stratify on: a random subset of the same size
            k = min(len(grasps), config.positives + config.negatives)
            picked = sorted(int(i) for i in rng.choice(len(grasps), size=k, replace=False))
            weights = [len(grasps) / max(k, 1)] * k
        if plan is not None:
            for old in plan:
                if not np.allclose(grasps[old["grasp"]]["pose"][:3], old["pose"], atol=1e-9):
                    raise ValueError(f"scene {index}: grasp {old['grasp']} is not the planned one")
            picked = [int(old["grasp"]) for old in plan]
            weights = [float(old["weight"]) for old in plan]
            planned = {int(old["grasp"]): old["stratum"] for old in plan}
            strata = [planned.get(i, x) for i, x in enumerate(strata)]
        records = []
        t_physics = 0.0
        for k, w in zip(picked, weights, strict=True):
            g = grasps[k]
            t0, c0 = time.perf_counter(), time.process_time()
            if config.restore:
                pb.restoreState(saved, physicsClientId=world.client)
                hand.park()
                world.time = 0.0
                phys = execute_one(world, hand, g["pose"])
            else:
                with build_world(spec) as fresh:
                    phys = execute_one(fresh, _recording_hand(fresh), g["pose"])
            dt, cpu = time.perf_counter() - t0, time.process_time() - c0
            t_physics += dt
            target = g.get("target")
            rec: dict[str, Any] = {
                "scene": index,
                "scene_seed": spec["scene_seed"],
                "grasp": k,
                "point": g["point"],
                "yaw_index": g["yaw_index"],
                "stratum": strata[k],
                "weight": round(w, 6),
                "pose": g["pose"][:3].tolist(),
                "surface": np.round(g["surface"], 6).tolist() if "surface" in g else None,
                "normal": np.round(g["normal"], 5).tolist() if "normal" in g else None,
                "offset": round(float(g["offset"]), 5) if "offset" in g else None,
                "target": target,
                "target_shape": objects[target]["shape"] if target in objects else None,
                **phys,
                "seconds_physics": round(dt, 4),
                "cpu_seconds_physics": round(cpu, 4),
            }
            if labels is not None:
                rec.update(labels[k])
            records.append(rec)
        pb.removeState(saved, physicsClientId=world.client)
    scene.update(
        grasps=len(records),
        sampled=len(grasps),
        sampled_labels=dict(Counter(strata)),
        status="ok",
        labelled=labels is not None,
        labeller=labeller_fingerprint() if labels is not None else None,
        seconds_physics=round(t_physics, 3),
        seconds_label=round(t_label, 5),
        seconds=round(time.perf_counter() - t_start, 3),
    )
    return scene, records


def check_restore(config: AgreementConfig, scenes: Iterable[int], limit: int) -> list[dict]:
    """Grasps executed after ``restoreState`` against the same grasps in a freshly built
    world (the scene rebuilt from its seed, a new hand): up to ``limit`` grasps of
    ``scenes`` that got past the pre-grasp pose (the others touch nothing that moves).
    One row per grasp: the kind, held object and closed width of each
    (the same: equal kind and object, widths within 1 mm)."""

    def key(r: dict[str, Any]) -> list[Any]:
        return [r["physics"], r["physics_object"], r["physics_width_closed"]]

    def same(a: list[Any], b: list[Any]) -> bool:
        if a[:2] != b[:2] or (a[2] is None) != (b[2] is None):
            return False
        return a[2] is None or abs(a[2] - b[2]) < 0.001

    rows: list[dict] = []
    for index in scenes:
        _, records = run_scene(dataclasses.replace(config, restore=True), index, label=False)
        spec = scene_spec(config, index)
        for rec in records:
            if len(rows) >= limit:
                return rows
            if rec["physics"] == "collision-pregrasp":
                continue
            with build_world(spec) as world:
                hand = _recording_hand(world)
                pose = np.vstack([np.asarray(rec["pose"]), [0.0, 0.0, 0.0, 1.0]])
                fresh = execute_one(world, hand, pose)
            rows.append(
                {
                    "scene": index,
                    "grasp": rec["grasp"],
                    "restored": key(rec),
                    "rebuilt": key(fresh),
                    "same": same(key(rec), key(fresh)),
                }
            )
    return rows


def _run_config(src: Path, **changes: Any) -> AgreementConfig:
    """The settings of the run in ``src`` (``config.json``), with ``changes``."""
    meta = json.loads((src / "config.json").read_text())
    fields = {f.name for f in dataclasses.fields(AgreementConfig)}
    known = {k: v for k, v in meta.items() if k in fields and k != "scenes"}
    scenes = _read_jsonl(src / "scenes.jsonl")
    return AgreementConfig(
        **{**known, **changes}, scenes=1 + max((s["scene"] for s in scenes), default=0)
    )


def plans_of(src: Path, restore: bool) -> tuple[AgreementConfig, dict[int, list[dict]]]:
    """The settings and the executed grasps per scene of the run in ``src``."""
    config = _run_config(src, restore=restore)
    plans: dict[int, list[dict[str, Any]]] = {}
    for s in _read_jsonl(src / "scenes.jsonl"):
        if s["status"] == "ok":
            plans[s["scene"]] = []
    for g in _read_jsonl(src / "grasps.jsonl"):
        if g["scene"] in plans:
            plans[g["scene"]].append({k: g[k] for k in ("grasp", "pose", "stratum", "weight")})
    return config, plans


def relabel(src: Path, dst: Path) -> None:
    """The physics of ``src`` with the installed labeller's verdicts: each scene rebuilt
    (bit for bit the one executed), its whole VGN sample drawn again from the same seed
    and labelled (timed), the executed grasps' labels replaced. Stratum and weight stay
    those of the run (the sampling design), so the weighted estimates stay unbiased."""
    meta = json.loads((src / "config.json").read_text())
    scenes = _read_jsonl(src / "scenes.jsonl")
    config = _run_config(src)
    grasps: dict[int, list[dict[str, Any]]] = {}
    for g in _read_jsonl(src / "grasps.jsonl"):
        grasps.setdefault(g["scene"], []).append(g)
    dst.mkdir(parents=True, exist_ok=True)
    (dst / "config.json").write_text(json.dumps(meta, indent=1) + "\n")
    out_scenes, out_grasps = [], []
    fingerprint = labeller_fingerprint()
    for scene in scenes:
        rows = grasps.get(scene["scene"], [])
        if scene["status"] != "ok":
            out_scenes.append(scene)
            continue
        spec = scene_spec(config, scene["scene"])
        with build_world(spec) as world:
            names = {str(oid): o.model.name for oid, o in world.objects.items()}
            if names != {k: v["name"] for k, v in scene["objects"].items()}:
                raise SystemExit(f"scene {scene['scene']}: rebuilt with other objects")
            rng = np.random.default_rng(spec["sample_seed"])
            sample = default_sampler()(world, rng, config.points, config.yaws)
            t0 = time.perf_counter()
            labels = label_grasps(world, sample) or []
            seconds = time.perf_counter() - t0
            same = len(sample) == scene["sampled"] and all(
                np.allclose(sample[g["grasp"]]["pose"][:3], g["pose"], atol=1e-9) for g in rows
            )
            if not same:  # the sampler changed: label the executed poses themselves
                poses = [{"pose": np.vstack([g["pose"], [0, 0, 0, 1.0]])} for g in rows]
                labels = [{} for _ in sample]
                for g, lab in zip(rows, label_grasps(world, poses) or [], strict=True):
                    labels[g["grasp"]] = lab
        for g in rows:
            out_grasps.append({**g, **labels[g["grasp"]]})
        counts = Counter(x["label_reason"] for x in labels if x) if same else None
        out_scenes.append(
            {
                **scene,
                "labeller": fingerprint,
                "seconds_label": round(seconds, 5) if same else None,
                "sampled_labels": counts if counts is not None else scene["sampled_labels"],
                "relabelled_from": str(src),
            }
        )
    for name, data in (("scenes.jsonl", out_scenes), ("grasps.jsonl", out_grasps)):
        tmp = dst / f".{name}.tmp"
        tmp.write_text("".join(json.dumps(r) + "\n" for r in data))
        os.replace(tmp, dst / name)


# --------------------------------------------------------------------------- pool


def _init_worker() -> None:
    os.environ["HEAPGRASP_NUM_THREADS"] = "1"


def _scene_job(
    config: AgreementConfig, index: int, plan: list[dict[str, Any]] | None = None
) -> tuple[dict[str, Any], list[dict]]:
    try:
        return run_scene(config, index, plan=plan)
    except Exception as exc:  # reported with its scene; the others go on
        spec = scene_spec(config, index)
        return {**spec, "grasps": 0, "status": f"error: {type(exc).__name__}: {exc}"}, []


def _read_jsonl(path: Path) -> list[dict[str, Any]]:
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        if line.strip():
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:  # a line cut by a kill: its scene is redone
                continue
    return out


def _append(path: Path, rows: Iterable[dict[str, Any]]) -> None:
    with path.open("a") as f:
        for row in rows:
            f.write(json.dumps(row) + "\n")
        f.flush()
        os.fsync(f.fileno())


def _prepare(out: Path, config: AgreementConfig, source: str | None = None) -> set[int]:
    """Checks ``out`` was made with the same settings; drops the grasps of scenes not
    finished (a kill between a scene's grasps and its scene line); the scenes done."""
    out.mkdir(parents=True, exist_ok=True)
    meta = out / "config.json"
    mine = {"format": FORMAT, "version": VERSION, **config.identity()}
    if source is not None:
        mine["executed_from"] = source
    if meta.exists():
        old = json.loads(meta.read_text())
        if old != mine:
            raise SystemExit(f"{out} holds a run with other settings: {old} (asked {mine})")
    else:
        meta.write_text(json.dumps(mine, indent=1) + "\n")
    done = {s["scene"] for s in _read_jsonl(out / "scenes.jsonl") if s["status"] != "crashed"}
    grasps = _read_jsonl(out / "grasps.jsonl")
    kept = [g for g in grasps if g["scene"] in done]
    if len(kept) != len(grasps) or (
        (out / "grasps.jsonl").exists() and len(kept) != _count_lines(out / "grasps.jsonl")
    ):
        tmp = out / ".grasps.jsonl.tmp"
        tmp.write_text("".join(json.dumps(g) + "\n" for g in kept))
        os.replace(tmp, out / "grasps.jsonl")
    return done


def _count_lines(path: Path) -> int:
    return sum(1 for line in path.read_text().splitlines() if line.strip())


def run(
    config: AgreementConfig,
    out: Path,
    workers: int,
    plans: dict[int, list[dict[str, Any]]] | None = None,
    source: str | None = None,
) -> None:
    """Every scene not yet in ``out``, on ``workers`` processes; with ``plans``, only
    their scenes, each executing its planned grasps (``source``: the run they are
    from, recorded)."""
    done = _prepare(out, config, source)
    todo = [i for i in range(config.scenes) if i not in done]
    if plans is not None:
        todo = [i for i in sorted(plans) if i not in done]
    print(f"{len(done)} scenes done, {len(todo)} to run", file=sys.stderr)

    def finished(scene: dict[str, Any], records: list[dict]) -> None:
        _append(out / "grasps.jsonl", records)
        _append(out / "scenes.jsonl", [scene])
        print(
            f"scene {scene['scene']}: {scene['grasps']} grasps, {scene['status']}, "
            f"{scene.get('seconds', 0):.1f} s",
            file=sys.stderr,
        )

    if workers == 1:
        for i in todo:
            finished(*_scene_job(config, i, None if plans is None else plans[i]))
        return
    crashed: list[int] = []
    if todo:
        with ProcessPoolExecutor(min(workers, len(todo)), initializer=_init_worker) as pool:
            futures = {
                pool.submit(_scene_job, config, i, None if plans is None else plans[i]): i
                for i in todo
            }
            remaining = set(futures)
            while remaining:
                ready, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for fut in ready:
                    try:
                        finished(*fut.result())
                    except BrokenProcessPool:
                        crashed.append(futures[fut])
    for i in sorted(crashed):  # each alone: the guilty scene fails by itself
        with ProcessPoolExecutor(1, initializer=_init_worker) as single:
            try:
                plan = None if plans is None else plans[i]
                finished(*single.submit(_scene_job, config, i, plan).result())
            except BrokenProcessPool:
                spec = scene_spec(config, i)
                finished({**spec, "grasps": 0, "status": "crashed"}, [])


# --------------------------------------------------------------------------- summary


def _wilson(k: int, n: int) -> tuple[float, float] | None:
    if n == 0:
        return None
    z = 1.959963984540054
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return (round(100 * (c - h), 2), round(100 * (c + h), 2))


def summarize(grasps: Sequence[dict[str, Any]], scenes: Sequence[dict[str, Any]]) -> dict:
    """The confusion matrix (physics = truth), agreement, disagreements by kind and by
    object shape, and the cost per grasp."""
    n = len(grasps)
    ok = [s for s in scenes if s["status"] == "ok"]
    summary: dict[str, Any] = {
        "scenes": len(scenes),
        "scenes_ok": len(ok),
        "scenes_status": dict(Counter(s["status"].split(":")[0] for s in scenes)),
        "grasps": n,
        "physics_kinds": dict(Counter(g["physics"] for g in grasps)),
        "physics_positive_rate": round(sum(g["physics_success"] for g in grasps) / max(n, 1), 4),
        "layouts": dict(Counter(s["layout"] for s in ok)),
        "splits": dict(Counter(s["split"] for s in ok)),
        "object_sets": dict(Counter(s["object_set"] for s in ok)),
        "objects_per_scene": dict(sorted(Counter(s["objects_left"] for s in ok).items())),
    }
    phys_seconds = [g["seconds_physics"] for g in grasps]
    if phys_seconds:
        cpu = [g["cpu_seconds_physics"] for g in grasps if "cpu_seconds_physics" in g]
        if cpu:
            summary["physics_cpu_seconds_per_grasp"] = {
                "mean": round(float(np.mean(cpu)), 4),
                "median": round(float(np.median(cpu)), 4),
                "by_kind": {
                    k: round(
                        float(
                            np.mean([g["cpu_seconds_physics"] for g in grasps if g["physics"] == k])
                        ),
                        4,
                    )
                    for k in sorted({g["physics"] for g in grasps})
                },
            }
        if cpu and all("weight" in g for g in grasps):
            w = np.array([g["weight"] for g in grasps])
            c = np.array([g.get("cpu_seconds_physics", np.nan) for g in grasps])
            summary["physics_cpu_seconds_per_grasp"]["weighted_mean"] = round(
                float(np.nansum(w * c) / w[np.isfinite(c)].sum()), 4
            )
        summary["physics_seconds_per_grasp"] = {
            "mean": round(float(np.mean(phys_seconds)), 4),
            "median": round(float(np.median(phys_seconds)), 4),
            "p90": round(float(np.percentile(phys_seconds, 90)), 4),
            "by_kind": {
                k: round(
                    float(np.mean([g["seconds_physics"] for g in grasps if g["physics"] == k])), 4
                )
                for k in sorted({g["physics"] for g in grasps})
            },
        }
        summary["scene_build_seconds_mean"] = round(
            float(np.mean([s["seconds_build"] for s in ok])), 3
        )
    labelled = [g for g in grasps if "label" in g]
    if labelled:
        m = {"tp": 0, "fn": 0, "fp": 0, "tn": 0}
        for g in labelled:
            p, q = bool(g["physics_success"]), bool(g["label"])
            m["tp" if p and q else "fn" if p else "fp" if q else "tn"] += 1
        agree = m["tp"] + m["tn"]
        nl = len(labelled)
        summary["confusion"] = m
        summary["agreement"] = round(100 * agree / nl, 2)
        summary["agreement_interval"] = _wilson(agree, nl)
        summary["labeller_positive_rate"] = round((m["tp"] + m["fp"]) / nl, 4)
        summary["precision"] = round(m["tp"] / max(m["tp"] + m["fp"], 1), 4)
        summary["recall"] = round(m["tp"] / max(m["tp"] + m["fn"], 1), 4)
        summary["same_object"] = _same_object(labelled)
        summary["width_error"] = _width_error(labelled)
        pairs = Counter((g["physics"], str(g.get("label_reason"))) for g in labelled)
        summary["by_reason"] = [
            {"physics": p, "labeller": r, "grasps": c, "disagree": _disagree(p, r, labelled)}
            for (p, r), c in sorted(pairs.items(), key=lambda kv: -kv[1])
        ]
        shapes: dict[str, Counter[str]] = {}
        for g in labelled:
            c = shapes.setdefault(str(g.get("target_shape")), Counter())
            c["grasps"] += 1
            c["physics_success"] += int(g["physics_success"])
            c["label_success"] += int(bool(g["label"]))
            c["agree"] += int(bool(g["physics_success"]) == bool(g["label"]))
            c["fp"] += int(bool(g["label"]) and not g["physics_success"])
            c["fn"] += int(not g["label"] and bool(g["physics_success"]))
        summary["by_shape"] = {
            s: {**c, "agreement": round(100 * c["agree"] / c["grasps"], 1)}
            for s, c in sorted(shapes.items())
        }
        summary["by_stratum"] = _by_stratum(labelled)
        summary.update(_weighted(labelled))
        lab = [s for s in ok if s.get("labelled")]
        sampled = sum(s.get("sampled", 0) for s in lab)
        natural: Counter[str] = Counter()
        for s in lab:
            natural.update(s.get("sampled_labels", {}))
        summary["sampled"] = sampled
        summary["sampled_labels"] = dict(natural.most_common())
        timed = [s for s in lab if s.get("seconds_label") is not None]
        summary["label_seconds_per_grasp"] = sum(s["seconds_label"] for s in timed) / max(
            sum(s.get("sampled", 0) for s in timed), 1
        )
    return summary


def _by_stratum(labelled: Sequence[dict]) -> dict[str, dict[str, Any]]:
    """Per labeller verdict: grasps executed, physics successes, agreement."""
    out: dict[str, dict[str, Any]] = {}
    for g in labelled:
        c = out.setdefault(g["label_reason"], {"grasps": 0, "physics_success": 0, "agree": 0})
        c["grasps"] += 1
        c["physics_success"] += int(g["physics_success"])
        c["agree"] += int(bool(g["physics_success"]) == bool(g["label"]))
    for c in out.values():
        c["agreement"] = round(100 * c["agree"] / c["grasps"], 1)
    return dict(sorted(out.items(), key=lambda kv: -kv[1]["grasps"]))


def _weighted(labelled: Sequence[dict], resamples: int = 2000) -> dict[str, Any]:
    """The confusion matrix of the whole VGN sample (every sampled grasp, not only the
    stratified subset executed): each executed grasp weighted by its stratum's size over
    the number executed from it; a 95 % interval of the agreement by resampling scenes."""
    if not all("weight" in g for g in labelled):
        return {}
    cells = ("tp", "fn", "fp", "tn")
    by_scene: dict[int, np.ndarray] = {}
    for g in labelled:
        p, q = bool(g["physics_success"]), bool(g["label"])
        cell = cells.index("tp" if p and q else "fn" if p else "fp" if q else "tn")
        row = by_scene.setdefault(g["scene"], np.zeros(4))
        row[cell] += g["weight"]
    rows = np.stack(list(by_scene.values()))
    total = rows.sum(axis=0)
    share = total / total.sum()
    rng = np.random.default_rng(0)
    boot = []
    for _ in range(resamples):
        t = rows[rng.integers(len(rows), size=len(rows))].sum(axis=0)
        boot.append((t[0] + t[3]) / t.sum())
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return {
        "weighted_confusion_percent": {
            c: round(100 * float(v), 3) for c, v in zip(cells, share, strict=True)
        },
        "weighted_agreement": round(100 * float(share[0] + share[3]), 2),
        "weighted_agreement_interval": (round(100 * float(lo), 2), round(100 * float(hi), 2)),
        "weighted_physics_positive_rate": round(float(share[0] + share[1]), 4),
        "weighted_labeller_positive_rate": round(float(share[0] + share[2]), 4),
    }


def _disagree(physics: str, reason: str, labelled: Sequence[dict]) -> int:
    return sum(
        1
        for g in labelled
        if g["physics"] == physics
        and str(g.get("label_reason")) == reason
        and bool(g["physics_success"]) != bool(g["label"])
    )


def _same_object(labelled: Sequence[dict]) -> dict[str, int]:
    both = [g for g in labelled if g["physics_success"] and g["label"]]
    same = sum(1 for g in both if g.get("label_object") == g["physics_object"])
    return {"both_success": len(both), "same_object": same}


def _width_error(labelled: Sequence[dict]) -> dict[str, float] | None:
    err = [
        abs(float(g["label_width"]) - float(g["physics_width_closed"]))
        for g in labelled
        if g["physics_success"] and g["label"] and g.get("label_width") is not None
    ]
    if not err:
        return None
    return {
        "mean_mm": round(1000 * float(np.mean(err)), 2),
        "median_mm": round(1000 * float(np.median(err)), 2),
        "p90_mm": round(1000 * float(np.percentile(err, 90)), 2),
    }


def markdown(summary: dict[str, Any], command: str) -> str:
    """The summary as Markdown."""
    lines = ["# Grasp labeller against physics", "", f"`{command}`", ""]
    lines.append(
        f"{summary['grasps']} grasps over {summary['scenes_ok']} scenes "
        f"(status: {summary['scenes_status']}); layouts {summary['layouts']}, "
        f"splits {summary['splits']}, object sets {summary['object_sets']}, "
        f"objects per scene {summary['objects_per_scene']}."
    )
    lines.append("")
    lines.append(
        f"Physics outcomes: {summary['physics_kinds']}; positive rate "
        f"{100 * summary['physics_positive_rate']:.1f} %."
    )
    if "physics_seconds_per_grasp" in summary:
        s = summary["physics_seconds_per_grasp"]
        lines.append(
            f"Physics cost: {s['mean']:.3f} s/grasp/core mean, {s['median']:.3f} median, "
            f"{s['p90']:.3f} p90 (scene built or restored + execute, one thread); "
            f"by outcome {s['by_kind']}. "
            f"Scene build {summary['scene_build_seconds_mean']:.2f} s mean."
        )
    if "physics_cpu_seconds_per_grasp" in summary:
        c = summary["physics_cpu_seconds_per_grasp"]
        lines.append(
            f"Physics CPU time (the process's, unaffected by other jobs on the machine): "
            f"{c['mean']:.3f} s/grasp mean, {c['median']:.3f} median; by outcome {c['by_kind']}; "
            f"over the whole VGN sample (weighted) {c.get('weighted_mean', float('nan')):.3f} s."
        )
    if "confusion" in summary:
        m = summary["confusion"]
        lo, hi = summary["agreement_interval"]
        lines += [
            "",
            "| | labeller success | labeller failure |",
            "|---|--:|--:|",
            f"| physics success | {m['tp']} | {m['fn']} |",
            f"| physics failure | {m['fp']} | {m['tn']} |",
            "",
            f"Agreement {summary['agreement']:.1f} % [{lo:.1f}, {hi:.1f}] (95 % Wilson); "
            f"labeller positive rate {100 * summary['labeller_positive_rate']:.1f} %; "
            f"precision {summary['precision']:.3f}, recall {summary['recall']:.3f}; "
            f"same object where both succeed: {summary['same_object']}; width error "
            f"{summary['width_error']}.",
            "",
            "By the labeller's verdict (the strata executed):",
            "",
            "| labeller | executed | physics success | agree % |",
            "|---|--:|--:|--:|",
        ]
        for r, c in summary["by_stratum"].items():
            lines.append(f"| {r} | {c['grasps']} | {c['physics_success']} | {c['agreement']} |")
        if "weighted_agreement" in summary:
            w = summary["weighted_confusion_percent"]
            lo, hi = summary["weighted_agreement_interval"]
            lines += [
                "",
                f"Over the whole VGN sample ({summary['sampled']} grasps labelled; labeller "
                f"verdicts {summary['sampled_labels']}), weighting each executed grasp by its "
                f"stratum: agreement {summary['weighted_agreement']:.1f} % [{lo:.1f}, {hi:.1f}] "
                f"(95 %, scenes resampled); TP {w['tp']:.2f} %, FN {w['fn']:.2f} %, "
                f"FP {w['fp']:.2f} %, TN {w['tn']:.2f} %; physics positive rate "
                f"{100 * summary['weighted_physics_positive_rate']:.2f} %. Labeller: "
                f"{1e6 * summary['label_seconds_per_grasp']:.1f} µs a grasp (one thread).",
            ]
        lines += [
            "",
            "| physics | labeller reason | grasps | disagree |",
            "|---|---|--:|--:|",
        ]
        for row in summary["by_reason"]:
            lines.append(
                f"| {row['physics']} | {row['labeller']} | {row['grasps']} | {row['disagree']} |"
            )
        lines += [
            "",
            "| shape | grasps | physics + | labeller + | agree % | FP | FN |",
            "|---|--:|--:|--:|--:|--:|--:|",
        ]
        for s, c in summary["by_shape"].items():
            lines.append(
                f"| {s} | {c['grasps']} | {c['physics_success']} | {c['label_success']} | "
                f"{c['agreement']} | {c['fp']} | {c['fn']} |"
            )
    return "\n".join(lines) + "\n"


def write_summary(out: Path, command: str) -> dict[str, Any]:
    grasps = _read_jsonl(out / "grasps.jsonl")
    # A scene that crashed and was run again has a line per attempt: the last one counts.
    scenes = list({s["scene"]: s for s in _read_jsonl(out / "scenes.jsonl")}.values())
    summary = summarize(grasps, scenes)
    summary["command"] = command
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    (out / "summary.md").write_text(markdown(summary, command))
    return summary


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--scenes", type=int, default=80)
    parser.add_argument("--seed", type=int, default=38)
    parser.add_argument("--points", type=int, default=240, help="surface points a scene")
    parser.add_argument("--yaws", type=int, default=6)
    parser.add_argument("--positives", type=int, default=10, help="executed a scene, at most")
    parser.add_argument("--negatives", type=int, default=14, help="executed a scene, at most")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument(
        "--restore",
        action="store_true",
        help="one world a scene, restored between grasps (cheaper, not the same physics)",
    )
    parser.add_argument(
        "--execute-from",
        type=Path,
        metavar="RUN",
        help="execute exactly RUN's grasps (its settings; --restore chooses the mode)",
    )
    parser.add_argument("--summarize-only", action="store_true")
    parser.add_argument(
        "--relabel-from",
        type=Path,
        metavar="RUN",
        help="write to --out RUN's physics with the installed labeller's labels",
    )
    parser.add_argument(
        "--check-restore",
        type=int,
        default=0,
        metavar="N",
        help="also re-run N grasps (past the pre-grasp pose) in freshly built worlds",
    )
    args = parser.parse_args(argv)
    config = AgreementConfig(
        scenes=args.scenes,
        root_seed=args.seed,
        points=args.points,
        yaws=args.yaws,
        positives=args.positives,
        negatives=args.negatives,
        restore=args.restore,
    )
    command = "python scripts/label_agreement.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    if args.relabel_from is not None:
        relabel(args.relabel_from, args.out)
    elif args.execute_from is not None:
        config, plans = plans_of(args.execute_from, args.restore)
        run(config, args.out, args.workers, plans, str(args.execute_from))
    elif not args.summarize_only:
        run(config, args.out, args.workers)
    if args.check_restore:
        rows = check_restore(config, range(config.scenes), args.check_restore)
        same = sum(r["same"] for r in rows)
        print(f"restore check: {same}/{len(rows)} grasps the same as in a rebuilt world")
        (args.out / "restore_check.json").write_text(json.dumps(rows) + "\n")
    summary = write_summary(args.out, command)
    print(markdown(summary, command))


if __name__ == "__main__":
    main()
