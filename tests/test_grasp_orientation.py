"""scripts/grasp_orientation.py: the angles it reports and its errors."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "grasp_orientation.py"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("grasp_orientation", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_approach_angles_are_signed_and_closing_angles_folded() -> None:
    s = _script()
    down = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    other = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(s._angles(down, other, folded=False), [0.0, 90.0, 180.0])
    # the finger swap turns the closing axis around: 180 degrees off is no error
    np.testing.assert_allclose(s._angles(down, other, folded=True), [0.0, 90.0, 0.0])
    stats = s._stats(np.array([10.0, 20.0, 40.0, 50.0]))
    assert stats["median"] == 30.0 and stats["over_30_deg"] == 0.5


def test_a_missing_network_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nope.onnx"
    assert _script().main([str(missing), str(tmp_path)]) == 2
    assert "nope.onnx" in capsys.readouterr().err
