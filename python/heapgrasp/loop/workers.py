"""Worker processes of the pools that run scenes, dataset shards and benchmark poses.

:func:`init_worker` is every pool's initializer: one core per worker (the pool provides
the parallelism) and a worker that dies with its parent. A parent killed outright
(``kill -9``, the out-of-memory killer) runs no clean-up of its own, and its pool's
workers would otherwise go on for ever, holding hundreds of megabytes each.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

__all__ = ["die_with_parent", "init_worker"]

#: ``prctl`` option: the signal the kernel sends this process when its parent dies.
_PR_SET_PDEATHSIG = 1


def die_with_parent(poll_s: float = 1.0) -> None:
    """Ends this process when its parent dies. On Linux the kernel sends it ``SIGKILL``
    (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread checks the parent every
    ``poll_s`` seconds. A parent already gone by the time this runs ends it at once: the
    parent is the process that started this one (``multiprocessing``'s record of it, for
    a pool's worker), not whoever adopted it after a kill — a worker still starting up
    when its parent was killed would otherwise take its adopter for its parent and live
    on."""
    import multiprocessing

    started_by = multiprocessing.parent_process()
    parent = started_by.pid if started_by is not None and started_by.pid else os.getppid()
    if os.getppid() != parent:  # already gone
        os._exit(1)
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0:
                if os.getppid() != parent:  # it died before the call took effect
                    os._exit(1)
                return
        except (OSError, AttributeError):
            pass  # no prctl here: watch instead

    def watch() -> None:
        while True:
            if os.getppid() != parent:
                os._exit(1)
            time.sleep(poll_s)

    threading.Thread(target=watch, name="heapgrasp-parent-watch", daemon=True).start()


def init_worker(threads: int = 1) -> None:
    """A pool worker's set-up: ``threads`` cores for the Rust core (and PyTorch where it
    is imported), and :func:`die_with_parent`."""
    os.environ["HEAPGRASP_NUM_THREADS"] = str(threads)
    die_with_parent()
