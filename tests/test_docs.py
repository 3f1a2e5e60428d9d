"""The documentation that states facts about the code states them correctly."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from heapgrasp.loop.config import RunConfig

DOCS = Path(__file__).resolve().parent.parent / "docs"


def _settings_rows() -> list[list[str]]:
    text = (DOCS / "running.md").read_text()
    assert "\n## Settings\n" in text, "docs/running.md needs a '## Settings' section"
    section = text.split("\n## Settings\n", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        if line.startswith("| `"):
            rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
    return rows


def _default(cell: str) -> object:
    text = cell.strip("`")
    if "π" in text:  # e.g. π/5
        num, _, den = text.partition("/")
        factor = 1.0 if num == "π" else float(num.replace("π", ""))
        return factor * math.pi / (float(den) if den else 1.0)
    return json.loads(text)


def test_every_setting_is_in_the_one_documented_table_with_its_default_and_source() -> None:
    rows = _settings_rows()
    names = [row[0].strip("`") for row in rows]
    assert len(names) == len(set(names)), "a setting listed twice"
    assert sorted(names) == sorted(RunConfig.field_names())
    defaults = RunConfig()
    for name, default, group, source, *_ in rows:
        key = name.strip("`")
        want = getattr(defaults, key)
        got = _default(default)
        if isinstance(want, float):
            assert isinstance(got, int | float) and math.isclose(got, want), (key, default)
        else:
            assert got == want, (key, default)
        assert key in RunConfig.field_names(group), (key, group)
        assert source == RunConfig.source(key), (key, source)


def test_the_readme_example_runs(capsys: pytest.CaptureFixture[str]) -> None:
    readme = (DOCS.parent / "README.md").read_text()
    code = readme.split("```python\n", 1)[1].split("```", 1)[0]
    exec(compile(code, "README.md", "exec"), {})  # our own README
    assert "voxels in the hull" in capsys.readouterr().out
