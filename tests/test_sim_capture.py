"""``heapgrasp sim capture``: files, keys, and mask/mesh/pose consistency from them alone."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from heapgrasp.cli import main
from heapgrasp.sim.mesh_files import load_mesh


def test_capture_writes_consistent_frames(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("HEAPGRASP_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "cap"
    argv = ["sim", "capture", "--layout", "pile", "--category", "mixed", "--objects", "4"]
    argv += ["--seed", "3", "--views", "4", "--out", str(out)]
    assert main(argv) == 0
    frames = np.load(out / "frames.npz")
    scene = json.loads((out / "scene.json").read_text())
    n = 4
    w, h, fx, fy, cx, cy = frames["intrinsics"]
    assert frames["rgb"].shape == (n, int(h), int(w), 3) and frames["rgb"].dtype == np.uint8
    assert frames["depth"].shape == (n, int(h), int(w)) and frames["depth"].dtype == np.float32
    assert frames["masks"].dtype == np.bool_ and frames["cam2world"].shape == (n, 4, 4)
    assert {o["category"] for o in scene["objects"]} <= {"transparent", "specular", "opaque"}
    for k in range(n):
        mask = frames["masks"][k]
        near = mask.copy()
        for du in (-1, 0, 1):
            for dv in (-1, 0, 1):
                near |= np.roll(np.roll(mask, du, 1), dv, 0)
        world2cam = np.linalg.inv(frames["cam2world"][k])
        for obj in scene["objects"]:
            v, _ = load_mesh(Path(obj["mesh"]))
            p = world2cam @ np.asarray(obj["obj2world"]) @ np.c_[v, np.ones(len(v))].T
            x, y, z = p[:3]
            u = np.floor(fx * x / z + cx + 0.5).astype(int)
            vv = np.floor(fy * y / z + cy + 0.5).astype(int)
            inside = (z > 0) & (u >= 0) & (u < w) & (vv >= 0) & (vv < h)
            # Every vertex of a visible object lands on (or, on the contour, next to) a
            # set mask pixel.
            assert near[vv[inside], u[inside]].all(), (k, obj["name"])
        np.testing.assert_array_equal(frames["labels"][k] > 0, mask)
    # Same seed -> same files.
    out2 = tmp_path / "cap2"
    assert main([*argv[:-1], str(out2)]) == 0
    again = np.load(out2 / "frames.npz")
    for key in ("depth", "masks", "labels", "cam2world"):
        np.testing.assert_array_equal(frames[key], again[key])


def test_capture_rejects_bad_arguments(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "capture", "--objects", "0", "--out", str(tmp_path)]) == 2
    assert "--objects" in capsys.readouterr().err
    assert main(["sim", "capture", "--layout", "heap", "--out", str(tmp_path)]) == 2
    assert "--layout" in capsys.readouterr().err
