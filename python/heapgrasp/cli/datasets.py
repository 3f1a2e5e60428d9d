"""What every dataset command shares (``views data``, ``grasps data``, ``grasps
loop-data``, ``seg data``, ``viewsphere data``): the options, the run on a process pool
or Ray, the summary line, and the closing paragraph of their help (:data:`SHARDS`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeAlias

from heapgrasp.cli.argtypes import add_ray_argument, int_at_least

__all__ = ["SHARDS", "dataset_parser", "generate_command", "section"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"

#: The closing paragraph of every dataset command's help.
SHARDS = """\
Shards are written whole or not at all; running the same command again continues where
it stopped (finished shards are kept) and adding scenes (a larger ``--scenes``) adds
shards; other settings than the dataset's are refused. Scenes run on a process pool
(``--workers``, default: every core) or on Ray (``--ray`` starts a local cluster,
``--ray ADDRESS`` joins one)."""


def section(doc: str | None, command: str) -> str:
    """The paragraphs of a module's ``doc`` on ``heapgrasp COMMAND``: from the one that
    opens with ````heapgrasp COMMAND```` to the next that opens with ````heapgrasp ````."""
    paragraphs = (doc or "").strip().split("\n\n")
    own: list[str] = []
    for para in paragraphs:
        if para.startswith(f"``heapgrasp {command}``"):
            own = [para]
        elif own and para.startswith("``heapgrasp "):
            break
        elif own:
            own.append(para)
    return "\n\n".join(own)


def generate_command(
    args: argparse.Namespace,
    config_class: Callable[..., Any],
    *,
    report: Callable[[Path], Any] | None = None,
    **settings: Any,
) -> int:
    """Generates the dataset of ``config_class`` (a dataset's config, e.g.
    :class:`heapgrasp.data.views.ViewDataConfig`) the options ask for, with ``settings``
    (and ``--max-objects`` where the command has it); prints a JSON summary, with
    ``network_on_these_phases`` from ``report(out)`` where given."""
    from heapgrasp.data.shards import ShardFailure, generate

    common = {
        "scenes": args.scenes,
        "root_seed": args.seed,
        "split": args.split,
        "shard_size": args.shard_size,
    }
    if getattr(args, "max_objects", None) is not None:
        common["max_objects"] = args.max_objects
    try:
        config = config_class(**common, **settings)
    except ValueError as exc:
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out)
    try:
        manifest = generate(
            config, out, workers=args.workers, ray_address=args.ray, progress=not args.quiet
        )
    except ShardFailure as exc:
        print(
            f"heapgrasp: error: {exc}\nthe other shards are written; run again to retry",
            file=sys.stderr,
        )
        return 1
    except ImportError as exc:  # --ray without Ray
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # refused: a dataset of other settings, stray shard files
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    keys = ("split", "samples", "dropped", "grasps", "complete")
    summary = {"out": str(out), **{k: manifest[k] for k in keys if k in manifest}}
    if report is not None:
        summary["network_on_these_phases"] = report(out)
    print(json.dumps(summary))
    return 0


def dataset_parser(
    sub: SubParsers,
    name: str,
    help: str,
    description: str,
    *,
    scenes: int,
    shard_size: int,
    max_objects: bool = True,
) -> argparse.ArgumentParser:
    """A dataset command with the options every dataset has; its help is
    ``description`` (that dataset alone) and :data:`SHARDS`."""
    p = sub.add_parser(
        name,
        help=help,
        description=f"{description}\n\n{SHARDS}" if description else SHARDS,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("out", metavar="OUT", help="dataset directory (created; resumed if present)")
    p.add_argument(
        "--scenes",
        type=int_at_least(1),
        default=scenes,
        help=f"scenes to run (default {scenes})",
    )
    p.add_argument(
        "--seed", type=int_at_least(0), default=0, help="root seed of every scene (default 0)"
    )
    p.add_argument(
        "--split",
        choices=("train", "val", "test"),
        default="train",
        help="objects: train, val (train objects held out for validation) or test (the "
        "benchmark's held-out objects, for measuring only); default train",
    )
    p.add_argument(
        "--shard-size",
        type=int_at_least(1),
        default=shard_size,
        help=f"scenes per shard (default {shard_size})",
    )
    if max_objects:
        p.add_argument(
            "--max-objects", type=int_at_least(1), default=5, help="N_ob (Table I; default 5)"
        )
    p.add_argument(
        "--workers",
        type=int_at_least(1),
        default=os.cpu_count() or 1,
        help="processes of the local pool (default: every core)",
    )
    add_ray_argument(p, "shards")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p
