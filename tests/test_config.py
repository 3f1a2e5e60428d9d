"""RunConfig: Table I defaults, TOML files, CLI precedence, clear errors."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from heapgrasp.cli import build_parser, main
from heapgrasp.cli.run import config_from_args
from heapgrasp.loop.config import (
    GROUPS,
    PAPER_EXTENSIONS,
    ConfigError,
    ConfigFile,
    RunConfig,
    presets,
)


def test_defaults_are_table_one() -> None:
    c = RunConfig()
    assert (c.cube_size, c.resolution, c.radius, c.theta_max) == (0.30, 40, 0.33, math.pi / 5)
    assert (c.U, c.V, c.L, c.lam, c.gamma1) == (40, 20, 3, 0.9, 0.2)
    assert c.epsilon is None and c.sigma is None  # the grasp planner's own (0.8 for VGN)
    assert (c.gamma2_first, c.gamma2, c.objects) == (0.0, 0.35, 5)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"method": "magic"}, "method: must be one of"),
        ({"lam": 1.5}, r"lam: must be in \[0.0, 1.0\]; got 1.5"),
        ({"L": 0}, "L: must be an integer >= 1; got 0"),
        ({"objects": 2.5}, "objects must be of type int"),
        ({"radius": -0.3}, "radius: must be > 0"),
        ({"start": "below"}, "start: must be one of side, above; got 'below'"),
        ({"grasp_planner": "vgn"}, "grasp_planner: must be one of auto, antipodal, network"),
        ({"noise": 0.7}, "noise: must be in"),
        ({"epsilon": float("nan")}, "epsilon"),
        ({"roof_radius": float("inf")}, "roof_radius: must be in"),
        ({"target_radius": -0.05}, r"target_radius: must be in \[0.0, 1.0\]; got -0.05"),
        ({"scene_memory": 1}, "scene_memory must be of type bool"),
        ({"stop_below": -0.1}, r"stop_below: must be in \[0.0, 1.0\]; got -0.1"),
        ({"stop_confidence": 2.0}, r"stop_confidence: must be in \[0.0, 1.0\]; got 2.0"),
        ({"stop_detour_weight": -1.0}, r"stop_detour_weight: must be in \[0.0, 100.0\]"),
        ({"move_weight": float("nan")}, r"move_weight: must be in \[0.0, 100.0\]"),
        # retired experiments are unknown settings now (docs/experiments.md)
        ({"confirm_below": 0.5}, "unknown parameter 'confirm_below'"),
        ({"final_grasp": "best"}, "unknown parameter 'final_grasp'"),
        ({"net_device": "gpu"}, "net_device: must be cpu, cuda, cuda:N or auto; got 'gpu'"),
        ({"net_device": "cuda:x"}, "net_device: must be cpu, cuda, cuda:N or auto"),
        ({"lamda": 0.9}, "unknown parameter 'lamda'"),
        ({"Theta-Max": 0.5}, "did you mean 'theta_max'"),
        # bounded by what a run can do: L = 10⁸ was accepted and ran for ever
        ({"L": 100_000_000}, "L: must be <= 50; got 100000000"),
        ({"U": 10_000}, "U: must be <= 360"),
        ({"max_attempts": 10**9}, "max_attempts: must be <= 1000"),
        ({"nms_window": 41}, "nms_window: must be <= 40"),
        ({"fps": 1e9}, "fps: must be <= 240"),
        ({"max_velocity": 1e9}, "max_velocity: must be <= 5"),
        ({"look_again": 4}, r"look_again: must be an integer in \[0, 3\]; got 4"),
        ({"look_again": True}, "look_again"),
    ],
)
def test_bad_values_name_the_key(change: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        RunConfig.from_mapping(change)


def test_toml_file_then_flags(tmp_path: Path) -> None:
    path = tmp_path / "run.toml"
    path.write_text('method = "no-vp"\nL = 4\nnoise = 0.05\nradius = 1\n')
    c = RunConfig.from_toml(path)
    assert (c.method, c.L, c.noise, c.radius) == ("no-vp", 4, 0.05, 1.0)
    args = build_parser().parse_args(
        ["run", "--config", str(path), "--method", "vgn", "--set", "L=2", "--set", "sigma=0"]
    )
    c = config_from_args(args)
    assert (c.method, c.L, c.noise, c.sigma) == ("vgn", 2, 0.05, 0.0)


def test_bad_files_are_reported(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        RunConfig.from_toml(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("L = \n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        RunConfig.from_toml(bad)
    wrong = tmp_path / "wrong.toml"
    wrong.write_text('L = "three"\n')
    with pytest.raises(ConfigError, match=r"wrong.toml: L must be of type int"):
        RunConfig.from_toml(wrong)


def test_cli_reports_bad_config_with_status_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["run", "--set", "gamma2=-1", "--out", str(tmp_path / "r")]) == 2
    assert "gamma2: must be in" in capsys.readouterr().err
    assert main(["run", "--set", "nonsense", "--out", str(tmp_path / "r")]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    assert not (tmp_path / "r").exists(), "nothing is written for a bad configuration"
    assert main(["run", "--print-config", "--objects", "7"]) == 0
    assert '"objects": 7' in capsys.readouterr().out


def test_the_presets_are_the_settings_docs_benchmarks_measured() -> None:
    # docs/benchmarks.md, the short-path table: HEAPGrasp with these settings, from above,
    # against no-vp from above
    assert set(presets()) == {"above", "paper", "short-path"}
    above = RunConfig(start="above")
    assert RunConfig.load("above") == above
    short = above.replace(
        {
            "view_planner": "oracle",  # as measured
            "gamma2": 0.0,
            "stop_below": 0.02,
            "stop_detour_weight": 0.1,
            "stop_confidence": 0.95,
            "move_weight": 0.05,
            "scene_memory": True,
            "sweep_degrees": 360.0,
            "sweep_step": 30.0,
        }
    )
    assert RunConfig.load("short-path") == short
    assert short != RunConfig()
    # the baselines as measured: each phase starts afresh
    for method in ("no-vp", "vgn", "hemisphere6"):
        assert ConfigFile.load("short-path").resolve(method) == short.replace(
            {"scene_memory": False}
        )


def test_settings_are_grouped_and_the_paper_preset_is_table_one_alone() -> None:
    c = RunConfig()
    names = RunConfig.field_names()
    groups = [RunConfig.field_names(g) for g in GROUPS]
    assert sorted(n for g in groups for n in g) == sorted(names), "every setting in one group"
    assert c.group("method")["lam"] == 0.9 and "lam" not in c.group("run")
    assert RunConfig.source("lam") == "Table I" and RunConfig.source("roof_radius") == "ours"
    with pytest.raises(ConfigError, match="group: must be one of run, method, extension"):
        c.group("misc")
    # every extension has its "off" value in PAPER_EXTENSIONS, and the paper preset is
    # exactly the defaults with all of them off
    assert set(PAPER_EXTENSIONS) == set(RunConfig.field_names("extension"))
    paper = RunConfig.load("paper")
    assert paper == c.paper_only()
    assert paper.group("method") == c.group("method") and paper.group("run") == c.group("run")
    assert paper.critic is None and paper.roof_radius == 0.0 and paper.target_radius == 0.0
    # the defaults are Table I plus the extensions measured to help
    on = {k for k, v in PAPER_EXTENSIONS.items() if c.group("extension")[k] != v}
    assert on == {
        "roof_radius",
        "grasp_critic",
        "failed_grasp_radius",
        "target_radius",
        "look_again",
        "fine_width",
    }


def test_config_takes_a_file_or_a_preset_and_names_a_bad_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(ConfigError, match=r"'short-paht' is neither a file nor a preset"):
        RunConfig.load("short-paht")
    with pytest.raises(ConfigError, match="config file not found"):
        RunConfig.load(tmp_path / "missing.toml")
    # a file of a preset's name wins over the preset
    monkeypatch.chdir(tmp_path)
    Path("above").write_text("L = 4\n")
    assert RunConfig.load("above") == RunConfig(L=4)
    assert main(["run", "--print-config", "--config", "short-path", "--set", "L=2"]) == 0
    out = capsys.readouterr().out
    assert '"sweep_degrees": 360.0' in out and '"L": 2' in out
    assert main(["bench", "sim", "--config", "nope", "--out", str(tmp_path / "b")]) == 2
    assert "'nope' is neither a file nor a preset (presets: above, paper, short-path)" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "b").exists()


def test_a_config_files_method_tables_apply_to_that_method_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from heapgrasp.bench.sim import _configs

    path = tmp_path / "c.toml"
    path.write_text("L = 4\nscene_memory = true\n[methods.no-vp]\nscene_memory = false\nL = 2\n")
    loaded = ConfigFile.load(path)
    assert loaded.resolve() == RunConfig(L=4, scene_memory=True)
    assert loaded.resolve("no-vp") == RunConfig(L=2)
    assert RunConfig.from_toml(path) == RunConfig(L=4, scene_memory=True)
    # precedence: the method's table < flags < --set
    assert main(["run", "--print-config", "--config", str(path), "--method", "no-vp"]) == 0
    out = capsys.readouterr().out
    assert '"scene_memory": false' in out and '"L": 2' in out and '"method": "no-vp"' in out
    argv = ["run", "--print-config", "--config", str(path), "--set", "method=no-vp"]
    assert main([*argv, "--set", "L=5"]) == 0
    out = capsys.readouterr().out
    assert '"scene_memory": false' in out and '"L": 5' in out
    args = build_parser().parse_args(
        ["bench", "sim", "--config", str(path), "--set", "objects=3", "--scenes", "4"]
    )
    base, per_method = _configs(args, ["heapgrasp", "no-vp", "magic"])
    assert set(per_method) == {"heapgrasp", "no-vp"}  # run_bench refuses "magic"
    assert base == per_method["heapgrasp"] == RunConfig(L=4, scene_memory=True, objects=3, scenes=4)
    assert per_method["no-vp"] == RunConfig(L=2, objects=3, scenes=4)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[methods.magic]\nL = 2\n", r"\[methods.magic\]: unknown method"),
        ("methods = 3\n", "'methods' must hold tables"),
        ("[methods.no-vp]\nL = 0\n", r"c.toml \[methods.no-vp\]: L: must be an integer"),
        ("[methods.no-vp]\nlamda = 0.5\n", r"\[methods.no-vp\]: unknown parameter 'lamda'"),
    ],
)
def test_a_bad_method_table_is_named(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "c.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match):
        ConfigFile.load(path)


def test_the_oracle_counts_eq14_on_the_configured_column() -> None:
    from heapgrasp.loop.stages import ORACLE_FRAMES, make_view_scorer
    from heapgrasp.planning.views import OracleViewScorer

    scorer = make_view_scorer(RunConfig(view_planner="oracle", target_radius=0.05))
    assert isinstance(scorer, OracleViewScorer) and scorer.frames_per_candidate == ORACLE_FRAMES
    assert scorer.target_radius == 0.05
    assert make_view_scorer(RunConfig(method="no-vp")) is None


def test_files_are_stored_as_absolute_paths(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a run is resumed, shown and replayed from anywhere
    monkeypatch.chdir(tmp_path)
    c = RunConfig(grasp_weights="w.onnx", view_weights="~/v.onnx", grasp_critic="c.onnx")
    assert c.grasp_weights == str(tmp_path / "w.onnx")
    assert c.view_weights == str(Path("~/v.onnx").expanduser())
    assert c.grasp_critic == str(tmp_path / "c.onnx")
    assert RunConfig(grasp_critic="auto").grasp_critic == "auto"
    assert RunConfig.from_mapping(c.to_dict()) == c  # read back unchanged


def test_auto_grasp_planner_is_vgns_network_for_vgn_and_analytic_elsewhere() -> None:
    # issue 58: the VGN baseline runs VGN's network (on the TSDF, checked) by default;
    # the silhouette methods keep the analytic planner with the critic
    from heapgrasp.loop.stages import make_grasp_planner
    from heapgrasp.planning.antipodal import AntipodalPlanner
    from heapgrasp.planning.grasp_network import NetworkGraspPlanner

    assert RunConfig().grasp_planner == "auto"
    uses = {m: RunConfig(method=m) for m in ("heapgrasp", "no-vp", "hemisphere6", "vgn")}
    assert {m: c.grasp_planner_in_use for m, c in uses.items()} == {
        "heapgrasp": "antipodal",
        "no-vp": "antipodal",
        "hemisphere6": "antipodal",
        "vgn": "network",
    }
    assert uses["heapgrasp"].critic == "default" and uses["vgn"].critic is None
    vgn = make_grasp_planner(uses["vgn"])
    assert isinstance(vgn, NetworkGraspPlanner) and vgn.input_kind == "tsdf"
    assert isinstance(make_grasp_planner(uses["no-vp"]), AntipodalPlanner)
    # an explicit choice wins, for either
    analytic = RunConfig(method="vgn", grasp_planner="antipodal")
    assert analytic.grasp_planner_in_use == "antipodal"
    assert isinstance(make_grasp_planner(analytic), AntipodalPlanner)
    assert RunConfig(grasp_planner="network").critic is None
    # the resolved choice follows a later change of method
    assert uses["heapgrasp"].replace({"method": "vgn"}).grasp_planner_in_use == "network"
