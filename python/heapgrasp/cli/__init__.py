"""The ``heapgrasp`` command line: one grammar, noun then verb.

Commands are grouped in subparsers, every parser built in a module of this package
(``add_parser(subparsers)`` adds a group; a command with an old spelling has its own
function, ``add_VERB(subparsers, name)``, that builds it under either name); every leaf
command sets ``func``, a callable taking the parsed :class:`argparse.Namespace` and
returning the exit status. The commands::

    heapgrasp run [options]                  simulated pick-and-place (HEAPGrasp, baselines)
    heapgrasp show RUN_DIR                   a run's scene recorded for the Rerun viewer
    heapgrasp bench carve|world|sim|grasp|topk|compare|seg|noise|clutter
                                             benchmarks
    heapgrasp sim capture                    frames of a seeded scene
    heapgrasp views data|train               the view network: its dataset (Algorithm 1),
                                             the network trained on it (eq. 13)
    heapgrasp grasps data|loop-data|train    the grasp network: its datasets (VGN's scheme,
                                             the loop's own phases), the network (eq. 11)
    heapgrasp critic data|train|eval|convert the learned grasp critic
    heapgrasp seg data|train|eval|predict|coco
                                             the 4-class segmentation network (DeepLabv3+)
    heapgrasp viewsphere bench|data|train    the active-vision grasp benchmark (Natarajan et
                                             al.), its policies' dataset and learned policies
    heapgrasp robot init|check|board|calibrate|run|replay
                                             the real robot (UR + RealSense + Robotiq);
                                             --sim rehearses it against the simulator,
                                             replay plans a recorded run again

Old spellings, kept for one release (:mod:`heapgrasp.cli.aliases`): each runs its new
spelling, with the same options, after one deprecation line on stderr::

    heapgrasp data views|grasps|loop-grasps|seg|viewsphere-paths
                                             views data, grasps data, grasps loop-data,
                                             seg data, viewsphere data
    heapgrasp train views|grasps|viewsphere-policy
                                             views train, grasps train, viewsphere train
    heapgrasp bench viewsphere               viewsphere bench
    heapgrasp replay RUN_DIR                 robot replay
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from typing import Any

__all__ = ["OPTIONAL_MODULES", "build_parser", "install_hint", "main"]


def build_parser() -> argparse.ArgumentParser:
    """Builds the ``heapgrasp`` argument parser with all command groups (and the old
    spellings, :mod:`heapgrasp.cli.aliases`).

    Returns
    -------
    argparse.ArgumentParser
        The top-level parser.
    """
    from heapgrasp import __version__
    from heapgrasp.cli import aliases, critic, grasps, robot, run, seg, show, sim, views
    from heapgrasp.cli import bench as bench_cli
    from heapgrasp.cli import viewsphere as viewsphere_cli

    parser = argparse.ArgumentParser(
        prog="heapgrasp",
        description="HEAPGrasp: active-perception robotic grasping with a Rust core.",
    )
    parser.add_argument(
        "--version",
        action="version",
        version=f"%(prog)s {__version__}",
        help="print the version and exit",
    )
    commands = parser.add_subparsers(
        dest="command", metavar="COMMAND", title="commands", required=True
    )
    run.add_parser(commands)
    show.add_parser(commands)
    benches = bench_cli.add_parser(commands)
    sim.add_parser(commands)
    views.add_parser(commands)
    grasps.add_parser(commands)
    critic.add_parser(commands)
    seg.add_parser(commands)
    viewsphere_cli.add_parser(commands)
    robot.add_parser(commands)
    aliases.add_aliases(commands, {"bench": benches})
    _plain_help(parser)
    return parser


_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")
_LITERAL = re.compile(r"``([^`]+)``")


def plain(text: str) -> str:
    """Help text without the reStructuredText of the docstrings it comes from:
    ``:mod:`heapgrasp.run``` → ``heapgrasp.run`` (``~a.b`` → ``b``), double backticks →
    none."""

    def role(m: re.Match[str]) -> str:
        target = m.group(1)
        return target.rsplit(".", 1)[-1] if m.group(0).count("~") else target

    text = _LITERAL.sub(r"\1", _ROLE.sub(role, text))
    return text.replace("::\n", ":\n")  # a literal block's marker


class _PlainMixin(argparse.HelpFormatter):
    """Help as plain text (:func:`plain`); no "(default: None)" after a required option
    or one without a default."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return super()._fill_text(plain(text), width, indent)

    def _split_lines(self, text: str, width: int) -> list[str]:
        return super()._split_lines(plain(text), width)

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.required or action.default is None:
            return action.help
        return super()._get_help_string(action)


def _plain_help(parser: argparse.ArgumentParser) -> None:
    """Every parser under ``parser`` prints its help as plain text (:class:`_PlainMixin`
    over its own formatter: raw descriptions stay raw, shown defaults stay shown)."""
    own = parser.formatter_class
    if isinstance(own, type) and not issubclass(own, _PlainMixin):
        plain_class: Any = type(f"Plain{own.__name__}", (_PlainMixin, own), {})
        parser.formatter_class = plain_class
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                _plain_help(sub)


#: The optional modules a command may need, and the extra that installs each
#: (``pip install 'heapgrasp[EXTRA]'``); None: a benchmark's own baseline, by name.
OPTIONAL_MODULES: dict[str, str | None] = {
    "torch": "train",
    "onnx": "train",
    "onnxscript": "train",
    "safetensors": "train",
    "sklearn": "train",
    "segmentation_models_pytorch": "train",
    "cv2": "robot",
    "rtde_control": "robot",
    "rtde_receive": "robot",
    "pyrealsense2": "robot",
    "tomlkit": "robot",
    "rerun": "viz",
    "ray": "ray",
    "numba": None,
    "open3d": None,
}


def install_hint(exc: ImportError) -> str:
    """One line for a missing module: the error's own message where it already says how
    to install it, else the module and the extra (:data:`OPTIONAL_MODULES`) or package
    that brings it."""
    text = str(exc)
    if "pip install" in text:
        return text
    root = (exc.name or "").split(".")[0]
    if root in OPTIONAL_MODULES:
        extra = OPTIONAL_MODULES[root]
        how = f"pip install 'heapgrasp[{extra}]'" if extra else f"pip install {root}"
        return f"this command needs {root}, which is not installed: {how}"
    return f"{text}: reinstall heapgrasp (pip install .), which brings its dependencies"


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the ``heapgrasp`` command line.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status: 0 on success, 1 when a command fails while working (for
        benchmarks: a result check failed), 2 when it refuses its input (invalid
        arguments, settings or files: a ``ValueError`` naming them) or a missing optional
        dependency (one line naming the extra that installs it, :func:`install_hint`);
        ``--help`` and ``--version`` return 0.
    """
    try:
        status = _main(argv)
        sys.stdout.flush()  # a closed pipe shows here, not at the interpreter's exit
        return status
    except BrokenPipeError as exc:
        if not _stdout_broken():  # another pipe (a device, a worker): a real error
            print(f"heapgrasp: error: {exc}", file=sys.stderr)
            return 1
        _silence_stdout()  # `heapgrasp ... | head`: the reader has what it wanted
        return 0


def _stdout_broken() -> bool:
    """Whether stdout is a pipe whose reader has gone (poll reports an error on its write
    end); where that cannot be asked, a broken pipe is taken to be stdout's."""
    import select

    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(event & select.POLLERR for _, event in poller.poll(0))
    except (AttributeError, OSError, ValueError):
        return True


def _silence_stdout() -> None:
    """Points stdout at the null device, so that flushing it at exit after a closed pipe
    raises nothing more."""
    import os

    try:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


def _main(argv: Sequence[str] | None) -> int:
    from heapgrasp.loop.config import ConfigError

    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(args_list)
    except SystemExit as exc:  # --help, --version, or a usage error (already printed)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    args.argv = args_list
    try:
        status: int = args.func(args)
    except BrokenPipeError:  # not a command's error: main() ends quietly
        raise
    except KeyboardInterrupt:
        print("heapgrasp: interrupted", file=sys.stderr)
        return 130
    except ConfigError as exc:  # a configuration error exits 2 in every command
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    except ImportError as exc:  # a missing optional dependency: one line, exit 2
        print(f"heapgrasp: error: {install_hint(exc)}", file=sys.stderr)
        return 2
    except (ValueError, FileNotFoundError) as exc:  # a refused input, named: exit 2
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 2
    except (OSError, RuntimeError) as exc:  # a failure while working
        print(f"heapgrasp: error: {exc}", file=sys.stderr)
        return 1
    return status


if __name__ == "__main__":
    raise SystemExit(main())
