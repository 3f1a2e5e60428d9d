"""The grasp network (eq. 11) and view network (eq. 13), their weights files, and the
planners built on them, which run the exported ONNX files (heapgrasp.training,
planning.grasp_network, planning.view_network)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

torch = pytest.importorskip("torch")

import heapgrasp as hg  # noqa: E402
from heapgrasp.geometry.grid import GridFrame  # noqa: E402
from heapgrasp.inference.errors import WeightsError  # noqa: E402
from heapgrasp.planning.grasp_network import NetworkGraspPlanner  # noqa: E402
from heapgrasp.planning.view_network import NetworkViewScorer  # noqa: E402
from heapgrasp.planning.views import ViewContext, ViewScorer  # noqa: E402
from heapgrasp.planning.volumes import GraspPlanner, GraspVolumes, select_candidates  # noqa: E402
from heapgrasp.training import (  # noqa: E402
    Encoder3d,
    GraspNet,
    ViewNet,
    default_weights_dir,
    find_default,
    load_grasp_net,
    load_view_net,
    read_metadata,
    resolve_device,
    save_weights,
)
from heapgrasp.training.models import _unit_quaternions  # noqa: E402

SMALL = 16  # small grids keep the suite fast; the paper's 40³ is tested once per net


@pytest.fixture(autouse=True)
def _threads():
    old = torch.get_num_threads()
    torch.set_num_threads(2)
    yield
    torch.set_num_threads(old)


def _grid(r: int, seed: int = 0, batch: int | None = None) -> np.ndarray:
    """A random binary occupancy grid (float32)."""
    rng = np.random.default_rng(seed)
    shape = (r, r, r) if batch is None else (batch, r, r, r)
    return (rng.random(shape) > 0.85).astype(np.float32)


def _grasp_net(r: int = SMALL, seed: int = 0) -> GraspNet:
    torch.manual_seed(seed)
    return GraspNet(r).eval()


def _view_net(r: int = SMALL, shape=(12, 6), seed: int = 0) -> ViewNet:
    torch.manual_seed(seed)
    return ViewNet(r, shape).eval()


def _frame(r: int) -> GridFrame:
    return GridFrame((-0.15, -0.15, 0.0), 0.30, r)


# --------------------------------------------------------------------------- models


def test_grasp_net_paper_resolution_shapes_and_ranges():
    net = _grasp_net(40)
    x = torch.from_numpy(_grid(40, batch=2))[:, None]
    with torch.inference_mode():
        quality, rotation, width = net(x)
        again = net(x)
    assert quality.shape == (2, 1, 40, 40, 40)
    assert rotation.shape == (2, 4, 40, 40, 40)
    assert width.shape == (2, 1, 40, 40, 40)
    assert quality.min() >= 0.0 and quality.max() <= 1.0
    norms = torch.linalg.vector_norm(rotation, dim=1)
    torch.testing.assert_close(norms, torch.ones_like(norms), atol=1e-5, rtol=0)
    assert torch.isfinite(width).all()
    for a, b in zip((quality, rotation, width), again, strict=True):
        assert torch.equal(a, b)


def test_view_net_paper_resolution_shapes_and_ranges():
    torch.manual_seed(0)
    net = ViewNet().eval()
    assert (net.resolution, net.view_shape) == (40, (40, 20))
    assert net.sizes == ((10, 10), (20, 20), (40, 20))
    x = torch.from_numpy(_grid(40, batch=2))[:, None]
    with torch.inference_mode():
        s = net(x)
        again = net(x)
    assert s.shape == (2, 40, 20)
    assert s.min() >= 0.0 and s.max() <= 1.0
    assert torch.equal(s, again)


def test_encoder_halves_three_times():
    torch.manual_seed(0)
    enc = Encoder3d()
    assert enc.out_channels == 64 and enc.levels == 3
    with torch.inference_mode():
        out = enc(torch.zeros(1, 1, 24, 24, 24))
    assert out.shape == (1, 64, 3, 3, 3)


@pytest.mark.parametrize("cls", [GraspNet, ViewNet])
def test_same_seed_same_init(cls):
    torch.manual_seed(7)
    a = cls(SMALL).state_dict()
    torch.manual_seed(7)
    b = cls(SMALL).state_dict()
    torch.manual_seed(8)
    c = cls(SMALL).state_dict()
    assert a.keys() == b.keys()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


def test_view_net_configurable_shape():
    torch.manual_seed(0)
    net = ViewNet(8, (7, 3), up_channels=(8, 8), compress_channels=8).eval()
    with torch.inference_mode():
        s = net(torch.zeros(3, 1, 8, 8, 8))
    assert s.shape == (3, 7, 3)
    assert net.sizes == ((2, 2), (7, 3))


@pytest.mark.parametrize("cls", [GraspNet, ViewNet])
@pytest.mark.parametrize("r", [0, 4, 12, 42])
def test_resolution_must_fit_encoder(cls, r):
    with pytest.raises(ValueError, match=f"R = {r} .*multiple of 8"):
        cls(r)


@pytest.mark.parametrize(
    ("cls", "kwargs", "match"),
    [
        (GraspNet, {"decoder_channels": (64, 32)}, "decoder channels must have 3"),
        (GraspNet, {"encoder_kernels": (5, 4, 3)}, "odd"),
        (ViewNet, {"view_shape": (40, 0)}, "view_shape"),
        (ViewNet, {"up_channels": ()}, "up_channels"),
    ],
)
def test_bad_hyperparameters(cls, kwargs, match):
    with pytest.raises(ValueError, match=match):
        cls(SMALL, **kwargs)


@pytest.mark.parametrize("cls", [GraspNet, ViewNet])
def test_forward_rejects_wrong_grid(cls):
    net = cls(SMALL)
    with pytest.raises(ValueError, match=r"expects a \(B, 1, 16, 16, 16\) grid, got \(1, 1, 8"):
        net(torch.zeros(1, 1, 8, 8, 8))
    with pytest.raises(ValueError, match="expects a"):
        net(torch.zeros(1, SMALL, SMALL, SMALL))


def test_zero_quaternion_becomes_identity():
    raw = torch.zeros(1, 4, 2, 1, 1)
    raw[0, :, 1, 0, 0] = torch.tensor([0.0, 3.0, 0.0, 4.0])
    q = _unit_quaternions(raw)
    assert q[0, :, 0, 0, 0].tolist() == [0.0, 0.0, 0.0, 1.0]
    torch.testing.assert_close(q[0, :, 1, 0, 0], torch.tensor([0.0, 0.6, 0.0, 0.8]))


# --------------------------------------------------------------------------- weights


def _outputs(net, x):
    with torch.inference_mode():
        out = net(x)
    return out if isinstance(out, tuple) else (out,)


@pytest.mark.parametrize(
    ("kind", "make", "load"),
    [
        ("grasp", _grasp_net, load_grasp_net),
        ("view", _view_net, load_view_net),
    ],
)
def test_weights_round_trip(tmp_path, kind, make, load):
    net = make(seed=3)
    path = save_weights(
        net,
        tmp_path / "sub" / f"{kind}.pt",
        kind=kind,
        metadata={
            "epochs": np.int64(2),
            "loss": np.float64(0.25),
            "dataset": {"scenes": (1, 2)},
            "tag": None,
        },
        command="heapgrasp train --test",
    )
    loaded = load(path)
    assert type(loaded) is type(net) and not loaded.training
    x = torch.from_numpy(_grid(SMALL, seed=1, batch=2))[:, None]
    for a, b in zip(_outputs(net, x), _outputs(loaded, x), strict=True):
        assert torch.equal(a, b)
    meta = read_metadata(path)
    assert meta["kind"] == kind
    assert meta["resolution"] == SMALL
    assert meta["architecture"] == net.hparams()
    assert meta["command"] == "heapgrasp train --test"
    assert meta["created"].endswith("Z")
    assert meta["metadata"] == {
        "epochs": 2,
        "loss": 0.25,
        "dataset": {"scenes": [1, 2]},
        "tag": None,
    }
    assert "state_dict" not in meta


def test_default_command_is_recorded(tmp_path):
    path = save_weights(_grasp_net(8), tmp_path / "g.pt", kind="grasp")
    assert read_metadata(path)["command"]
    assert read_metadata(path)["metadata"] == {}


def test_wrong_kind_raises(tmp_path):
    path = save_weights(_grasp_net(), tmp_path / "g.pt", kind="grasp", metadata={})
    with pytest.raises(ValueError, match=r"g\.pt.*grasp-network weights.*expected view-network"):
        load_view_net(path)
    vpath = save_weights(_view_net(), tmp_path / "v.pt", kind="view", metadata={})
    with pytest.raises(ValueError, match=r"v\.pt.*view-network weights.*kind='grasp'"):
        load_grasp_net(vpath)


def test_save_checks_kind_and_metadata(tmp_path):
    with pytest.raises(ValueError, match="kind='view' needs a ViewNet, got GraspNet"):
        save_weights(_grasp_net(8), tmp_path / "x.pt", kind="view", metadata={})
    with pytest.raises(ValueError, match="kind must be"):
        save_weights(_grasp_net(8), tmp_path / "x.pt", kind="vgn", metadata={})
    with pytest.raises(TypeError, match=r"metadata\.arr: ndarray is not a plain type"):
        save_weights(_grasp_net(8), tmp_path / "x.pt", kind="grasp", metadata={"arr": np.zeros(2)})
    assert not (tmp_path / "x.pt").exists()


def test_missing_file_raises(tmp_path):
    missing = tmp_path / "nope" / "grasp.pt"
    with pytest.raises(FileNotFoundError, match=r"grasp-network weights.*nope.*training"):
        load_grasp_net(missing)
    with pytest.raises(FileNotFoundError, match="view-network"):
        load_view_net(str(missing))
    with pytest.raises(ValueError, match="not a file"):
        load_grasp_net(tmp_path)


def test_corrupt_or_truncated_file_raises(tmp_path):
    path = save_weights(_grasp_net(), tmp_path / "g.pt", kind="grasp", metadata={})
    data = path.read_bytes()
    trunc = tmp_path / "trunc.pt"
    trunc.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError, match=r"trunc\.pt: corrupt or truncated"):
        load_grasp_net(trunc)
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"definitely not a zip archive")
    with pytest.raises(ValueError, match=r"junk\.pt: corrupt"):
        load_grasp_net(junk)
    empty = tmp_path / "empty.pt"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match=r"empty\.pt"):
        read_metadata(empty)
    plain = tmp_path / "plain.pt"
    torch.save({"state_dict": {}}, plain)
    with pytest.raises(ValueError, match=r"plain\.pt: not a heapgrasp weights file"):
        load_grasp_net(plain)


def _rewrite(path: Path, out: Path, **changes) -> Path:
    data = torch.load(path, weights_only=True)
    data.update(changes)
    torch.save(data, out)
    return out


def test_architecture_mismatch_raises(tmp_path):
    net = _grasp_net()
    path = save_weights(net, tmp_path / "g.pt", kind="grasp", metadata={})
    arch = dict(net.hparams(), decoder_channels=[64, 32, 8])
    bad = _rewrite(path, tmp_path / "arch.pt", architecture=arch)
    with pytest.raises(ValueError, match=r"arch\.pt: weights do not match.*size mismatch"):
        load_grasp_net(bad)
    # Same architecture at another resolution: the view net's z-compression depends on R.
    vnet = _view_net()
    vpath = save_weights(vnet, tmp_path / "v.pt", kind="view", metadata={})
    bad = _rewrite(vpath, tmp_path / "res.pt", architecture=dict(vnet.hparams(), resolution=24))
    with pytest.raises(ValueError, match=r"res\.pt: weights do not match"):
        load_view_net(bad)
    bad = _rewrite(path, tmp_path / "inv.pt", architecture=dict(net.hparams(), resolution=42))
    with pytest.raises(ValueError, match=r"inv\.pt: architecture .* is invalid.*multiple of 8"):
        load_grasp_net(bad)
    bad = _rewrite(path, tmp_path / "key.pt", architecture=dict(net.hparams(), depth=3))
    with pytest.raises(ValueError, match=r"key\.pt: architecture .* is invalid"):
        load_grasp_net(bad)
    state = {k: v.clone() for k, v in net.state_dict().items()}
    state["quality_head.bias"][0] = float("nan")
    bad = _rewrite(path, tmp_path / "nan.pt", state_dict=state)
    with pytest.raises(ValueError, match=r"nan\.pt: weights hold NaN"):
        load_grasp_net(bad)
    with pytest.raises(ValueError, match=r"g\.pt: network reads 16³ grids, the grid here is 40³"):
        load_grasp_net(path, resolution=40)


def test_default_weights_location():
    assert default_weights_dir() == Path(hg.__file__).parent / "weights"
    assert find_default("grasp") is None
    assert find_default("view") is None
    with pytest.raises(ValueError, match="kind must be"):
        find_default("other")


# --------------------------------------------------------------------------- planners
# The planners run the networks' ONNX files with onnxruntime (heapgrasp.inference); these
# tests export randomly initialised networks first.


@pytest.fixture(scope="module")
def onnx_files(tmp_path_factory):
    """Exported networks: grasp and view at R = 16 and at the paper's 40."""
    from heapgrasp.training import export_onnx

    folder = tmp_path_factory.mktemp("onnx")
    nets = {
        "grasp16": _grasp_net(),
        "grasp40": _grasp_net(40, seed=3),
        "view16": _view_net(),
        "view40": _view_net(40, (40, 20), seed=4),
    }
    return {
        name: (net, export_onnx(net, folder / f"{name}.onnx", provenance={}))
        for name, net in nets.items()
    }


def test_grasp_planner_paper_resolution(onnx_files):
    net, path = onnx_files["grasp40"]
    planner = NetworkGraspPlanner(path)
    assert isinstance(planner, GraspPlanner)
    assert planner.name == "vgn-net" and planner.input_kind == "occupancy"
    assert planner.resolution == 40 and planner.device == "cpu"
    frame = _frame(40)
    vols = planner.predict(_grid(40), frame)
    assert isinstance(vols, GraspVolumes) and vols.frame == frame
    assert vols.quality.dtype == vols.quaternions.dtype == vols.widths.dtype == np.float32
    assert vols.quaternions.shape == (40, 40, 40, 4)
    assert 0.0 <= vols.quality.min() and vols.quality.max() <= 1.0
    np.testing.assert_allclose(np.linalg.norm(vols.quaternions, axis=-1), 1.0, atol=1e-5)
    # PyTorch's volumes
    quality, rotation, width = _outputs(net, torch.from_numpy(_grid(40))[None, None])
    # ... their quality kept within one voxel of the occupied grid (a file without
    # grasp_origin holds TCPs, which lie in the hull), 0 beyond
    near = ndimage.binary_dilation(_grid(40) > 0, iterations=1)
    assert planner.grasp_origin == "tcp" and planner.tcp_offset == planner.hull_margin == 0.0
    assert (~near).any()
    np.testing.assert_allclose(vols.quality[near], quality[0, 0].numpy()[near], atol=1e-5)
    assert (vols.quality[~near] == 0.0).all()
    np.testing.assert_allclose(vols.quaternions, rotation[0].permute(1, 2, 3, 0).numpy(), atol=1e-5)
    np.testing.assert_allclose(vols.widths, width[0, 0].numpy(), atol=1e-5)
    # The volumes feed eq. 15 as they are.
    cands = select_candidates(vols, epsilon=0.0, sigma=1.0, nms_window=4)
    assert cands and all(np.isfinite(c.pose).all() for c in cands)


def test_a_tsdf_networks_quality_is_kept_where_vgn_keeps_it(onnx_files, tmp_path):
    from heapgrasp.planning.grasp_network import tsdf_valid
    from heapgrasp.training import export_onnx

    # A table-like surface: unobserved below, the band behind it, the band in front,
    # free space above (heapgrasp's TSDF: 1 free, 0 unobserved).
    column = np.array([0, 0, 0, 0, 0, -0.8, -0.3, 0.2, 0.5, 0.9] + [1.0] * 6, np.float32)
    grid = np.broadcast_to(column, (16, 16, 16)).copy()
    valid = tsdf_valid(grid)
    # the front band and two voxels beyond it, never the band behind
    expected = np.zeros(16, bool)
    expected[7:12] = True
    assert (valid == expected).all()
    assert not tsdf_valid(np.zeros((16, 16, 16), np.float32)).any()
    # The planner applies it to a TSDF network's quality and keeps the rest.
    net, _ = onnx_files["grasp16"]
    path = export_onnx(net, tmp_path / "tsdf.onnx", provenance={}, hparams={"input_kind": "tsdf"})
    vols = NetworkGraspPlanner(path).predict(grid, _frame(16))
    quality, _, _ = _outputs(net, torch.from_numpy(grid)[None, None])
    np.testing.assert_allclose(vols.quality[valid], quality[0, 0].numpy()[valid], atol=1e-5)
    assert (vols.quality[~valid] == 0.0).all()


def test_a_palm_origin_network_grasps_ahead_of_its_voxel(onnx_files, tmp_path):
    """Networks trained on format-2 data hold VGN's grasp origin, the palm's face: the
    TCP lies -palm_front ahead along the approach, grasps lie in front of the hull
    (within 1.1 finger depths and a voxel), never deep inside it."""
    from heapgrasp.geometry.gripper import PANDA_HAND
    from heapgrasp.inference.errors import WeightsError
    from heapgrasp.training import export_onnx

    net, _ = onnx_files["grasp40"]
    hp = {"input_kind": "occupancy", "grasp_origin": "palm"}
    path = export_onnx(net, tmp_path / "palm.onnx", provenance={}, hparams=hp)
    planner = NetworkGraspPlanner(path)
    assert planner.grasp_origin == "palm"
    assert planner.tcp_offset == pytest.approx(-PANDA_HAND.palm_front)
    grid = np.zeros((40, 40, 40), np.float32)
    grid[15:25, 15:25, 0:10] = 1.0  # a box on the table
    frame = _frame(40)
    vols = planner.predict(grid, frame)
    assert vols.tcp_offset == planner.tcp_offset
    occupied = grid > 0
    margin = int(np.ceil(1.1 * PANDA_HAND.finger_depth / frame.voxel_size)) + 1
    near = ndimage.binary_dilation(occupied, iterations=margin) & ~ndimage.binary_erosion(occupied)
    quality, _, _ = _outputs(net, torch.from_numpy(grid)[None, None])
    np.testing.assert_allclose(vols.quality[near], quality[0, 0].numpy()[near], atol=1e-5)
    assert (vols.quality[~near] == 0.0).all() and (~near & occupied).any()
    for c in select_candidates(vols, epsilon=0.0, sigma=1.0, nms_window=4):
        centre = frame.centers(np.array([c.index]))[0]
        np.testing.assert_allclose(c.position, centre + planner.tcp_offset * c.pose[:3, 2])
    with pytest.raises(ValueError, match="tcp_offset must be finite"):
        GraspVolumes(frame, vols.quality, vols.quaternions, vols.widths, tcp_offset=np.nan)
    bad = export_onnx(
        net, tmp_path / "bad.onnx", provenance={}, hparams={**hp, "grasp_origin": "wrist"}
    )
    with pytest.raises(WeightsError, match="grasp_origin is 'wrist'"):
        NetworkGraspPlanner(bad)


def test_a_network_for_the_2f140_plans_for_its_hand(onnx_files, tmp_path):
    """A network trained on ``--gripper robotiq-2f140`` data puts the TCP ahead of its
    voxels by that hand's palm; the loop refuses it on a hand that opens less."""
    from heapgrasp.geometry.gripper import PANDA_HAND, ROBOTIQ_2F140
    from heapgrasp.inference.errors import WeightsError
    from heapgrasp.loop.config import ConfigError, RunConfig
    from heapgrasp.loop.stages import make_grasp_planner
    from heapgrasp.training import export_onnx

    net, _ = onnx_files["grasp40"]
    hp = {"input_kind": "occupancy", "grasp_origin": "palm", "gripper": "robotiq-2f140"}
    path = export_onnx(net, tmp_path / "2f140.onnx", provenance={}, hparams=hp)
    planner = NetworkGraspPlanner(path)
    assert planner.gripper == "robotiq-2f140"
    assert planner.tcp_offset == pytest.approx(-ROBOTIQ_2F140.palm_front)
    config = RunConfig(grasp_planner="network", grasp_weights=str(path))
    assert make_grasp_planner(config, ROBOTIQ_2F140).gripper == "robotiq-2f140"
    with pytest.raises(ConfigError, match="trained for the robotiq-2f140 hand, which opens to 14"):
        make_grasp_planner(config, PANDA_HAND)
    bad = export_onnx(net, tmp_path / "bad.onnx", provenance={}, hparams={**hp, "gripper": "x"})
    with pytest.raises(WeightsError, match="gripper is 'x'"):
        NetworkGraspPlanner(bad)


def test_grasp_planner_batch_matches_single(onnx_files):
    planner = NetworkGraspPlanner(onnx_files["grasp16"][1])
    frame = _frame(SMALL)
    grids = _grid(SMALL, seed=5, batch=3)
    batch = planner.predict_batch(grids, frame)
    assert len(batch) == 3
    for i, vols in enumerate(batch):
        single = planner.predict(grids[i], frame)
        np.testing.assert_allclose(vols.quality, single.quality, atol=1e-6)
        np.testing.assert_allclose(vols.quaternions, single.quaternions, atol=1e-5)
        np.testing.assert_allclose(vols.widths, single.widths, atol=1e-6)
    frames = [_frame(SMALL), GridFrame((0.0, 0.0, 0.0), 0.2, SMALL), _frame(SMALL)]
    assert [v.frame for v in planner.predict_batch(grids, frames)] == frames
    with pytest.raises(ValueError, match="3 grids but 2 frames"):
        planner.predict_batch(grids, frames[:2])
    with pytest.raises(ValueError, match=r"grids must be a \(B >= 1, 16, 16, 16\) array"):
        planner.predict_batch(grids[0], frame)
    bad = grids.copy()
    bad[1, 0, 0, 0] = np.inf
    with pytest.raises(ValueError, match=r"grids\[1\] holds NaN or infinity"):
        planner.predict_batch(bad, frame)


def test_grasp_planner_accepts_read_only_grid(onnx_files):
    planner = NetworkGraspPlanner(onnx_files["grasp16"][1])
    grid = _grid(SMALL)
    grid.flags.writeable = False
    planner.predict(grid, _frame(SMALL))


def test_grasp_planner_rejects_bad_input(onnx_files):
    planner = NetworkGraspPlanner(onnx_files["grasp16"][1])
    frame = _frame(SMALL)
    grid = _grid(SMALL)
    with pytest.raises(ValueError, match=r"grid must have shape \(16, 16, 16\), got \(16, 16\)"):
        planner.predict(grid[0], frame)
    nan = grid.copy()
    nan[3, 4, 5] = np.nan
    with pytest.raises(ValueError, match="grid holds NaN or infinity"):
        planner.predict(nan, frame)
    with pytest.raises(ValueError, match="grid must be float32, got float64"):
        planner.predict(grid.astype(np.float64), frame)
    with pytest.raises(ValueError, match="grid must be a numpy array, got list"):
        planner.predict(grid.tolist(), frame)
    with pytest.raises(ValueError, match=r"frame\.resolution is 40, the grasp network reads 16³"):
        planner.predict(grid, _frame(40))
    with pytest.raises(TypeError, match="grasp network's ONNX file, got GraspNet"):
        NetworkGraspPlanner(_grasp_net())
    with pytest.raises(FileNotFoundError, match=r"missing\.onnx"):
        NetworkGraspPlanner("missing.onnx")


def _ort_cuda() -> bool:
    import onnxruntime

    return "CUDAExecutionProvider" in onnxruntime.get_available_providers()


cuda = pytest.mark.skipif(
    not (torch.cuda.is_available() and _ort_cuda()),
    reason="needs a CUDA device and onnxruntime-gpu",
)
# On a GPU, convolutions may run in TF32 (a 10-bit mantissa, where cuDNN allows it): the
# tolerance leaves room for that.
TF32_ATOL = 1e-2


@cuda
def test_grasp_planner_on_cuda_matches_cpu(onnx_files):
    path = onnx_files["grasp40"][1]
    frame = _frame(40)
    grids = _grid(40, seed=7, batch=2)
    gpu = NetworkGraspPlanner(path, device="cuda")
    assert gpu.network.providers[0] == "CUDAExecutionProvider"
    for a, b in zip(
        NetworkGraspPlanner(path).predict_batch(grids, frame),
        gpu.predict_batch(grids, frame),
        strict=True,
    ):
        np.testing.assert_allclose(b.quality, a.quality, atol=TF32_ATOL)
        np.testing.assert_allclose(b.widths, a.widths, atol=TF32_ATOL)
        # q and -q are the same rotation
        dots = np.abs(np.sum(a.quaternions * b.quaternions, axis=-1))
        np.testing.assert_allclose(dots, 1.0, atol=TF32_ATOL)
        assert b.quality.dtype == np.float32 and b.quaternions.shape == (40, 40, 40, 4)


@cuda
def test_view_scorer_on_cuda_matches_cpu(onnx_files):
    path = onnx_files["view40"][1]
    occ = _grid(40, seed=8)
    cpu = NetworkViewScorer(path).scores(occ)
    gpu = NetworkViewScorer(path, device="cuda")
    assert gpu.network.providers[0] == "CUDAExecutionProvider"
    s = gpu.scores(occ)
    assert s.shape == (40, 20) and s.dtype == np.float32
    np.testing.assert_allclose(s, cpu, atol=TF32_ATOL)


def test_resolve_device_names_what_pytorch_sees():
    assert resolve_device("cpu") == "cpu"
    assert resolve_device("auto") == ("cuda" if torch.cuda.is_available() else "cpu")
    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    # A device PyTorch cannot see is an error, not a quiet run on the CPU.
    with pytest.raises(ValueError, match=rf"'cuda:{count}' asked for, but PyTorch sees {count}"):
        resolve_device(f"cuda:{count}")
    for bad in ("gpu", "cuda:", "cuda:x", "CPU", 0):
        with pytest.raises(ValueError, match="device must be cpu, cuda, cuda:N or auto"):
            resolve_device(bad)  # type: ignore[arg-type]


def test_the_grasp_network_reads_the_grid_it_was_trained_on(onnx_files, tmp_path):
    from heapgrasp.loop.config import ConfigError, RunConfig
    from heapgrasp.loop.stages import make_grasp_planner
    from heapgrasp.training import export_onnx

    net, occupancy = onnx_files["grasp16"]
    tsdf = export_onnx(net, tmp_path / "tsdf.onnx", provenance={}, hparams={"input_kind": "tsdf"})
    assert NetworkGraspPlanner(tsdf).input_kind == "tsdf"
    base = {"grasp_planner": "network", "resolution": 16}
    vgn = RunConfig.from_mapping({**base, "method": "vgn", "grasp_weights": str(tsdf)})
    assert make_grasp_planner(vgn).input_kind == "tsdf"
    for method, weights, trained, fed in (
        ("vgn", occupancy, "occupancy", "tsdf"),
        ("no-vp", tsdf, "tsdf", "occupancy"),
    ):
        config = RunConfig.from_mapping({**base, "method": method, "grasp_weights": str(weights)})
        match = f"{weights} was trained on {trained} grids, but the {method} method feeds it {fed}"
        with pytest.raises(ConfigError, match=match):
            make_grasp_planner(config)
    bad = export_onnx(net, tmp_path / "bad.onnx", provenance={}, hparams={"input_kind": "depth"})
    with pytest.raises(WeightsError, match="hparams input_kind is 'depth'"):
        NetworkGraspPlanner(bad)


def test_the_config_picks_the_networks_device(onnx_files):
    from heapgrasp.inference import resolve_device as ort_device
    from heapgrasp.loop.config import ConfigError, RunConfig
    from heapgrasp.loop.stages import make_grasp_planner, make_view_scorer, net_device

    base = {"grasp_planner": "network", "grasp_weights": str(onnx_files["grasp40"][1])}
    base |= {"view_planner": "network", "view_weights": str(onnx_files["view40"][1])}
    base |= {"target_radius": 0.0}  # a one-channel view network
    cpu = RunConfig.from_mapping(base)
    assert net_device(cpu) == "cpu"
    assert make_grasp_planner(cpu).device == "cpu"
    assert make_view_scorer(cpu).device == "cpu"
    auto = RunConfig.from_mapping({**base, "net_device": "auto"})
    assert net_device(auto) == ort_device("auto")
    if not _ort_cuda():
        missing = RunConfig.from_mapping({**base, "net_device": "cuda:0"})
        match = r"net_device: 'cuda:0' asked for, but this onnxruntime has no CUDAExecution"
        with pytest.raises(ConfigError, match=match):
            make_grasp_planner(missing)
        with pytest.raises(ConfigError, match="net_device"):
            make_view_scorer(missing)


def test_view_scorer_scores(onnx_files):
    net, path = onnx_files["view16"]
    scorer = NetworkViewScorer(path)
    assert isinstance(scorer, ViewScorer)
    assert scorer.name == "view-net" and scorer.view_shape == (12, 6)
    assert scorer.in_channels == 1 and scorer.resolution == SMALL
    occ = _grid(SMALL, seed=2)
    s = scorer.scores(occ)
    assert s.shape == (12, 6) and s.dtype == np.float32
    assert 0.0 <= s.min() and s.max() <= 1.0
    (expected,) = _outputs(net, torch.from_numpy(occ)[None, None])
    np.testing.assert_allclose(s, expected[0].numpy(), atol=1e-5)
    with pytest.raises(ValueError, match=r"occupancy must have shape \(16, 16, 16\)"):
        scorer.scores(_grid(8))
    with pytest.raises(ValueError, match="occupancy holds NaN"):
        scorer.scores(np.full((SMALL,) * 3, np.nan, np.float32))
    with pytest.raises(ValueError, match=r"holds a 'view-network' .*expected a 'grasp-network'"):
        NetworkGraspPlanner(path)


def test_view_scorer_paper_resolution_and_context(onnx_files):
    scorer = NetworkViewScorer(onnx_files["view40"][1])
    grid = hg.OccupancyGrid((-0.15, -0.15, 0.0), 0.30, 40)
    ctx = ViewContext(grid, np.eye(4), np.zeros((40, 20, 4, 4)), None, None, 0.9)
    s = scorer.scores(ctx)
    assert s.shape == (40, 20) and 0.0 <= s.min() and s.max() <= 1.0
    np.testing.assert_array_equal(s, scorer.scores(grid.occupancy()))
    ctx.candidates = np.zeros((10, 5, 4, 4))
    with pytest.raises(ValueError, match="scores 40×20 candidates, the context has 10×5"):
        scorer.scores(ctx)


def test_no_torch_import_at_run_time_and_clear_error():
    code = textwrap.dedent(
        """
        import sys
        sys.modules["torch"] = None  # as if PyTorch were not installed
        import heapgrasp, heapgrasp.planning.volumes, heapgrasp.planning.views
        import heapgrasp.planning.grasp_network as gn, heapgrasp.planning.view_network as vn
        for make in (lambda: gn.NetworkGraspPlanner("w.onnx"),
                     lambda: vn.NetworkViewScorer("w.onnx")):
            try:
                make()
            except FileNotFoundError as exc:  # no ImportError: the planners need no PyTorch
                assert "w.onnx" in str(exc), exc
            else:
                raise AssertionError("no FileNotFoundError")
        import heapgrasp.training  # by itself no PyTorch (the linear critic needs none)
        try:
            from heapgrasp.training import GraspNet  # noqa: F401
        except ImportError as exc:
            assert "install heapgrasp[train]" in str(exc), exc
        else:
            raise AssertionError("no ImportError")
        print("ok")
        """
    )
    # The same heapgrasp as this test session (installed in CI, or PYTHONPATH).
    env = dict(os.environ)
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"
