"""A pool's workers die with their parent: killed outright (kill -9), a run leaves no
worker running."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def _children(pid: int) -> list[int]:
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        text = (task / "children").read_text() if (task / "children").exists() else ""
        found += [int(x) for x in text.split()]
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split()[2]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state != "Z"


def test_pool_workers_die_with_a_killed_parent(tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("heapgrasp")
    argv = [str(exe), "views", "data", str(tmp_path / "d"), "--scenes", "40"]
    parent = subprocess.Popen(
        [*argv, "--shard-size", "1", "--workers", "2", "--quiet"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=os.environ,
    )
    try:
        workers: list[int] = []
        deadline = time.monotonic() + 120
        while len(workers) < 2 and time.monotonic() < deadline:
            time.sleep(0.5)
            workers = [c for c in _children(parent.pid) if _alive(c)]
        assert len(workers) >= 2, "the pool's workers did not start"
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=30)
        deadline = time.monotonic() + 20
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not [w for w in workers if _alive(w)], "workers outlived their parent"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait(timeout=30)


#: A parent that starts one worker, which is still starting (asleep) when the parent
#: exits; the worker then sets itself up and would sleep for a minute more.
_LATE_WORKER = """
import multiprocessing, os, sys, time

def worker(path):
    time.sleep(1.5)  # still starting up when its parent is gone
    from heapgrasp.loop.workers import die_with_parent
    die_with_parent()
    with open(path, "w") as f:
        f.write(str(os.getpid()))
    time.sleep(60)

if __name__ == "__main__":
    ctx = multiprocessing.get_context(sys.argv[2])
    p = ctx.Process(target=worker, args=(sys.argv[1],))
    p.start()
    with open(sys.argv[1] + ".child", "w") as f:
        f.write(str(p.pid))
    os._exit(0)  # the parent gone without a word, as after kill -9
"""


def test_a_worker_still_starting_when_its_parent_died_ends_too(tmp_path: Path) -> None:
    # the worker took its adopter for its parent: it lived on for ever
    script = tmp_path / "late.py"
    script.write_text(_LATE_WORKER)
    for method in ("fork", "spawn"):
        marker = tmp_path / f"{method}.pid"
        subprocess.run([sys.executable, str(script), str(marker), method], check=True, timeout=60)
        child = int(Path(str(marker) + ".child").read_text())
        deadline = time.monotonic() + 30
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.2)
        alive = _alive(child)
        if alive:
            os.kill(child, signal.SIGKILL)
        assert not alive, f"{method}: the worker outlived its parent"
        assert not marker.exists()  # it ended before doing any work
