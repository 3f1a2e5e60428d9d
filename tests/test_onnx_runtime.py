"""Every shipped network loads and runs one way (issue 37 §3): an ONNX file, checked
whole, run with onnxruntime; PyTorch is never imported at run time."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from heapgrasp import OccupancyGrid
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.inference import (
    META_HPARAMS,
    META_KIND,
    META_PROVENANCE,
    META_SHA256,
    META_VERSION,
    OnnxNetwork,
    content_digest,
    resolve_device,
    seal,
    shipped_weights,
)
from heapgrasp.inference.errors import WeightsError
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.stages import make_grasp_planner, make_view_scorer
from heapgrasp.planning.critic import CROP_SHAPE, DEFAULT_CRITIC, N_SCALARS, GraspCritic
from heapgrasp.planning.view_network import NetworkViewScorer, network_input
from heapgrasp.planning.views import ViewContext, ViewScorer, target_region
from heapgrasp.training.train_critic import fit_critic, save_critic

R = 16
VIEW_SHAPE = (12, 6)
SMALL = {"encoder_channels": (4, 8, 8)}
N_FEATURES = 2 * int(np.prod(CROP_SHAPE)) + N_SCALARS


def _grids(n: int, channels: int, r: int = R, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.random((n, channels, r, r, r)) > 0.85).astype(np.float32)


@pytest.fixture(scope="module")
def torch() -> Any:
    return pytest.importorskip("torch")


@pytest.fixture(scope="module")
def view_nets(torch: Any, tmp_path_factory: pytest.TempPathFactory) -> dict[int, tuple[Any, Path]]:
    """Small randomly initialised view networks of 1, 2 and 3 input channels, exported."""
    from heapgrasp.training import ViewNet, export_onnx

    folder = tmp_path_factory.mktemp("view")
    out = {}
    for channels in (1, 2, 3):
        torch.manual_seed(channels)
        net = ViewNet(R, VIEW_SHAPE, in_channels=channels, **SMALL).eval()
        path = export_onnx(net, folder / f"view{channels}.onnx", provenance={"data": "test"})
        out[channels] = (net, path)
    return out


@pytest.fixture(scope="module")
def grasp_net(torch: Any, tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path]:
    from heapgrasp.training import GraspNet, export_onnx

    torch.manual_seed(0)
    net = GraspNet(R, encoder_channels=(4, 8, 8), decoder_channels=(8, 8, 4)).eval()
    path = export_onnx(net, tmp_path_factory.mktemp("grasp") / "g.onnx", provenance={})
    return net, path


# --------------------------------------------------------------------------- equality


@pytest.mark.parametrize("channels", [1, 2, 3])
def test_onnxruntime_gives_pytorchs_view_scores(
    torch: Any, view_nets: dict[int, tuple[Any, Path]], channels: int
) -> None:
    net, path = view_nets[channels]
    onnx_net = OnnxNetwork(path, kind="view-network")
    assert onnx_net.hparams["in_channels"] == channels
    assert onnx_net.hparams["resolution"] == R and onnx_net.hparams["view_shape"] == [12, 6]
    assert onnx_net.provenance["data"] == "test" and onnx_net.provenance["command"]
    for batch in (1, 3):  # the batch axis is dynamic
        x = _grids(batch, channels, seed=batch)
        with torch.no_grad():
            expected = net(torch.from_numpy(x)).numpy()
        (got,) = onnx_net.run(x)
        assert got.shape == (batch, *VIEW_SHAPE) and got.dtype == np.float32
        assert np.max(np.abs(got - expected)) <= 1e-5


def test_onnxruntime_gives_pytorchs_grasp_volumes(torch: Any, grasp_net: tuple[Any, Path]) -> None:
    net, path = grasp_net
    onnx_net = OnnxNetwork(path, kind="grasp-network")
    x = _grids(2, 1, seed=4)
    with torch.no_grad():
        expected = [t.numpy() for t in net(torch.from_numpy(x))]
    got = onnx_net.run(x)
    assert onnx_net.output_names == ["quality", "rotation", "width"]
    for a, b in zip(got, expected, strict=True):
        assert a.shape == b.shape and np.max(np.abs(a - b)) <= 1e-5


def test_shipped_critic_equals_pytorch(torch: Any) -> None:
    """The shipped critic runs in onnxruntime (float32) as in PyTorch (float64) on the
    weights the file holds, over many random feature rows."""
    onnx = pytest.importorskip("onnx")
    from heapgrasp.training.critic_net import _torch_module
    from onnx import numpy_helper

    critic = GraspCritic.load(DEFAULT_CRITIC)
    assert critic.model == "cnn" and critic.threshold == pytest.approx(0.6)
    model = onnx.load(DEFAULT_CRITIC)
    w = {i.name: numpy_helper.to_array(i).astype(np.float64) for i in model.graph.initializer}
    net = _torch_module(len(w["conv1_b"]), len(w["conv2_b"]), len(w["fc1_b"])).double().eval()
    net.load_state_dict(
        {
            f"{layer}.{kind}": torch.from_numpy(w[f"{layer}_{kind[0]}"])
            for layer in ("conv1", "conv2", "fc1", "fc2")
            for kind in ("weight", "bias")
        }
    )
    rng = np.random.default_rng(0)
    n_crop = N_FEATURES - N_SCALARS
    rows = []
    for density in np.linspace(0.05, 0.95, 10):
        crops = (rng.random((300, n_crop)) < density).astype(np.float64)
        scalars = w["mean"][n_crop:] + w["scale"][n_crop:] * rng.normal(size=(300, N_SCALARS))
        rows.append(np.hstack([crops, scalars]))
    f = np.vstack(rows)
    with torch.no_grad():
        logits = net(torch.from_numpy((f - w["mean"]) / w["scale"])).numpy()
    expected = 1.0 / (1.0 + np.exp(-np.clip(logits, -30, 30)))
    assert np.max(np.abs(critic.probability(f) - expected)) <= 1e-5


# --------------------------------------------------------------------------- the scorer


def test_view_scorer_feeds_the_region_to_two_channel_networks(
    view_nets: dict[int, tuple[Any, Path]],
) -> None:
    scorer = NetworkViewScorer(view_nets[2][1], target_radius=0.05)
    assert isinstance(scorer, ViewScorer)
    assert scorer.in_channels == 2 and scorer.resolution == R and scorer.view_shape == VIEW_SHAPE
    grid = OccupancyGrid((0.0, 0.0, 0.0), 0.3, R)
    target = np.eye(4)
    target[:3, 3] = (0.1, 0.2, 0.05)
    ctx = ViewContext(grid, np.eye(4), np.zeros((*VIEW_SHAPE, 4, 4)), None, None, 0.9)  # type: ignore[arg-type]
    whole = scorer.scores(ctx)  # no target: every voxel (the paper's eq. 14)
    assert scorer.region(ctx) is None
    np.testing.assert_array_equal(whole, scorer.scores(grid.occupancy()))
    ctx.target = target
    region = scorer.region(ctx)
    assert region is not None
    np.testing.assert_array_equal(region, target_region(grid, (0.1, 0.2, 0.05), 0.05))
    x = network_input(grid.occupancy(), region, 2)
    assert x.shape == (2, R, R, R) and x.dtype == np.float32
    np.testing.assert_array_equal(x[1], region)
    (expected,) = scorer.network.run(x[None])
    np.testing.assert_array_equal(scorer.scores(ctx), expected[0])
    assert not np.array_equal(scorer.scores(ctx), whole)
    # target_radius = 0: the whole grid even with a target
    np.testing.assert_array_equal(NetworkViewScorer(view_nets[2][1]).scores(ctx), whole)
    # a one-channel network reads the occupancy alone
    one = NetworkViewScorer(view_nets[1][1])
    np.testing.assert_array_equal(network_input(grid.occupancy(), region, 1)[0], grid.occupancy())
    assert one.scores(ctx).shape == VIEW_SHAPE
    with pytest.raises(TypeError, match="ONNX file"):
        NetworkViewScorer(view_nets[1][0])
    with pytest.raises(ValueError, match="target_radius"):
        NetworkViewScorer(view_nets[2][1], target_radius=-1.0)


def test_view_scorer_feeds_the_camera_to_three_channel_networks(
    view_nets: dict[int, tuple[Any, Path]],
) -> None:
    scorer = NetworkViewScorer(view_nets[3][1], target_radius=0.05)
    assert scorer.in_channels == 3
    grid = OccupancyGrid((0.0, 0.0, 0.0), 0.3, R)
    here, there = np.eye(4), np.eye(4)
    here[:3, 3] = (0.15, -0.2, 0.3)
    there[:3, 3] = (0.45, 0.15, 0.3)
    ctx = ViewContext(grid, here, np.zeros((*VIEW_SHAPE, 4, 4)), None, None, 0.9)  # type: ignore[arg-type]
    field = GridFrame((0.0, 0.0, 0.0), 0.3, R).distance_field(here[:3, 3])
    # nearest the camera: the top voxels of the y = 0 face, in the middle of x
    a, b, c = np.unravel_index(field.argmin(), field.shape)
    assert a in (R // 2 - 1, R // 2) and (b, c) == (0, R - 1)
    np.testing.assert_allclose(
        field[0, 0, 0], np.linalg.norm(here[:3, 3] - 0.15 / R) / 0.5, rtol=1e-6
    )
    x = network_input(grid.occupancy(), None, 3, field)
    (expected,) = scorer.network.run(x[None])
    np.testing.assert_array_equal(scorer.scores(ctx), expected[0])
    moved = scorer.scores(ViewContext(grid, there, ctx.candidates, None, None, 0.9))  # type: ignore[arg-type]
    assert not np.array_equal(moved, expected[0])  # where the camera is, is read
    with pytest.raises(ValueError, match="camera pose"):
        scorer.scores(grid.occupancy())
    with pytest.raises(ValueError, match="camera channel"):
        network_input(grid.occupancy(), None, 3)


def test_the_scorer_runs_with_torch_blocked(
    torch: Any, view_nets: dict[int, tuple[Any, Path]], tmp_path: Path
) -> None:
    net, path = view_nets[2]
    occ = _grids(1, 1, seed=9)[0, 0]
    with torch.no_grad():
        expected = net(torch.from_numpy(np.stack([occ, np.ones_like(occ)])[None]))[0].numpy()
    np.save(tmp_path / "occ.npy", occ)
    script = textwrap.dedent(
        f"""
        import json, sys
        import numpy as np
        sys.modules["torch"] = None  # as if PyTorch were not installed
        from heapgrasp.planning.view_network import NetworkViewScorer
        scorer = NetworkViewScorer({str(path)!r}, target_radius=0.08)
        s = scorer.scores(np.load({str(tmp_path / "occ.npy")!r}))
        print(json.dumps({{"scores": s.tolist(), "torch": sys.modules.get("torch") is not None,
                          "training": "heapgrasp.training" in sys.modules}}))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert not out["torch"] and not out["training"]
    assert np.max(np.abs(np.asarray(out["scores"], dtype=np.float32) - expected)) <= 1e-5


def test_make_view_scorer_checks_the_network_against_the_run(
    view_nets: dict[int, tuple[Any, Path]], tmp_path: Path
) -> None:
    one, two = str(view_nets[1][1]), str(view_nets[2][1])
    base = {"view_planner": "network", "resolution": R, "U": 12, "V": 6}
    scorer = make_view_scorer(RunConfig.from_mapping({**base, "view_weights": two}))
    assert isinstance(scorer, NetworkViewScorer) and scorer.target_radius == 0.08
    assert scorer.device == "cpu"
    cfg = RunConfig.from_mapping({**base, "view_weights": one, "target_radius": 0.0})
    assert isinstance(make_view_scorer(cfg), NetworkViewScorer)
    # a one-channel network cannot count eq. 14 on the target's column
    with pytest.raises(ConfigError, match=r"one-channel .*target_radius = 0.* region channel"):
        make_view_scorer(RunConfig.from_mapping({**base, "view_weights": one}))
    with pytest.raises(ConfigError, match=r"reads 16³ grids, the run's grid is 40³"):
        make_view_scorer(RunConfig.from_mapping({**base, "resolution": 40, "view_weights": two}))
    with pytest.raises(ConfigError, match=r"scores 12×6 candidates, the run has 40×20"):
        make_view_scorer(RunConfig.from_mapping({**base, "U": 40, "V": 20, "view_weights": two}))
    with pytest.raises(ConfigError, match=rf"grasp_weights: {two}: holds a 'view-network'"):
        make_grasp_planner(
            RunConfig.from_mapping({"grasp_planner": "network", "grasp_weights": two})
        )
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"\x00" * 100)
    with pytest.raises(ConfigError, match=rf"view_weights: {bad}: not a valid ONNX model"):
        make_view_scorer(RunConfig.from_mapping({**base, "view_weights": str(bad)}))
    if shipped_weights("view-network") is None:
        with pytest.raises(ConfigError, match="no view-network weights ship with this version"):
            make_view_scorer(RunConfig.from_mapping(base))


def test_devices(view_nets: dict[int, tuple[Any, Path]]) -> None:
    import onnxruntime

    assert resolve_device("cpu") == "cpu"
    has_cuda = "CUDAExecutionProvider" in onnxruntime.get_available_providers()
    assert resolve_device("auto") == ("cuda" if has_cuda else "cpu")
    for bad in ("gpu", "cuda:", "CPU", 0):
        with pytest.raises(ValueError, match="device must be cpu, cuda, cuda:N or auto"):
            resolve_device(bad)  # type: ignore[arg-type]
    one = OnnxNetwork(view_nets[1][1], kind="view-network", threads=1)
    assert one.providers == ["CPUExecutionProvider"]
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        OnnxNetwork(view_nets[1][1], kind="view-network", threads=0)
    if not has_cuda:
        with pytest.raises(ValueError, match=r"'cuda:0' asked for, .*onnxruntime-gpu"):
            resolve_device("cuda:0")
        with pytest.raises(ConfigError, match="net_device: 'cuda' asked for"):
            make_view_scorer(
                RunConfig.from_mapping(
                    {"view_planner": "network", "net_device": "cuda", "resolution": R, "U": 12}
                    | {"V": 6, "view_weights": str(view_nets[2][1])}
                )
            )


# --------------------------------------------------------------------------- bad files


def _edited(src: Path, out: Path, change: Callable[[Any], None]) -> Path:
    """``src`` changed by ``change`` and sealed again: a file written with that mistake."""
    onnx = pytest.importorskip("onnx")
    model = onnx.load(src)
    change(model)
    entries = [(e.key, e.value) for e in model.metadata_props if e.key != META_SHA256]
    del model.metadata_props[:]
    for k, v in entries:
        e = model.metadata_props.add()
        e.key, e.value = k, v
    out.write_bytes(seal(model.SerializeToString()))
    return out


def _meta(key: str, value: str | None) -> Callable[[Any], None]:
    def change(model: Any) -> None:
        entries = [(e.key, e.value) for e in model.metadata_props if e.key != key]
        if value is not None:
            entries.append((key, value))
        del model.metadata_props[:]
        for k, v in entries:
            e = model.metadata_props.add()
            e.key, e.value = k, v

    return change


def _hparams(**changes: Any) -> Callable[[Any], None]:
    def change(model: Any) -> None:
        meta = {e.key: e.value for e in model.metadata_props}
        hp = json.loads(meta[META_HPARAMS]) | changes
        _meta(META_HPARAMS, json.dumps(hp))(model)

    return change


def _nan_weights(model: Any) -> None:
    from onnx import numpy_helper

    init = next(i for i in model.graph.initializer if numpy_helper.to_array(i).size > 10)
    a = numpy_helper.to_array(init).copy()
    a.flat[3] = np.nan
    init.CopyFrom(numpy_helper.from_array(a, init.name))


def _fixed_batch(model: Any) -> None:
    dim = model.graph.input[0].type.tensor_type.shape.dim[0]
    dim.Clear()
    dim.dim_value = 1


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (
            _meta(META_KIND, None),
            "an ONNX model but not a heapgrasp network: metadata 'heapgrasp.k",
        ),
        (_meta(META_KIND, "grasp-network"), "holds a 'grasp-network' .*expected a 'view-network'"),
        (_meta(META_VERSION, "2"), "unsupported heapgrasp.format_version '2'"),
        (_meta(META_VERSION, None), "metadata 'heapgrasp.format_version' missing"),
        (_meta(META_HPARAMS, "{not json"), "metadata 'heapgrasp.hparams' is not valid JSON"),
        (_meta(META_PROVENANCE, "[1]"), "'heapgrasp.provenance' is a JSON list, not an object"),
        (
            _hparams(resolution=24),
            r"input 'grid' has shape \(B, 2, 16, 16, 16\), expected \(B, 2, 24",
        ),
        (_hparams(in_channels=1), r"input 'grid' has shape \(B, 2, 16.*expected \(B, 1, 16"),
        (
            _hparams(view_shape=[40, 20]),
            r"output 'scores' has shape \(B, 12, 6\), expected \(B, 40",
        ),
        (_hparams(view_shape="40x20"), "'view_shape' is '40x20', not a pair"),
        (_hparams(resolution=None), "'resolution' is None, not an integer"),
        (_fixed_batch, "input 'grid' has a fixed batch axis of 1"),
        (_nan_weights, "output 'scores' holds NaN or infinity on an all-zero input"),
    ],
)
def test_bad_network_files(
    view_nets: dict[int, tuple[Any, Path]],
    tmp_path: Path,
    change: Callable[[Any], None],
    match: str,
) -> None:
    path = _edited(view_nets[2][1], tmp_path / "bad.onnx", change)
    with pytest.raises(WeightsError, match=match) as exc:
        NetworkViewScorer(path)
    assert str(exc.value).startswith(f"{path}: ") and exc.value.path == path


def test_broken_and_foreign_files(view_nets: dict[int, tuple[Any, Path]], tmp_path: Path) -> None:
    data = view_nets[1][1].read_bytes()
    rng = np.random.default_rng(0)
    cases = {
        "empty.onnx": (b"", r"empty file \(0 bytes\)"),
        "random.onnx": (rng.bytes(4096), "not a valid ONNX model"),
        "text.onnx": (b"this is not a network\n", "not a valid ONNX model"),
        "zip.onnx": (b"PK\x03\x04" + bytes(200), r"a zip archive \(a PyTorch .pt"),
    }
    # Truncated anywhere: the file's end (its metadata) or its protobuf structure is lost.
    for cut in [*np.linspace(1, len(data) - 1, 25).astype(int), len(data) - 1, len(data) - 7]:
        cases[f"cut{cut}.onnx"] = (data[:cut], r"not a valid ONNX model|metadata")
    for name, (content, match) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(WeightsError, match=match) as exc:
            OnnxNetwork(path, kind="view-network")
        assert str(exc.value).startswith(f"{path}: "), name
    # Garbled weights still parse and run: the checksum catches them.
    offset = len(data) // 2
    garbled = bytearray(data)
    garbled[offset : offset + 16] = bytes(b ^ 0x5A for b in garbled[offset : offset + 16])
    path = tmp_path / "garbled.onnx"
    path.write_bytes(bytes(garbled))
    with pytest.raises(WeightsError, match=r"garbled\.onnx: garbled: .*SHA-256"):
        OnnxNetwork(path, kind="view-network")
    # The checksum leaves the metadata out, so sealing again changes nothing else...
    resealed = _edited(view_nets[1][1], tmp_path / "resealed.onnx", lambda m: None).read_bytes()
    assert content_digest(resealed) == content_digest(data)
    # ...and a file without it, or with another, is refused.
    onnx = pytest.importorskip("onnx")
    for name, digest in (("nodigest.onnx", None), ("zeros.onnx", "0" * 64)):
        model = onnx.load(view_nets[1][1])
        _meta(META_SHA256, digest)(model)
        path = tmp_path / name
        path.write_bytes(model.SerializeToString())
        match = "metadata 'heapgrasp.sha256' missing" if digest is None else "do not match"
        with pytest.raises(WeightsError, match=match):
            OnnxNetwork(path, kind="view-network")
    with pytest.raises(FileNotFoundError, match=r"view-network file not found: .*nothere\.onnx"):
        NetworkViewScorer(tmp_path / "nothere.onnx")
    with pytest.raises(WeightsError, match="not a file"):
        NetworkViewScorer(tmp_path)
    # the shipped critic is not a view network, a view network not a critic
    with pytest.raises(WeightsError, match="holds a 'grasp-critic'"):
        NetworkViewScorer(DEFAULT_CRITIC)
    with pytest.raises(WeightsError, match="holds a 'view-network'"):
        GraspCritic.load(view_nets[1][1])


def test_a_fitted_critic_round_trips_through_its_file(tmp_path: Path) -> None:
    pytest.importorskip("onnx")
    rng = np.random.default_rng(1)
    x = rng.random((80, N_FEATURES)).round()
    x[:, -N_SCALARS] = rng.random(80)
    y = (x[:, -N_SCALARS] > 0.5).astype(float)
    critic = fit_critic(x, y, components=3, threshold=0.55)
    path = save_critic(critic, tmp_path / "c.onnx", command="test", metadata={"data": "synthetic"})
    back = GraspCritic.load(path)
    assert back.model == "linear" and back.threshold == pytest.approx(0.55)
    assert back.metadata["data"] == "synthetic" and back.metadata["command"] == "test"
    np.testing.assert_array_equal(back.probability(x), critic.probability(x))
    bad = _edited(path, tmp_path / "t.onnx", _hparams(threshold=1.5))
    with pytest.raises(WeightsError, match=r"t\.onnx: hparams field 'threshold' is 1.5"):
        GraspCritic.load(bad)
    bad = _edited(path, tmp_path / "s.onnx", _hparams(crop_shape=[7, 13, 13]))
    with pytest.raises(WeightsError, match="hparams field 'crop_shape' is"):
        GraspCritic.load(bad)
