"""The view network's dataset (Algorithm 1, :mod:`heapgrasp.data.views`)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pybullet")

from heapgrasp.cli import main
from heapgrasp.data import views
from heapgrasp.data.views import (
    ShardFailure,
    ViewDataConfig,
    generate,
    object_split,
    read_manifest,
    shard_path,
)

SMALL = {"scenes": 3, "shard_size": 2, "max_objects": 2}


def _load(path: Path) -> dict[str, Any]:
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def test_samples_are_algorithm_1(tmp_path: Path) -> None:
    config = ViewDataConfig(**SMALL, region_fraction=1.0)  # type: ignore[arg-type]
    manifest = generate(config, tmp_path, progress=False)
    assert manifest["complete"] and manifest["samples"] + manifest["dropped"] == 3
    assert set(manifest["shards"]) == {"shard-00000.npz", "shard-00001.npz"}
    data = [_load(shard_path(tmp_path, s)) for s in range(2)]
    assert [int(d["scenes"]) for d in data] == [2, 1]
    for d in data:
        n = len(d["k"])
        assert d["segmented"].shape == d["visible"].shape == (n, 40, 40, 40)
        assert d["segmented"].dtype == np.uint16 and (d["segmented"] <= d["visible"]).all()
        assert d["scores"].shape == (n, 40, 20) and d["scores"].dtype == np.float32
        # eq. 14 is at most 1; below 0 where a view would see voxels no frame saw yet
        # inside objects (they become high-confidence): the label keeps that
        assert (d["scores"] <= 1).all() and (d["scores"].max(axis=(1, 2)) != 0).all()
        assert ((0 <= d["k"]) & (d["k"] <= 2)).all()
        for i in range(n):
            has_target = not np.isnan(d["target"][i]).all()
            # region_fraction = 1: every sample past p0 is counted on its target's column
            assert has_target == (d["k"][i] >= 1)
            if has_target:
                region = d["region"][i]
                assert 0 < region.sum() < region.size
                # the target's column is inside its region
                a, b = (d["target"][i][:2, 3] / 0.3 * 40).astype(int)  # the cube spans [0, 0.3]
                assert region[a, b]
            else:
                assert d["region"][i].all()
            if d["k"][i] == 0:  # one frame, at p0
                assert d["visible"][i].max() == 1


def test_a_shard_run_again_is_identical_and_resume_skips(tmp_path: Path) -> None:
    config = ViewDataConfig(**SMALL)  # type: ignore[arg-type]
    generate(config, tmp_path / "a", progress=False)
    first = _load(shard_path(tmp_path / "a", 1))
    os.remove(shard_path(tmp_path / "a", 1))
    before = shard_path(tmp_path / "a", 0).stat().st_mtime_ns
    manifest = generate(config, tmp_path / "a", progress=False)
    assert shard_path(tmp_path / "a", 0).stat().st_mtime_ns == before  # kept, not redone
    again = _load(shard_path(tmp_path / "a", 1))
    assert first.keys() == again.keys()
    for key in first:
        np.testing.assert_array_equal(first[key], again[key])
    assert manifest["complete"]
    # more scenes add shards; other settings are refused
    bigger = ViewDataConfig(**{**SMALL, "scenes": 4})  # type: ignore[arg-type]
    generate(bigger, tmp_path / "a", progress=False)
    assert read_manifest(tmp_path / "a")["config"]["scenes"] == 4
    with pytest.raises(ValueError, match="max_objects: 2 there, 3 asked"):
        generate(ViewDataConfig(**{**SMALL, "max_objects": 3}), tmp_path / "a", progress=False)  # type: ignore[arg-type]


def _crash_on_shard_1(config: ViewDataConfig, shard: int) -> dict[str, Any]:
    if shard == 1:
        os._exit(3)  # a native crash of the worker, as a segfault would
    raise RuntimeError("boom")


def test_failures_are_reported_with_their_shard_and_lose_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = ViewDataConfig(scenes=6, shard_size=2, max_objects=1)
    generate(config, tmp_path, progress=False, workers=1)  # every shard written
    os.remove(shard_path(tmp_path, 1))
    os.remove(shard_path(tmp_path, 2))
    kept = shard_path(tmp_path, 0).read_bytes()
    monkeypatch.setattr(views, "shard_samples", _crash_on_shard_1)
    with pytest.raises(ShardFailure) as err:
        generate(config, tmp_path, progress=False, workers=2)
    assert set(err.value.failures) == {1, 2}
    assert "died" in err.value.failures[1] and "boom" in err.value.failures[2]
    assert shard_path(tmp_path, 0).read_bytes() == kept
    assert not shard_path(tmp_path, 1).exists() and not list(tmp_path.glob(".*tmp*"))
    assert not read_manifest(tmp_path)["complete"]


def test_splits_are_disjoint_and_test_is_the_benchmarks() -> None:
    names = [f"procedural/box_{i:02d}" for i in range(200)]
    splits = [object_split(n, "train") for n in names]
    assert {"train", "val"} == set(splits) and 0.1 < splits.count("val") / 200 < 0.3
    assert all(object_split(n, "test") == "test" for n in names)


def test_bad_settings_are_named() -> None:
    with pytest.raises(ValueError, match="split must be one of"):
        ViewDataConfig(split="holdout")
    with pytest.raises(ValueError, match="scenes must be an integer >= 1, got 0"):
        ViewDataConfig(scenes=0)
    with pytest.raises(ValueError, match="region_fraction"):
        ViewDataConfig(region_fraction=1.5)


def test_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "d"
    assert main(["views", "data", str(out), "--scenes", "1", "--workers", "1", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["samples"] + summary["dropped"] == 1 and summary["complete"]
    assert main(["views", "data", str(out), "--scenes", "0"]) == 2
    assert "--scenes" in capsys.readouterr().err
    # --ray without Ray: a clear message, not a traceback
    import builtins

    real_import = builtins.__import__

    def no_ray(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "ray":
            raise ImportError("No module named 'ray'")
        return real_import(name, *args, **kwargs)

    builtins.__import__ = no_ray
    try:
        assert main(["views", "data", str(out), "--scenes", "2", "--ray", "--quiet"]) == 2
    finally:
        builtins.__import__ = real_import
    assert "pip install 'heapgrasp[ray]'" in capsys.readouterr().err
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "shard-00000.npz").write_bytes(b"x")
    assert main(["views", "data", str(tmp_path / "junk"), "--scenes", "1", "--quiet"]) == 2
    assert "without a manifest" in capsys.readouterr().err
