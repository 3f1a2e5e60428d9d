"""``summary.md`` of a benchmark's folder: its table and its figures on one page, as
``heapgrasp run`` writes one for a run."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

__all__ = ["write_summary"]


def write_summary(out: Path, table: str, figures: Sequence[tuple[str, str]] = ()) -> Path:
    """Writes ``out/summary.md``: ``table`` (markdown, its own title first), then each
    figure of ``figures`` — ``(file name in out, caption)`` — that was written; returns
    the page."""
    lines = [table.rstrip(), ""]
    for name, caption in figures:
        if (out / name).is_file():
            lines += [f"![{caption}]({name})", ""]
    lines.append("Every number: `summary.json` and each run's `results.json`.")
    page = out / "summary.md"
    page.write_text("\n".join(lines) + "\n")
    return page
