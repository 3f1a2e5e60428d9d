"""The command line's one grammar (noun then verb, issue 55): every command is listed in
:mod:`heapgrasp.cli`'s docstring, and every old spelling still parses to its new
spelling's command, with the same options, printing one deprecation line first."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import heapgrasp.cli
import pytest
from heapgrasp.cli import build_parser, main
from heapgrasp.cli.aliases import ALIASES, Deprecated, notice


def _leaves(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> set[str]:
    """Every leaf command of ``parser``, as its words (``"grasps data"``)."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return {" ".join(path)}
    out: set[str] = set()
    for action in subs:
        for name, sub in action.choices.items():
            out |= _leaves(sub, (*path, name))
    return out


def _documented() -> set[str]:
    """The commands the docstring's literal blocks list: ``heapgrasp NOUN VERB|VERB``."""
    doc = heapgrasp.cli.__doc__ or ""
    out: set[str] = set()
    for line in doc.splitlines():
        m = re.match(r"\s+heapgrasp ([a-z][a-z-]*)(?: ([a-z][a-z|-]*))?(?:\s|$)", line)
        if m is None:
            continue
        noun, verbs = m.groups()
        out |= {f"{noun} {v}" for v in verbs.split("|")} if verbs else {noun}
    return out


def test_every_command_is_in_the_cli_docstring() -> None:
    leaves = _leaves(build_parser())
    documented = _documented()
    assert len(leaves) > 40
    assert not leaves - documented, f"missing from heapgrasp.cli's docstring: {leaves - documented}"
    assert not documented - leaves, f"documented but not commands: {documented - leaves}"


def test_the_grammar_is_noun_then_verb() -> None:
    leaves = _leaves(build_parser())
    for noun, verbs in {
        "views": ("data", "train"),
        "grasps": ("data", "loop-data", "train"),
        "critic": ("data", "train", "eval", "convert"),
        "seg": ("data", "train", "eval", "predict", "coco"),
        "viewsphere": ("bench", "data", "train"),
        "robot": ("init", "check", "board", "calibrate", "run", "replay"),
    }.items():
        assert {f"{noun} {v}" for v in verbs} <= leaves, noun
    old = {old for old, _, _ in ALIASES}
    data_train = {c for c in leaves if c.split()[0] in ("data", "train")}
    assert data_train == {c for c in old if c.split()[0] in ("data", "train")}


#: Each old spelling with arguments it parses, and the same command's new spelling.
OLD_AND_NEW = [
    (["data", "views", "OUT", "--scenes", "3"], ["views", "data", "OUT", "--scenes", "3"]),
    (["data", "grasps", "OUT", "--input", "tsdf"], ["grasps", "data", "OUT", "--input", "tsdf"]),
    (
        ["data", "loop-grasps", "OUT", "--top", "2"],
        ["grasps", "loop-data", "OUT", "--top", "2"],
    ),
    (["data", "seg", "OUT", "--size", "64x48"], ["seg", "data", "OUT", "--size", "64x48"]),
    (
        ["data", "viewsphere-paths", "OUT", "--tries", "2"],
        ["viewsphere", "data", "OUT", "--tries", "2"],
    ),
    (
        ["train", "views", "D", "--val", "V", "--out", "O", "--epochs", "2"],
        ["views", "train", "D", "--val", "V", "--out", "O", "--epochs", "2"],
    ),
    (
        ["train", "grasps", "D", "--out", "O", "--channels", "4", "8", "16"],
        ["grasps", "train", "D", "--out", "O", "--channels", "4", "8", "16"],
    ),
    (
        ["train", "viewsphere-policy", "--kind", "dqn", "--out", "O"],
        ["viewsphere", "train", "--kind", "dqn", "--out", "O"],
    ),
    (["bench", "viewsphere", "--poses", "2"], ["viewsphere", "bench", "--poses", "2"]),
    (["replay", "RUN", "--set", "lam=0.7"], ["robot", "replay", "RUN", "--set", "lam=0.7"]),
]


def test_every_old_spelling_is_tested() -> None:
    tested = {" ".join(old[:n]) for old, _ in OLD_AND_NEW for n in (1, 2)}
    assert {old for old, _, _ in ALIASES} <= tested


@pytest.mark.parametrize(("old", "new"), OLD_AND_NEW, ids=lambda argv: " ".join(argv[:2]))
def test_an_old_spelling_parses_to_the_new_command_and_says_so(
    old: list[str],
    new: list[str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    parser = build_parser()
    was, now = parser.parse_args(old), parser.parse_args(new)
    assert isinstance(was.func, Deprecated) and not isinstance(now.func, Deprecated)
    assert was.func.func is now.func  # the same command

    def options(args: argparse.Namespace) -> dict[str, object]:
        return {k: v for k, v in vars(args).items() if k != "func" and k != "command"}

    def without_groups(d: dict[str, object]) -> dict[str, object]:
        return {k: v for k, v in d.items() if not k.endswith("_command") and k != "benchmark"}

    assert without_groups(options(was)) == without_groups(options(now))  # the same options
    spelled = (was.func.old, was.func.new)
    assert " ".join(old).startswith(spelled[0]) and " ".join(new).startswith(spelled[1])
    # under the old spelling, the command runs after exactly one line on stderr
    ran: list[argparse.Namespace] = []
    monkeypatch.setattr(was.func, "func", lambda args: ran.append(args) or 0)
    assert was.func(was) == 0 and ran == [was]
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == notice(*spelled) + "\n"
    assert captured.err.count("\n") == 1
    assert "is now" in captured.err and "the old spelling goes in the next release" in captured.err


def test_an_old_spelling_runs_the_command_end_to_end(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "missing"
    argv = ["--kind", "pca-lr", "--data", str(missing), "--val", str(missing)]
    argv += ["--out", str(tmp_path / "o")]
    assert main(["train", "viewsphere-policy", *argv]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (
        "heapgrasp: 'train viewsphere-policy' is now 'viewsphere train'; the old spelling "
        "goes in the next release"
    )
    assert len(err) == 2 and err[1].startswith("heapgrasp: error: ")
    assert main(["viewsphere", "train", *argv]) == 2  # the new spelling: the same error alone
    assert capsys.readouterr().err.splitlines() == err[1:]
    assert not (tmp_path / "o").exists()


def test_the_old_groups_say_they_are_deprecated() -> None:
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {a.dest: a.help or "" for a in commands._choices_actions}
    for group in ("data", "train", "replay"):
        assert helps[group].startswith("deprecated"), group
    for old, new, _ in ALIASES:
        words = old.split()
        sub = commands.choices[words[0]]
        if len(words) > 1:
            action = next(a for a in sub._actions if isinstance(a, argparse._SubParsersAction))
            listed = {a.dest: a.help or "" for a in action._choices_actions}
            assert listed[words[1]] == f"deprecated: now '{new}'"
            sub = action.choices[words[1]]
        assert (sub.description or "").startswith(f"Deprecated: '{old}' is now '{new}'")
