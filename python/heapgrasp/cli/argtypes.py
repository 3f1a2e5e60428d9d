"""Argument types of the ``heapgrasp`` commands: numbers checked against a range, lists
of names checked against their choices, refused with a message that names the bad value
(argparse turns it into exit status 2); the user's object directory; ``--ray``."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

__all__ = [
    "OBJECT_DIR_HELP",
    "add_ray_argument",
    "comma_choices",
    "float_in",
    "int_at_least",
    "object_dir",
]


def int_at_least(lo: int) -> Callable[[str], int]:
    """A parser of integers ``>= lo``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {value}")
        return value

    parse.__name__ = f"integer >= {lo}"
    return parse


def float_in(lo: float, hi: float = math.inf, *, open_low: bool = False) -> Callable[[str], float]:
    """A parser of finite numbers in ``[lo, hi]`` (``(lo, hi]`` with ``open_low``)."""
    low = "(" if open_low else "["
    span = f"> {lo}" if hi == math.inf and open_low else f"in {low}{lo}, {hi}]"
    if hi == math.inf and not open_low:
        span = f">= {lo}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        ok = math.isfinite(value) and (value > lo if open_low else value >= lo) and value <= hi
        if not ok:
            raise argparse.ArgumentTypeError(f"must be finite and {span}, got {text}")
        return value

    parse.__name__ = f"number {span}"
    return parse


def comma_choices(what: str, allowed: tuple[str, ...]) -> Callable[[str], tuple[str, ...]]:
    """A parser of a comma-separated subset of ``allowed`` (returned in ``allowed``'s
    order); ``what`` names the items in the error, e.g. ``"method"``."""

    def parse(text: str) -> tuple[str, ...]:
        names = [s.strip().lower() for s in text.split(",") if s.strip()]
        bad = [n for n in names if n not in allowed]
        if bad or not names:
            raise argparse.ArgumentTypeError(
                f"unknown {what}(s) {', '.join(repr(b) for b in bad) or '(none)'}; "
                f"choose from {', '.join(allowed)}"
            )
        return tuple(a for a in allowed if a in names)

    parse.__name__ = f"{what} list"
    return parse


#: ``--object-dir``'s help (``heapgrasp run``, ``heapgrasp bench sim``).
OBJECT_DIR_HELP = (
    "your own objects: each subfolder of DIR is an object, a PyBullet object (model.urdf "
    "with its visual and collision meshes, in metres, e.g. pybullet-object-models' "
    "ycb_objects/YcbCrackerBox) or a download's mesh (YCB's "
    "003_cracker_box/google_16k/textured.obj, Google Scanned Objects' meshes/model.obj), "
    "or DIR holds mesh/URDF files; a concave collision "
    "mesh collides as its convex decomposition (cached), and the optical categories are "
    "drawn per scene group as for our objects. Scenes are drawn from these objects only, "
    "all of them treated as the evaluated split (object_set and the train/test split do "
    "not apply)"
)


def object_dir(text: str) -> str:
    """``--object-dir``: the directory as an absolute path, so that a resumed run finds it
    from anywhere (what it holds is checked before any scene runs)."""
    return str(Path(text).expanduser().absolute())


def add_ray_argument(parser: argparse.ArgumentParser, what: str) -> None:
    """``--ray [ADDRESS]``: run ``what`` (e.g. "shards") as Ray tasks."""
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        default=None,
        metavar="ADDRESS",
        help=f"run {what} as Ray tasks: alone, start a local cluster; with ADDRESS, join it "
        "(needs pip install 'heapgrasp[ray]')",
    )
