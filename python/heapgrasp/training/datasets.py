"""Reading a dataset directory of :mod:`heapgrasp.data.shards` (``manifest.json`` and
``shard-NNNNN.npz``), as the view and grasp datasets share it.

The writers sit above this package (:mod:`heapgrasp.data`), so the layout is read here
from its documented form: a manifest with ``format``, ``version``, ``split``,
``config`` and ``shards`` (``{file name: {"samples": n, ...}}``).
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any, Protocol, TypeVar

import numpy as np
import numpy.typing as npt

__all__ = [
    "check_array",
    "check_finite",
    "first_of_same",
    "open_shard",
    "read_manifest",
    "read_shards",
]

_T = TypeVar("_T")


class _Dataset(Protocol):
    @property
    def split(self) -> str: ...

    @property
    def sources(self) -> Sequence[Any]: ...


_D = TypeVar("_D", bound=_Dataset)


def read_manifest(
    path: Path,
    *,
    fmt: str,
    version: int,
    what: str,
    command: str,
    error: type[Exception],
) -> dict[str, Any]:
    """The manifest of the ``what`` dataset directory ``path`` (format ``fmt``, version
    ``version``), checked; ``error`` naming the directory or file and the problem
    otherwise (``command`` is the one that writes such a dataset, for the hint)."""
    if not path.exists():
        raise error(f"{path}: no such directory")
    if not path.is_dir():
        raise error(f"{path}: not a directory (expected a {what} directory)")
    file = path / "manifest.json"
    try:
        manifest = json.loads(file.read_text())
    except FileNotFoundError:
        raise error(
            f"{path}: not a {what} (no manifest.json; write one with '{command} {path}')"
        ) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise error(f"{file}: not a readable manifest ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != fmt:
        raise error(f"{file}: not a {what} manifest (format != {fmt!r})")
    got = manifest.get("version")
    if got != version:
        raise error(f"{file}: dataset format version {got!r}; this heapgrasp reads {version}")
    for key, typ in (("split", str), ("config", dict), ("shards", dict)):
        if not isinstance(manifest.get(key), typ):
            raise error(f"{file}: {key!r} missing or not a {typ.__name__}")
    return manifest


def read_shards(
    root: Path,
    manifest: dict[str, Any],
    load: Callable[[Path, int], _T | None],
    *,
    workers: int,
    error: type[Exception],
) -> list[_T]:
    """``load(file, samples)`` of every shard the manifest lists, in name order, on
    ``workers`` threads (decompression releases the GIL); the shards that hold no
    sample (``load`` returns None) left out."""
    entries: list[tuple[Path, int]] = []
    for name, entry in sorted(manifest["shards"].items()):
        samples = entry.get("samples") if isinstance(entry, dict) else None
        if not isinstance(samples, int) or isinstance(samples, bool) or samples < 0:
            raise error(f"{root / 'manifest.json'}: shard {name!r} has no sample count")
        if Path(name).name != name:
            raise error(f"{root / 'manifest.json'}: shard name {name!r} is not a file")
        entries.append((root / name, samples))
    with ThreadPoolExecutor(max(1, workers)) as pool:
        return [s for s in pool.map(lambda e: load(e[0], e[1]), entries) if s is not None]


def open_shard(
    file: Path, names: Sequence[str], expected: int, *, what: str, error: type[Exception]
) -> dict[str, np.ndarray] | None:
    """The arrays ``names`` of shard ``file``, whose ``k`` array counts ``expected``
    samples (the manifest's count; ``what`` names them in messages); None when it holds
    none. ``error`` naming the file when it is missing, unreadable, lacks an array or
    holds another count."""
    try:
        with np.load(file, allow_pickle=False) as data:
            missing = [k for k in names if k not in data.files]
            if missing:
                raise error(f"{file}: missing array(s) {', '.join(missing)}")
            n = int(data["k"].shape[0]) if data["k"].ndim == 1 else -1
            if n != expected:
                raise error(
                    f"{file}: {n} {what}, the manifest says {expected} "
                    "(a shard rewritten without its manifest?)"
                )
            if n == 0:
                return None
            return {name: data[name] for name in names}
    except FileNotFoundError:
        raise error(f"{file}: listed in manifest.json but missing") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        if isinstance(exc, error):
            raise
        raise error(f"{file}: unreadable shard ({exc})") from None


def check_array(
    file: Path,
    name: str,
    a: np.ndarray,
    dtype: npt.DTypeLike,
    shape: tuple[int, ...],
    error: type[Exception],
) -> None:
    """``error`` naming ``file`` and array ``name`` unless ``a`` has ``dtype`` and
    ``shape``."""
    if a.dtype != dtype or a.shape != shape:
        raise error(f"{file}: {name!r} is {a.dtype} {a.shape}, expected {np.dtype(dtype)} {shape}")


def check_finite(file: Path, name: str, a: np.ndarray, error: type[Exception]) -> None:
    """``error`` naming ``file`` and array ``name`` where ``a`` holds NaN or infinity."""
    if not np.isfinite(a).all():
        raise error(f"{file}: {name!r} holds NaN or infinity")


def first_of_same(
    datasets: Sequence[_D], compatible: Callable[[_D, _D], None], error: type[Exception]
) -> _D:
    """The first of ``datasets`` to be concatenated, after ``compatible(first, other)``
    and a check that ``other`` has the first's split, in turn for every other; ``error``
    when there is none or a split differs."""
    if not datasets:
        raise error("no dataset given")
    first = datasets[0]
    for other in datasets[1:]:
        compatible(first, other)
        if other.split != first.split:
            raise error(
                f"{other.sources[0].path} is a {other.split!r} dataset, "
                f"{first.sources[0].path} a {first.split!r} one"
            )
    return first
