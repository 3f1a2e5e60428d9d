"""The error a bad weights file raises, and the archive check that raises it.

:class:`WeightsError` is raised wherever a weights file is read: the ONNX networks
(:mod:`heapgrasp.inference.network`), the grasp critic's arrays
(:mod:`heapgrasp.planning.critic`) and PyTorch checkpoints (:mod:`heapgrasp.training.weights`);
it lives in the lowest layer that reads weights, so that none needs the others (nor
PyTorch) to raise or catch it. Checkpoints and the critic's arrays are zip archives
(``torch.save``, ``numpy.savez``): :func:`check_archive` reads one whole before either
library parses it.
"""

from __future__ import annotations

import os
import zipfile
import zlib
from pathlib import Path

from heapgrasp._core import HeapgraspError

__all__ = ["WeightsError", "check_archive"]


class WeightsError(HeapgraspError):
    """A weights file (network or grasp critic) cannot be used: it is empty, truncated,
    garbled or of another format, or it loads but holds something wrong (a missing or
    misshapen array, a wrong dtype, NaN or infinity, a zero scale, bad metadata).

    A ``ValueError`` (through :class:`heapgrasp.HeapgraspError`). ``str()`` is the file's
    path, ``": "``, then the problem; :attr:`path` and :attr:`problem` hold the two.
    """

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        self.path = Path(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")

    def __reduce__(self) -> tuple[type[WeightsError], tuple[Path, str]]:
        # Picklable with its two arguments (worker processes send errors back).
        return (type(self), (self.path, self.problem))


def _detail(exc: BaseException) -> str:
    cls = type(exc)
    name = cls.__name__ if cls.__module__ == "builtins" else f"{cls.__module__}.{cls.__name__}"
    text = str(exc).splitlines()[0] if str(exc) else ""
    return f"{name}: {text}" if text else name


def check_archive(path: str | os.PathLike[str], what: str) -> None:
    """Checks that ``path`` (an existing path) is a whole zip archive: a regular, readable,
    non-empty file that ends in its central directory, every member of which reads back
    with its CRC-32 (``torch.load`` checks none; a garbled ``.npz`` fails later with
    zlib's "Error -3", naming no file). Raises :class:`WeightsError` naming ``path`` and
    the problem otherwise; ``what`` names the expected file in messages (e.g.
    ``"weights file"``)."""
    p = Path(path)
    if not p.is_file():
        raise WeightsError(p, f"not a file (expected a {what})")
    try:
        size = p.stat().st_size
        with p.open("rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        raise WeightsError(p, f"unreadable: {exc.strerror or _detail(exc)}") from exc
    if size == 0:
        raise WeightsError(p, f"empty file (0 bytes), not a {what}")
    try:
        archive = zipfile.ZipFile(p)
    except zipfile.BadZipFile as exc:
        if head == b"PK\x03\x04":
            problem = "it starts as a zip archive but its end is missing (truncated?)"
        else:
            problem = "not a zip archive"
        raise WeightsError(p, f"corrupt or truncated {what}: {problem}") from exc
    except (OSError, EOFError, ValueError) as exc:
        raise WeightsError(p, f"corrupt or truncated {what}: {_detail(exc)}") from exc
    with archive:
        for info in archive.infolist():
            try:
                with archive.open(info) as member:
                    while member.read(1 << 20):
                        pass
            except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as exc:
                raise WeightsError(
                    p, f"corrupt {what}: member {info.filename!r} is garbled ({_detail(exc)})"
                ) from exc
