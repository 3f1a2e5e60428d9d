"""The command line for a newcomer: a command that needs an optional dependency which is
not installed ends with one line naming the extra that brings it, and exit status 2 —
never a traceback; help reads as plain text."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest
from heapgrasp.cli import OPTIONAL_MODULES, build_parser, install_hint, main, plain


@pytest.mark.parametrize(
    ("missing", "argv", "extra"),
    [
        ("torch", ["bench", "seg", "--size", "64x64", "--repeats", "1"], "train"),
        ("cv2", ["robot", "board", "{tmp}/board.png"], "robot"),
        ("cv2", ["robot", "calibrate", "--synthetic", "--out", "{tmp}/cal"], "robot"),
        ("torch", ["grasps", "train", "{tmp}", "--out", "{tmp}/net"], "train"),
    ],
)
def test_a_missing_extra_is_one_line_and_exit_2(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    missing: str,
    argv: list[str],
    extra: str,
) -> None:
    monkeypatch.setitem(sys.modules, missing, None)  # `import missing` raises ImportError
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err
    assert code == 2
    assert f"pip install 'heapgrasp[{extra}]'" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert err.count("pip install") == 1  # the hint once
    assert not list(tmp_path.iterdir())  # nothing written


def test_install_hint_names_the_extra_or_keeps_the_message() -> None:
    err = ModuleNotFoundError("No module named 'rerun'", name="rerun")
    assert install_hint(err).endswith("pip install 'heapgrasp[viz]'")
    own = ImportError("training needs PyTorch: pip install 'heapgrasp[train]'")
    assert install_hint(own) == str(own)
    other = ModuleNotFoundError("No module named 'networkx'", name="networkx")
    assert "reinstall heapgrasp" in install_hint(other)
    assert OPTIONAL_MODULES["cv2"] == "robot" and OPTIONAL_MODULES["torch"] == "train"


def _helps(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> dict[str, str]:
    out = {" ".join(path): parser.format_help()}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out.update(_helps(sub, (*path, name)))
    return out


def test_every_help_is_plain_text() -> None:
    assert plain("see :mod:`heapgrasp.run` and :func:`~heapgrasp.sim.leftovers.describe`") == (
        "see heapgrasp.run and describe"
    )
    assert plain("``--scenes`` scenes::\n") == "--scenes scenes:\n"
    helps = _helps(build_parser())
    assert len(helps) > 30
    for command, text in helps.items():
        assert "``" not in text and ":mod:`" not in text and ":func:`" not in text, command
        assert "(default: None)" not in text, command
    # each dataset's help describes that dataset (and the shared resume rules) alone
    views = helps["views data"]
    assert "Algorithm 1" in views and "Poisson(4)" not in views and "2000" not in views
    assert "finished shards are kept" in views
    assert helps["data views"].count("Algorithm 1") == views.count("Algorithm 1")  # old spelling
    assert "(default: 5)" in helps["sim capture"]  # shown defaults stay shown


def test_output_into_a_closed_pipe_ends_quietly() -> None:
    # `heapgrasp run --print-config | head -0`: the reader is gone before the first line
    exe = Path(sys.executable).with_name("heapgrasp")
    proc = subprocess.Popen(
        [str(exe), "run", "--print-config"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=os.environ,
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()
    with proc.stderr:
        err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0
    assert "BrokenPipe" not in err and "Traceback" not in err


def test_no_command_opens_with_pybullet_s_build_line(tmp_path: Path) -> None:
    exe = Path(sys.executable).with_name("heapgrasp")
    argv = [str(exe), "run", "--method", "no-vp", "--objects", "1", "--layout", "packed"]
    argv += ["--set", "max_attempts=1", "--quiet", "--out", str(tmp_path / "r")]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    assert "pybullet build time" not in done.stderr + done.stdout


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--dpi", "1000000"], "must be in [72, 2400], got 1000000"),  # OpenCV ran out of memory
        (["b.xyz"], "'b.xyz': the board is written as .png"),  # "could not find a writer"
    ],
)
def test_robot_board_refuses_what_it_cannot_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], named: str
) -> None:
    args = [a if a.startswith("-") or a.isdigit() else str(tmp_path / a) for a in argv]
    assert main(["robot", "board", *args]) == 2
    assert named.replace("'b.xyz'", repr(str(tmp_path / "b.xyz"))) in capsys.readouterr().err
    assert not list(tmp_path.iterdir())
