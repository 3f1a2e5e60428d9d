"""What the network training commands share (``views train``, ``grasps train``): the
check that PyTorch is there, the thread count, the command line for the model card, and
the options ``--device``, ``--resume``, ``--seed``, ``--workers``, ``--no-progress``.
"""

from __future__ import annotations

import argparse
import importlib
import shlex
import sys

from heapgrasp.cli.argtypes import int_at_least

__all__ = [
    "add_cpu_options",
    "add_run_options",
    "command_line",
    "config_error",
    "require_training",
    "threads",
]


def config_error(message: str) -> Exception:
    """heapgrasp's configuration error (exit status 2, no traceback)."""
    from heapgrasp.loop.config import ConfigError

    return ConfigError(message)


def require_training(command: str) -> None:
    """A ConfigError naming what to install when PyTorch or safetensors is missing
    (``command``: e.g. ``"views train"``)."""
    from heapgrasp.training import require_torch

    try:
        require_torch()
        importlib.import_module("safetensors")
    except ImportError as exc:
        missing = (exc.name or "PyTorch").split(".")[0]
        if missing.startswith("heapgrasp"):
            missing = "torch"
        raise config_error(
            f"heapgrasp {command} needs PyTorch and safetensors ({missing} is not "
            "installed): pip install 'heapgrasp[train]'"
        ) from None


def threads(args: argparse.Namespace) -> int:
    """``--workers`` as PyTorch's thread count (where given); the shard readers' count."""
    import torch

    if args.workers is not None:
        torch.set_num_threads(args.workers)
    return int(args.workers or 1)


def command_line(args: argparse.Namespace) -> str:
    """The command line that trained the network, for its model card."""
    return "heapgrasp " + shlex.join(getattr(args, "argv", sys.argv[1:]))


def add_run_options(p: argparse.ArgumentParser, *, seed_help: str) -> None:
    """``--device``, ``--resume`` and ``--seed`` (what it draws: ``seed_help``)."""
    p.add_argument(
        "--device",
        default="cpu",
        help="cpu, cuda, cuda:N or auto (cuda where present) (default cpu)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue OUT's checkpoint (same data and settings; else exit 2)",
    )
    p.add_argument("--seed", type=int_at_least(0), default=0, help=seed_help)


def add_cpu_options(p: argparse.ArgumentParser, workers_note: str) -> None:
    """``--workers`` (its default's help followed by ``workers_note``) and
    ``--no-progress``."""
    p.add_argument(
        "--workers",
        type=int_at_least(1),
        default=None,
        help=f"CPU threads of PyTorch and of reading the shards (default: PyTorch's{workers_note})",
    )
    p.add_argument(
        "--no-progress", action="store_true", help="no progress bar (one line per epoch)"
    )
