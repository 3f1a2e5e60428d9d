"""heapgrasp bench noise (Table V) and bench clutter (Table IV): the noise-free reference
grid, the tables beside the paper's numbers, and bad arguments."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from heapgrasp.cli import main
from heapgrasp.perception.silhouette import grid_agreement


def test_grid_agreement_is_table_v_mse_and_iou() -> None:
    a = np.zeros((10, 10, 10), bool)
    b = np.zeros((10, 10, 10), bool)
    a[:2, :2, :2] = True  # 8 voxels
    b[1:3, :2, :2] = True  # 8 voxels, 4 shared
    got = grid_agreement(a, b)
    assert got["iou"] == pytest.approx(4 / 12)
    assert got["mse_percent"] == pytest.approx(100 * 8 / 1000)
    assert grid_agreement(a, a) == {"mse_percent": 0.0, "iou": 1.0}
    assert grid_agreement(np.zeros(3, bool), np.zeros(3, bool))["iou"] is None
    with pytest.raises(ValueError, match="shapes"):
        grid_agreement(a, b[:5])


def test_bench_noise_compares_with_the_noise_free_grid(tmp_path: Path) -> None:
    out = tmp_path / "noise"
    args = ["bench", "noise", "--scenes", "1", "--levels", "0.02,0.2", "--workers", "1"]
    args += ["--set", "objects=2", "--set", "layout=packed", "--set", "max_attempts=2"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    table = (out / "table.md").read_text()
    assert "| no-vp | 0.02 |" in table and "| no-vp | 0.2 |" in table
    summary = json.loads((out / "summary.json").read_text())
    low, high = summary["no-vp-0.02"]["reference_grid"], summary["no-vp-0.2"]["reference_grid"]
    # every phase compared, and more noise, a worse grid
    assert low["phases"] >= 1 and high["phases"] >= 1
    assert low["iou"]["mean"] > high["iou"]["mean"]
    assert low["mse_percent"]["mean"] < high["mse_percent"]["mean"]
    assert (out / "table5_noise.png").stat().st_size > 0
    page = (out / "summary.md").read_text()
    assert table.strip() in page and "](table5_noise.png)" in page
    # every phase of a noisy run carries its comparison
    records = [
        json.loads(s) for s in (out / "no-vp-0.02" / "scenes.jsonl").read_text().splitlines()
    ]
    assert all("reference_grid" in p for r in records for p in r["phases"])


def test_bench_clutter_puts_the_paper_beside_ours(tmp_path: Path) -> None:
    out = tmp_path / "clutter"
    args = ["bench", "clutter", "--scenes", "1", "--counts", "6", "--methods", "no-vp"]
    args += ["--set", "layout=packed", "--set", "max_attempts=1", "--workers", "1"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    table = (out / "table.md").read_text()
    assert "| 6 | no-vp (antipodal grasps, critic) |" in table
    assert "| 80 (4/5) | 2.15 ± 0.1 | 308 ± 27 | 9.99 ± 0.23 |" in table
    summary = json.loads((out / "summary.json").read_text())
    assert summary["no-vp-6"]["config"]["objects"] == 6
    assert summary["no-vp-6"]["reference_grid"] is None
    assert (out / "table4_clutter.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["noise", "--levels", "0.7"], "0.7"),
        (["noise", "--levels", "a"], "'a'"),
        (["noise", "--methods", "magic"], "magic"),
        (["clutter", "--counts", "0"], "'0'"),
        (["clutter", "--scenes", "0"], "0"),
        (["clutter", "--set", "lam=2"], "lam"),
    ],
)
def test_bad_arguments_are_refused_by_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], named: str
) -> None:
    try:  # argparse exits 2 on a bad flag; a bad setting is refused with status 2
        code = main(["bench", *args, "--out", str(tmp_path / "x")])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    assert named in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
