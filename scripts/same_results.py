"""Are two benchmark folders the same results? For proving a refactor kept behaviour.

Usage::

    python scripts/same_results.py BEFORE_DIR AFTER_DIR

Every ``*.json`` and ``*.jsonl`` file under ``BEFORE_DIR`` is compared with the file of the
same name under ``AFTER_DIR``, ignoring what legitimately differs between two runs of the
same code: timings (keys naming a time, duration, seconds or compute), dates, versions,
commits, hosts and absolute paths of the checkout (keys ``path``). ``.jsonl`` lines are
compared as a set (a process pool finishes scenes in any order); floats to 1e-6.

Prints each difference (at most 8 per file) and exits 0 when there are none, 1 otherwise.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

IGNORED = (
    "time",
    "_s",
    "seconds",
    "compute",
    "duration",
    "elapsed",
    "started",
    "finished",
    "date",
    "commit",
    "version",
    "host",
    "wall",
)


def _ignored(key: str) -> bool:
    k = key.lower()
    return k == "path" or any(t in k for t in IGNORED)


def strip(x: Any) -> Any:
    """``x`` without the ignored keys, floats rounded."""
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if not _ignored(k)}
    if isinstance(x, list):
        return [strip(v) for v in x]
    if isinstance(x, float):
        return round(x, 6)
    return x


def diff(a: Any, b: Any, where: str) -> list[str]:
    """Every place ``a`` and ``b`` differ."""
    if type(a) is not type(b):
        return [f"{where}: {a!r} != {b!r}"]
    if isinstance(a, dict):
        out: list[str] = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{where}/{k}: only in {'after' if k not in a else 'before'}")
            else:
                out += diff(a[k], b[k], f"{where}/{k}")
        return out
    if isinstance(a, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items != {len(b)}"]
        return [
            d
            for i, (x, y) in enumerate(zip(a, b, strict=True))
            for d in diff(x, y, f"{where}[{i}]")
        ]
    return [] if a == b else [f"{where}: {a!r} != {b!r}"]


def load(path: Path) -> Any:
    if path.suffix == ".json":
        return strip(json.loads(path.read_text()))
    lines = [strip(json.loads(line)) for line in path.read_text().splitlines() if line.strip()]
    return sorted(lines, key=lambda r: json.dumps(r, sort_keys=True))


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    before, after = (Path(a) for a in argv)
    for d in (before, after):
        if not d.is_dir():
            print(f"not a folder: {d}", file=sys.stderr)
            return 2
    count = 0
    files = sorted(p for p in before.rglob("*") if p.suffix in (".json", ".jsonl"))
    for f in files:
        rel = f.relative_to(before)
        other = after / rel
        if not other.is_file():
            print(f"{rel}: missing in {after}")
            count += 1
            continue
        found = diff(load(f), load(other), str(rel))
        count += len(found)
        for line in found[:8]:
            print(line)
    print(f"{len(files)} files compared, {count} differences")
    return 0 if count == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
