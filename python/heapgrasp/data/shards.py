"""What the networks' datasets share: sharded, resumable generation.

A dataset is a directory of shard files and a manifest::

    manifest.json          what was asked, what was made (rebuilt from the shards)
    shard-00000.npz        the samples of scenes 0 .. shard_size − 1
    ...

Every scene's seed derives from the dataset's root seed and the scene's index, so a
shard run again gives the same arrays, and the file is written deterministically (no
time stamps), so the same bytes. A shard is written to a temporary file and renamed:
whole or absent. :func:`generate` runs the shards not yet there (a re-run continues
where one stopped; a larger ``scenes`` adds shards) on this process, a process pool
that survives a dead worker, or Ray, and keeps the manifest up to date. A dataset's
settings (:meth:`ShardedConfig.identity`) must match to add shards to it.

Each dataset module (:mod:`heapgrasp.data.views`, :mod:`heapgrasp.data.grasps`) gives
its config, a :class:`ShardedConfig` that runs a shard's scenes
(:meth:`ShardedConfig.run_shard`) and names its :class:`DatasetSpec` (the format and
what the manifest records).
"""

from __future__ import annotations

import abc
import dataclasses
import importlib
import io
import json
import os
import platform
import sys
import time
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

__all__ = [
    "SPLITS",
    "DatasetSpec",
    "ShardFailure",
    "ShardedConfig",
    "generate",
    "ray_map",
    "read_manifest",
    "run_scenes",
    "save_shard",
    "shard_path",
    "shard_problem",
    "write_shard",
]

SPLITS = ("train", "val", "test")


@dataclass(frozen=True)
class DatasetSpec:
    """What a dataset's manifest says of it beyond its config."""

    format: str
    """The manifest's ``format``."""
    version: int
    name: str
    """What it is, for messages (``view dataset``)."""
    settings: Callable[[], dict[str, Any]]
    """The loop's settings the samples were made with (recorded in the manifest)."""
    counts: Mapping[str, str] = field(default_factory=dict)
    """Per-shard counts recorded in the manifest and summed: ``{name: array}``, the
    count is the array's length."""


@dataclass(frozen=True)
class ShardedConfig(abc.ABC):
    """The settings every dataset has; a dataset's config adds its own fields, its
    :attr:`spec` and :meth:`run_shard`."""

    spec: ClassVar[DatasetSpec]

    scenes: int = 1000
    """Scenes to run (each gives at most one sample)."""
    root_seed: int = 0
    """Seed every scene's seed derives from."""
    split: str = "train"
    """Objects of ``train``, ``val`` (held out of training) or ``test`` (the benchmark's)."""
    shard_size: int = 50
    """Scenes per shard file."""

    def __post_init__(self) -> None:
        self.positive("scenes", "shard_size")
        if isinstance(self.root_seed, bool) or not isinstance(self.root_seed, int):
            raise ValueError(f"root_seed must be an integer, got {self.root_seed!r}")
        if self.root_seed < 0:
            raise ValueError(f"root_seed must be >= 0, got {self.root_seed}")
        if self.split not in SPLITS:
            raise ValueError(f"split must be one of {', '.join(SPLITS)}; got {self.split!r}")

    def positive(self, *names: str) -> None:
        """ValueError unless each field of ``names`` is an integer >= 1."""
        for name in names:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")

    @property
    def shards(self) -> int:
        """Number of shard files."""
        return -(-self.scenes // self.shard_size)

    def shard_scenes(self, shard: int) -> range:
        """Scene indices of ``shard``."""
        return range(shard * self.shard_size, min(self.scenes, (shard + 1) * self.shard_size))

    def identity(self) -> dict[str, Any]:
        """What must match to add shards to an existing dataset (everything but the
        number of scenes)."""
        d = dataclasses.asdict(self)
        d.pop("scenes")
        return d

    def object_names(self) -> list[str]:
        """The objects the dataset's scenes draw from (recorded in the manifest; a
        dataset of other objects is not added to): the benchmark library's split."""
        from heapgrasp.data.scenes import dataset_objects

        return dataset_objects(self.split)

    @abc.abstractmethod
    def run_shard(self, shard: int) -> dict[str, Any]:
        """The arrays of ``shard`` (its scenes run in this process), with the sample
        axis's ``k`` and the counts ``scenes`` and ``dropped`` (each dataset's own)."""


class ShardFailure(RuntimeError):
    """Shards that failed; the others are written."""

    def __init__(self, failures: dict[int, str]) -> None:
        self.failures = failures
        lines = [f"shard {i}: {msg}" for i, msg in sorted(failures.items())]
        super().__init__(f"{len(failures)} shard(s) failed:\n" + "\n".join(lines))


# --------------------------------------------------------------------------- files


def shard_path(out: Path, shard: int) -> Path:
    """File of ``shard``."""
    return out / f"shard-{shard:05d}.npz"


def save_shard(out: str, shard: int, data: Mapping[str, Any]) -> tuple[int, int, int]:
    """Writes ``data`` as ``shard``'s file (a compressed ``.npz``, written to a temporary
    file and renamed); returns ``(shard, samples, dropped)`` (samples: ``len(data["k"])``).
    The bytes depend on the arrays alone (entries in the order given, no time stamps)."""
    path = shard_path(Path(out), shard)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key, value in data.items():
            buffer = io.BytesIO()
            np.lib.format.write_array(buffer, np.asanyarray(value), allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, buffer.getvalue())
    os.replace(tmp, path)
    return shard, len(data["k"]), int(data["dropped"])


def run_scenes(
    config: ShardedConfig, shard: int, sample: Callable[[Any, int, Any], dict[str, Any] | None]
) -> tuple[list[dict[str, Any]], range]:
    """``sample(config, index, library)`` of every scene of ``shard`` in this process
    (one object library for all); the samples made (None: dropped) and the scenes."""
    from heapgrasp.loop.config import RunConfig
    from heapgrasp.sim.build import object_library

    library = object_library(RunConfig())
    scenes = config.shard_scenes(shard)
    samples = [s for s in (sample(config, index, library) for index in scenes) if s is not None]
    return samples, scenes


def write_shard(config: ShardedConfig, shard: int, out: str) -> tuple[int, int, int]:
    """Runs and writes ``shard`` (:func:`save_shard`); returns ``(shard, samples,
    dropped)``. Idempotent: the same bytes on every run."""
    return save_shard(out, shard, config.run_shard(shard))


def _init_worker() -> None:
    from heapgrasp.loop.workers import init_worker

    init_worker()  # one core each, and dying with the parent


# --------------------------------------------------------------------------- manifest


def read_manifest(out: Path, spec: DatasetSpec) -> dict[str, Any]:
    """The dataset's ``manifest.json``; ValueError naming the file when it is not one."""
    path = out / "manifest.json"
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no {spec.name} here (no manifest.json)") from None
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a readable manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != spec.format:
        raise ValueError(f"{path}: not a {spec.format} manifest")
    return manifest


def _holds(out: Path, config: ShardedConfig, shard: int) -> bool:
    """Whether ``out`` holds ``shard`` whole: its file, with at least as many scenes as the
    shard has now (the last shard of a smaller dataset that is being extended has fewer,
    and is written again)."""
    path = shard_path(out, shard)
    if not path.exists():
        return False
    problem = shard_problem(path)
    if problem is not None:  # written again: the shard's scenes give the same bytes
        print(f"heapgrasp: {path} is damaged ({problem}); writing it again", file=sys.stderr)
        return False
    with np.load(path) as data:
        # a shard made for more scenes than now asked for is kept whole (nothing lost)
        return int(data["scenes"]) >= len(config.shard_scenes(shard))


#: :func:`shard_problem`'s verdicts by (path, size, modification time): the manifest is
#: rewritten after every shard, and a file checked once need not be read again.
_CHECKED: dict[tuple[str, int, int], str | None] = {}


def shard_problem(path: Path) -> str | None:
    """What is wrong with a shard file, None if nothing: it must be a whole zip archive
    whose every member passes its CRC-32 check (a truncated, empty or garbled file does
    not) and holds the ``scenes`` count."""
    stat = path.stat()
    key = (str(path), stat.st_size, stat.st_mtime_ns)
    if key not in _CHECKED:
        _CHECKED[key] = _check_archive(path)
    return _CHECKED[key]


def _check_archive(path: Path) -> str | None:
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
            if bad is not None:
                return f"member {bad} fails its CRC check"
            if "scenes.npy" not in archive.namelist():
                return "no 'scenes' entry"
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, RuntimeError) as exc:
        return f"{type(exc).__name__}: {exc}"
    except Exception as exc:  # zlib.error and the like: a garbled member
        return f"{type(exc).__name__}: {exc}"
    return None


def _shard_entry(path: Path, spec: DatasetSpec) -> dict[str, Any]:
    with np.load(path) as data:
        entry = {
            "samples": len(data["k"]),
            "scenes": int(data["scenes"]),
            "dropped": int(data["dropped"]),
        }
        entry.update({name: len(data[key]) for name, key in spec.counts.items()})
    entry["bytes"] = path.stat().st_size
    return entry


def _write_manifest(
    out: Path, spec: DatasetSpec, config: ShardedConfig, objects: list[str], started: float
) -> dict[str, Any]:
    import heapgrasp

    shards = {}
    for shard in range(config.shards):
        path = shard_path(out, shard)
        if path.exists() and shard_problem(path) is None:  # a damaged one is written again
            shards[path.name] = _shard_entry(path, spec)
    totals = {
        key: sum(s[key] for s in shards.values()) for key in ("samples", "dropped", *spec.counts)
    }
    manifest = {
        "format": spec.format,
        "version": spec.version,
        "split": config.split,
        "root_seed": config.root_seed,
        "objects": objects,
        "config": {**config.identity(), "scenes": config.scenes, **spec.settings()},
        "shards": shards,
        **totals,
        # every shard there, each holding all the scenes it has now
        "complete": all(
            shard_path(out, k).name in shards
            and shards[shard_path(out, k).name]["scenes"] >= len(config.shard_scenes(k))
            for k in range(config.shards)
        ),
        "package_version": heapgrasp.__version__,
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "command": " ".join(sys.argv),
        "seconds_this_run": round(time.monotonic() - started, 1),
    }
    tmp = out / ".manifest.json.tmp"
    tmp.write_text(json.dumps(manifest, indent=1) + "\n")
    os.replace(tmp, out / "manifest.json")
    return manifest


def _check_compatible(
    out: Path, spec: DatasetSpec, config: ShardedConfig, objects: list[str]
) -> None:
    """ValueError unless shards made now would belong with those in ``out``: the same
    config (but the number of scenes), loop settings and objects."""
    if not (out / "manifest.json").exists():
        if any(out.glob("shard-*.npz")):
            raise ValueError(f"{out}: shard files without a manifest.json; use an empty directory")
        return
    manifest = read_manifest(out, spec)
    old = manifest["config"]
    # as the manifest holds them: JSON's lists for tuples
    mine = json.loads(json.dumps({**config.identity(), **spec.settings()}))
    diff = [f"{k}: {old.get(k)!r} there, {mine[k]!r} asked" for k in mine if old.get(k) != mine[k]]
    if manifest.get("objects") != objects:
        diff.append(f"objects: {len(manifest.get('objects') or [])} there, {len(objects)} asked")
    if diff:
        raise ValueError(f"{out} holds a dataset made with other settings ({', '.join(diff)})")


# --------------------------------------------------------------------------- running


def generate(
    config: ShardedConfig,
    out: Path,
    *,
    workers: int = 1,
    ray_address: str | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Writes every shard of ``config`` not yet in ``out`` and the manifest; returns the
    manifest. A shard that fails (an exception, or a worker process that died) is
    reported by :class:`ShardFailure` after every other shard is written.

    ``workers``: processes of a local pool (1: this process). ``ray_address``: run the
    shards as Ray tasks instead (``"local"`` starts a local cluster, else the address of
    a running one); Ray retries a task whose worker died, which writing a shard
    tolerates (idempotent, atomic).
    """
    from tqdm import tqdm  # type: ignore[import-untyped,unused-ignore]

    spec = config.spec
    started = time.monotonic()
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    out.mkdir(parents=True, exist_ok=True)
    objects = config.object_names()
    _check_compatible(out, spec, config, objects)
    todo = [s for s in range(config.shards) if not _holds(out, config, s)]
    _write_manifest(out, spec, config, objects, started)
    bar = tqdm(
        total=config.scenes,
        initial=config.scenes - sum(len(config.shard_scenes(s)) for s in todo),
        unit="scene",
        file=sys.stderr,
        disable=not progress,
    )
    failures: dict[int, str] = {}

    def done(shard: int) -> None:
        bar.update(len(config.shard_scenes(shard)))
        _write_manifest(out, spec, config, objects, started)

    run = _Run(config, str(out), done, failures)
    if not todo:
        pass  # complete: no pool, no cluster
    elif ray_address is not None:
        run.ray(todo, ray_address)
    elif workers == 1:
        for shard in todo:
            try:
                write_shard(config, shard, str(out))
            except Exception as exc:  # reported with its shard; the others go on
                failures[shard] = f"{type(exc).__name__}: {exc}"
                continue
            done(shard)
    else:
        run.pool(todo, workers)
    bar.close()
    manifest = _write_manifest(out, spec, config, objects, started)
    if failures:
        raise ShardFailure(failures)
    return manifest


@dataclass
class _Run:
    """The shards of one :func:`generate` call on many processes."""

    config: ShardedConfig
    out: str
    done: Callable[[int], None]
    failures: dict[int, str]

    def pool(self, todo: list[int], workers: int) -> None:
        """The shards on a process pool. A worker that dies (a native crash) breaks the
        pool, and every shard it had not finished fails with it; those are run again,
        each in a pool of its own, so the guilty one fails alone and the others are
        written."""
        crashed: list[int] = []
        with ProcessPoolExecutor(min(workers, len(todo)), initializer=_init_worker) as pool:
            futures = {pool.submit(write_shard, self.config, s, self.out): s for s in todo}
            remaining = set(futures)
            while remaining:
                finished, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for fut in finished:
                    shard = futures[fut]
                    try:
                        fut.result()
                    except BrokenProcessPool:
                        crashed.append(shard)
                        continue
                    except Exception as exc:
                        self.failures[shard] = f"{type(exc).__name__}: {exc}"
                        continue
                    self.done(shard)
        for shard in sorted(crashed):
            with ProcessPoolExecutor(1, initializer=_init_worker) as single:
                try:
                    single.submit(write_shard, self.config, shard, self.out).result()
                except BrokenProcessPool:
                    self.failures[shard] = "the worker process died (a native crash)"
                    continue
                except Exception as exc:
                    self.failures[shard] = f"{type(exc).__name__}: {exc}"
                    continue
            self.done(shard)

    def ray(self, todo: list[int], address: str) -> None:
        """The shards as Ray tasks (``pip install 'heapgrasp[ray]'``)."""
        calls = [(self.config, s, self.out) for s in todo]
        for k, _, error in ray_map(write_shard, calls, address):
            if error is not None:
                self.failures[todo[k]] = f"{type(error).__name__}: {error}"
                continue
            self.done(todo[k])


def ray_map(
    fn: Callable[..., Any], calls: Sequence[tuple[Any, ...]], address: str
) -> Iterator[tuple[int, Any, Exception | None]]:
    """``fn(*calls[k])`` for every ``k`` as Ray tasks (``pip install 'heapgrasp[ray]'``;
    ``address`` ``"local"`` starts a local cluster, else joins that one), each on one
    CPU with the core on one thread, retried twice (so ``fn`` must be idempotent).
    Yields ``(k, result, None)`` or ``(k, None, error)`` as the tasks finish."""
    try:
        ray: Any = importlib.import_module("ray")  # optional; typed loosely either way
    except ImportError:
        raise ImportError(
            "--ray needs Ray, which is not installed: pip install 'heapgrasp[ray]'"
        ) from None
    env = {"env_vars": {"HEAPGRASP_NUM_THREADS": "1"}}
    if address == "local":
        ray.init(runtime_env=env)
    else:
        ray.init(address=address, runtime_env=env)
    try:
        task = ray.remote(max_retries=2, num_cpus=1)(fn)
        refs = {task.remote(*args): k for k, args in enumerate(calls)}
        remaining = list(refs)
        while remaining:
            ready, remaining = ray.wait(remaining, num_returns=1)
            for ref in ready:
                try:
                    yield refs[ref], ray.get(ref), None
                except Exception as exc:
                    yield refs[ref], None, exc
    finally:
        ray.shutdown()
