"""The commands' old spellings, kept for one release (issue 55: one grammar, noun then
verb).

An old spelling is the same command under another name: :func:`add_alias` calls the
function that builds the new spelling's parser (its options are defined there, once)
with the old group's subparsers and the old name, says in its help that it is
deprecated, and wraps its ``func`` in :class:`Deprecated`, which prints one line to
stderr before running the command::

    heapgrasp: 'data grasps' is now 'grasps data'; the old spelling goes in the next release

:data:`ALIASES` lists every old spelling; :func:`add_aliases` registers them: at the top
level (``replay``), in a group that still exists (``bench viewsphere``), or in a group
kept only for them (``data``, ``train``).
"""

from __future__ import annotations

import argparse
import sys
import textwrap
from collections.abc import Callable, Mapping
from typing import TypeAlias

from heapgrasp.cli import grasps, robot, seg, views, viewsphere

__all__ = ["ALIASES", "Builder", "Deprecated", "add_alias", "add_aliases", "notice"]

SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
#: A function that adds one command, under the name it is given, to a group's
#: subparsers and returns its parser (with ``func`` set as a default).
Builder: TypeAlias = "Callable[[SubParsers, str], argparse.ArgumentParser]"

#: Every old spelling, its new one, and the function that builds both.
ALIASES: tuple[tuple[str, str, Builder], ...] = (
    ("data views", "views data", views.add_data),
    ("data grasps", "grasps data", grasps.add_data),
    ("data loop-grasps", "grasps loop-data", grasps.add_loop_data),
    ("data seg", "seg data", seg.add_data),
    ("data viewsphere-paths", "viewsphere data", viewsphere.add_data),
    ("train views", "views train", views.add_train),
    ("train grasps", "grasps train", grasps.add_train),
    ("train viewsphere-policy", "viewsphere train", viewsphere.add_train),
    ("bench viewsphere", "viewsphere bench", viewsphere.add_bench),
    ("replay", "robot replay", robot.add_replay),
)


def notice(old: str, new: str) -> str:
    """The line an old spelling prints before it runs."""
    return f"heapgrasp: '{old}' is now '{new}'; the old spelling goes in the next release"


class Deprecated:
    """A command's ``func`` under its old spelling: prints :func:`notice` to stderr, then
    runs ``func``."""

    def __init__(self, func: Callable[[argparse.Namespace], int], old: str, new: str) -> None:
        self.func = func
        self.old = old
        self.new = new

    def __call__(self, args: argparse.Namespace) -> int:
        print(notice(self.old, self.new), file=sys.stderr, flush=True)
        return self.func(args)

    def __repr__(self) -> str:
        return f"Deprecated({self.func!r}, {self.old!r}, {self.new!r})"


def add_alias(sub: SubParsers, old: str, new: str, build: Builder) -> argparse.ArgumentParser:
    """Registers the command ``build`` makes under its old spelling ``old`` (its last word
    is the name in ``sub``, the old group's subparsers): the same options, its help marked
    deprecated, its ``func`` wrapped in :class:`Deprecated`."""
    name = old.split()[-1]
    parser = build(sub, name)
    for choice in sub._choices_actions:  # the line in the group's list of commands
        if choice.dest == name:
            choice.help = f"deprecated: now '{new}'"
    note = textwrap.fill(
        f"Deprecated: '{old}' is now '{new}', with the same options; the old spelling "
        "goes in the next release.",
        width=80,
    )
    parser.description = note + ("\n\n" + parser.description if parser.description else "")
    parser.set_defaults(func=Deprecated(parser.get_default("func"), old, new))
    return parser


def _group(commands: SubParsers, name: str) -> SubParsers:
    """A group kept only for old spellings (``data``, ``train``), its help saying so."""
    moved = [(old, new) for old, new, _ in ALIASES if old.split()[0] == name and " " in old]
    group = commands.add_parser(
        name,
        help="deprecated: now " + ", ".join(new for _, new in moved),
        description=textwrap.fill(
            f"Deprecated: the '{name}' commands moved (noun then verb). The old spellings "
            "run the new ones, with the same options, and go in the next release:",
            width=80,
        )
        + "\n\n"
        + "\n".join(f"  heapgrasp {old:<26} now: heapgrasp {new}" for old, new in moved),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    return group.add_subparsers(dest=f"{name}_command", metavar="COMMAND", required=True)


def add_aliases(commands: SubParsers, groups: Mapping[str, SubParsers]) -> None:
    """Registers every spelling of :data:`ALIASES`: a one-word one among ``commands``,
    the others in their group of ``groups`` (e.g. ``bench``) or, where the group is not
    there, in a deprecated group made for them."""
    made = dict(groups)
    for old, new, build in ALIASES:
        words = old.split()
        if len(words) == 1:
            sub = commands
        else:
            if words[0] not in made:
                made[words[0]] = _group(commands, words[0])
            sub = made[words[0]]
        add_alias(sub, old, new, build)
