"""Hostile input, every setting: each key of a run's settings and of ``robot.toml`` given
values of the wrong type, not finite, or beyond what the method or the hardware can do,
is refused with an error that names the key — from the library, and for a run from the
command line with exit status 2 and nothing written (issue 56's hostile-input suite)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import pytest
from heapgrasp.cli import main
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.robot.config import RobotConfig
from heapgrasp.robot.errors import RobotConfigError

#: Values no setting takes: a table, a list.
ANY_BAD: tuple[Any, ...] = ({"a": 1}, [1, 2])
#: Settings any non-negative integer is right for (a seed is any integer).
UNBOUNDED = {"seed"}


def _bad_values(default: Any, name: str) -> list[Any]:
    values = list(ANY_BAD)
    if isinstance(default, bool):
        values += ["yes", 2]
    elif isinstance(default, int):
        values += ["x", 1.5, -(10**12), True]
        if name not in UNBOUNDED:
            values.append(10**12)
    elif isinstance(default, float):
        values += ["x", math.nan, math.inf, -1e300, 1e300, True]
    elif isinstance(default, str):
        values += [3, True]
    elif default is None:
        values += [True]
    return values


RUN_CASES = [
    (f.name, value)
    for f in dataclasses.fields(RunConfig)
    for value in _bad_values(getattr(RunConfig(), f.name), f.name)
]


def _id(value: Any) -> str:
    return repr(value)[:20]


@pytest.mark.parametrize(("key", "value"), RUN_CASES, ids=[f"{k}={_id(v)}" for k, v in RUN_CASES])
def test_every_run_setting_refuses_nonsense_by_name(key: str, value: Any) -> None:
    with pytest.raises(ConfigError, match=key):
        RunConfig.from_mapping({key: value})


#: One bad value per setting through the command line (JSON as --set parses it).
CLI_CASES = [
    (f.name, values[-1])
    for f in dataclasses.fields(RunConfig)
    if (values := [v for v in _bad_values(getattr(RunConfig(), f.name), f.name) if v == v])
]


@pytest.mark.parametrize(("key", "value"), CLI_CASES, ids=[k for k, _ in CLI_CASES])
def test_a_run_given_nonsense_exits_2_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], key: str, value: Any
) -> None:
    out = tmp_path / "run"
    text = json.dumps(value) if not isinstance(value, str) else value
    assert main(["run", "--set", f"{key}={text}", "--out", str(out), "--quiet"]) == 2
    assert key in capsys.readouterr().err
    assert not out.exists()


def _robot_cases() -> list[tuple[str, str, Any]]:
    base = RobotConfig()
    cases: list[tuple[str, str, Any]] = []
    for table in dataclasses.fields(RobotConfig):
        section = getattr(base, table.name)
        if not dataclasses.is_dataclass(section):
            continue
        for f in dataclasses.fields(section):
            default = getattr(section, f.name)
            if f.name == "report":  # the calibration's own record, kept as written
                continue
            if isinstance(default, tuple):
                n = max(1, len(default))
                values: list[Any] = [{"a": 1}, "x", [math.nan] * n, [1e300] * n]
            else:
                values = _bad_values(default, f.name)
            cases += [(table.name, f.name, v) for v in values]
    return cases


ROBOT_CASES = _robot_cases()


@pytest.mark.parametrize(
    ("table", "key", "value"),
    ROBOT_CASES,
    ids=[f"{t}.{k}={_id(v)}" for t, k, v in ROBOT_CASES],
)
def test_every_robot_key_refuses_nonsense_naming_the_table(
    table: str, key: str, value: Any
) -> None:
    with pytest.raises(RobotConfigError, match=rf"\[{table}\]") as err:
        RobotConfig.from_mapping({table: {key: value}}, source="robot.toml")
    assert "robot.toml" in str(err.value)
    # the key, or for the camera's mode both of its keys
    assert key in str(err.value) or "width x height" in str(err.value)


def test_the_suite_is_the_size_issue_56_asks_for() -> None:
    assert len(RUN_CASES) + len(CLI_CASES) + len(ROBOT_CASES) >= 200
