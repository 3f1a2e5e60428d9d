"""PyBullet, imported once for the whole package without the build-time line
("pybullet build time: ...") its C module writes to stderr on import, which would
otherwise open the output of almost every command. Every module of :mod:`heapgrasp.sim`
takes ``pb`` from here."""

from __future__ import annotations

import os
import sys
from types import ModuleType
from typing import Any, cast

__all__ = ["pb"]


def _quiet_import() -> ModuleType:
    """``import pybullet`` with file descriptor 2 pointed at the null device meanwhile; an
    error raised by the import reaches the caller as usual."""
    if "pybullet" in sys.modules:
        import pybullet

        return cast(ModuleType, pybullet)
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (embedded, captured)
        import pybullet

        return cast(ModuleType, pybullet)
    sys.stderr.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
            import pybullet
    finally:
        os.dup2(saved, fd)
        os.close(saved)
    return cast(ModuleType, pybullet)


pb: Any = _quiet_import()
