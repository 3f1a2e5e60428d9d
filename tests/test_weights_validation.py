"""Weights files are checked whole when they are loaded (issue 36, item 2): a critic or
network file that is empty, truncated, garbled, of another format, or that loads but
holds a missing or misshapen array, a wrong dtype, NaN, infinity, a zero scale or bad
metadata raises a WeightsError naming the file and the problem; through a run's
configuration it is a ConfigError raised once, before any scene (``heapgrasp run`` exits
2 without a traceback and without creating the output directory)."""

from __future__ import annotations

import json
import pickle
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from heapgrasp import HeapgraspError
from heapgrasp.cli import main
from heapgrasp.inference.errors import WeightsError
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.loop.stages import make_critic
from heapgrasp.planning.critic import (
    ARRAYS,
    CROP_SHAPE,
    DEFAULT_CRITIC,
    N_SCALARS,
    GraspCritic,
    read_critic_arrays,
)
from heapgrasp.training.critic_net import convert_npz

N_FEATURES = 2 * int(np.prod(CROP_SHAPE)) + N_SCALARS


# --------------------------------------------------------------------------- helpers


def _garble(data: bytes, start: int, length: int = 64) -> bytes:
    """``data`` with ``length`` bytes from ``start`` flipped."""
    out = bytearray(data)
    for i in range(start, min(start + length, len(out))):
        out[i] ^= 0x5A
    return bytes(out)


def _member_data_offset(path: Path, member: str) -> int:
    """Where ``member``'s (compressed) bytes start in the zip ``path``."""
    with zipfile.ZipFile(path) as archive:
        info = archive.getinfo(member)
    raw = path.read_bytes()
    # Local header: 30 bytes, then the name and the extra field (lengths at 26 and 28).
    name_len = int.from_bytes(raw[info.header_offset + 26 : info.header_offset + 28], "little")
    extra_len = int.from_bytes(raw[info.header_offset + 28 : info.header_offset + 30], "little")
    return info.header_offset + 30 + name_len + extra_len


def _message(exc: pytest.ExceptionInfo[BaseException]) -> str:
    return str(exc.value)


# --------------------------------------------------------------------------- the critic


@pytest.fixture(scope="module")
def legacy(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Critic files of the former ``.npz`` format (the input of ``critic convert``): a
    small linear one (version 1) and the shipped cnn (version 2), rebuilt from the arrays
    of the shipped ONNX file."""
    onnx = pytest.importorskip("onnx")
    from onnx import numpy_helper

    folder = tmp_path_factory.mktemp("critic")
    rng = np.random.default_rng(0)
    n_crop = N_FEATURES - N_SCALARS
    meta = {"crop_shape": list(CROP_SHAPE)}
    np.savez_compressed(
        folder / "linear.npz",
        format=np.str_("heapgrasp-critic"),
        version=np.int64(1),
        mean=rng.random(N_FEATURES),
        scale=rng.random(N_FEATURES) + 0.5,
        components=rng.normal(size=(4, n_crop)).astype(np.float32),
        weights=rng.normal(size=4 + N_SCALARS + 1),
        threshold=np.float64(0.7),
        candidate_epsilon=np.float64(0.2),
        metadata=np.str_(json.dumps({**meta, "model": "linear", "command": "test"})),
    )
    model = onnx.load(DEFAULT_CRITIC)
    w = {i.name: numpy_helper.to_array(i) for i in model.graph.initializer}
    shipped = GraspCritic.load(DEFAULT_CRITIC)
    np.savez_compressed(
        folder / "cnn.npz",
        format=np.str_("heapgrasp-critic"),
        version=np.int64(2),
        **{f"net_{k}": w[k].astype(np.float64) for k in ARRAYS},
        mean=w["mean"].astype(np.float64),
        scale=w["scale"].astype(np.float64),
        components=np.zeros((0, n_crop), np.float32),
        weights=np.zeros(N_SCALARS + 1),
        threshold=np.float64(shipped.threshold),
        candidate_epsilon=np.float64(shipped.candidate_epsilon),
        metadata=np.str_(json.dumps({**meta, "model": "cnn", "command": "test"})),
    )
    return {"linear": folder / "linear.npz", "cnn": folder / "cnn.npz"}


def _onnx_critic_with(path: Path, change: Callable[[Any], None]) -> Path:
    """The shipped critic with ``change`` made to its ONNX model, sealed again."""
    onnx = pytest.importorskip("onnx")
    from heapgrasp.inference import META_SHA256, seal

    model = onnx.load(DEFAULT_CRITIC)
    change(model)
    keep = [(e.key, e.value) for e in model.metadata_props if e.key != META_SHA256]
    del model.metadata_props[:]
    for key, value in keep:
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    path.write_bytes(seal(model.SerializeToString()))
    return path


def _nan_mean(model: Any) -> None:
    from onnx import numpy_helper

    init = next(i for i in model.graph.initializer if i.name == "mean")
    a = numpy_helper.to_array(init).copy()
    a[0] = np.nan
    init.CopyFrom(numpy_helper.from_array(a, "mean"))


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as data:
        return {k: np.array(data[k]) for k in data.files}


def _critic_with(
    src: Path, out: Path, change: Callable[[dict[str, np.ndarray]], object] | None = None
) -> Path:
    """``src``'s arrays, changed by ``change``, written to ``out``."""
    arrays = _arrays(src)
    if change is not None:
        change(arrays)
    np.savez_compressed(out, **arrays)  # type: ignore[arg-type]
    return out


def _set(name: str, value: Any) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        arrays[name] = np.asarray(value)

    return change


def _poke(name: str, index: int, value: float) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        a = arrays[name].copy()
        a.flat[index] = value
        arrays[name] = a

    return change


def _meta(**changes: Any) -> Callable[[dict[str, np.ndarray]], None]:
    def change(arrays: dict[str, np.ndarray]) -> None:
        meta = json.loads(str(arrays["metadata"]))
        for k, v in changes.items():
            if v is None:
                meta.pop(k, None)
            else:
                meta[k] = v
        arrays["metadata"] = np.asarray(json.dumps(meta))

    return change


def test_valid_critic_files_load(legacy: dict[str, Path], tmp_path: Path) -> None:
    shipped = GraspCritic.load(DEFAULT_CRITIC)  # the shipped file passes every check
    assert shipped.model == "cnn"
    assert shipped.network.hparams["crop_shape"] == list(CROP_SHAPE)
    for name in ("linear", "cnn"):
        arrays, meta = read_critic_arrays(legacy[name])
        assert meta["crop_shape"] == list(CROP_SHAPE) and arrays["scale"].min() > 0
    # critic convert: the former file becomes the same critic
    out = convert_npz(legacy["cnn"], tmp_path / "cnn.onnx", command="test")
    back = GraspCritic.load(out)
    assert back.model == "cnn" and back.metadata["converted"]["from"] == "cnn.npz"
    x = np.random.default_rng(0).random((50, N_FEATURES)).round()
    np.testing.assert_array_equal(back.probability(x), shipped.probability(x))
    linear = GraspCritic.load(convert_npz(legacy["linear"], tmp_path / "linear.onnx"))
    assert linear.model == "linear" and linear.threshold == pytest.approx(0.7)


def test_weights_error_type() -> None:
    err = WeightsError(Path("/x/critic.npz"), "NaN in 'mean'")
    assert isinstance(err, ValueError) and isinstance(err, HeapgraspError)
    assert str(err) == "/x/critic.npz: NaN in 'mean'"
    assert err.path == Path("/x/critic.npz") and err.problem == "NaN in 'mean'"
    back = pickle.loads(pickle.dumps(err))  # worker processes send errors back
    assert type(back) is WeightsError and str(back) == str(err)


def test_broken_critic_files(legacy: dict[str, Path], tmp_path: Path) -> None:
    data = legacy["cnn"].read_bytes()
    cases = {
        "empty.npz": (b"", r"empty file \(0 bytes\)"),
        "truncated.npz": (data[: len(data) // 2], "corrupt or truncated .*its end is missing"),
        "tail.npz": (data[:-10], "its end is missing"),
        "junk.npz": (b"this is not a zip archive", r"truncated grasp critic .*: not a zip"),
        "npy.npz": (b"\x93NUMPY" + bytes(100), "not a zip archive"),
    }
    for name, (content, match) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(WeightsError, match=match) as exc:
            read_critic_arrays(path)
        assert _message(exc).startswith(f"{path}: "), name
        assert exc.value.path == path
    # The ONNX critic: the same failures, named the same way.
    onnx_data = DEFAULT_CRITIC.read_bytes()
    cases = {
        "empty.onnx": (b"", r"empty file \(0 bytes\)"),
        "truncated.onnx": (onnx_data[: len(onnx_data) // 2], "not a valid ONNX model"),
        "tail.onnx": (onnx_data[:-10], "not a valid ONNX model"),
        "junk.onnx": (b"this is not a network", "not a valid ONNX model"),
        "critic.npz": (data, r"a zip archive \(a PyTorch .pt or numpy .npz file\?\)"),
    }
    for name, (content, match) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(WeightsError, match=match) as exc:
            GraspCritic.load(path)
        assert _message(exc).startswith(f"{path}: "), name


def test_garbled_critic_is_caught_by_its_checksums(legacy: dict[str, Path], tmp_path: Path) -> None:
    src = legacy["cnn"]
    offset = _member_data_offset(src, "scale.npy")
    path = tmp_path / "garbled.npz"
    path.write_bytes(_garble(src.read_bytes(), offset + 200))
    match = r"garbled\.npz: corrupt .*member 'scale\.npy' is garbled"
    with pytest.raises(WeightsError, match=match):
        read_critic_arrays(path)
    # Garbled in a zip header too: still a WeightsError naming the file.
    header = tmp_path / "header.npz"
    header.write_bytes(_garble(src.read_bytes(), 0, 8))
    with pytest.raises(WeightsError, match=r"header\.npz: "):
        read_critic_arrays(header)
    # The ONNX file: weights garbled in place still parse; its SHA-256 does not match.
    data = DEFAULT_CRITIC.read_bytes()
    onnx_path = tmp_path / "garbled.onnx"
    onnx_path.write_bytes(_garble(data, len(data) // 3, 16))
    with pytest.raises(WeightsError, match=r"garbled\.onnx: garbled: .*SHA-256"):
        GraspCritic.load(onnx_path)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (_poke("mean", 17, np.nan), r"NaN in 'mean' \(1 of 2196 values, first at index 17\)"),
        (_poke("mean", 3, np.inf), r"infinity in 'mean' \(1 of 2196 values, first at index 3\)"),
        (_poke("weights", 0, -np.inf), "infinity in 'weights'"),
        (_poke("components", 5, np.nan), r"NaN in 'components' .*first at index \(0, 5\)"),
        (_poke("scale", 12, 0.0), r"zero or negative scale: 1 of 2196 .*index 12: 0\.0"),
        (_poke("scale", 40, -1.0), "zero or negative scale"),
        (_poke("scale", 2, np.nan), "NaN in 'scale'"),
        (_set("mean", np.zeros(100)), r"shape of 'mean' is \(100,\), expected \(2196,\)"),
        (_set("weights", np.zeros(3)), r"shape of 'weights' is \(3,\), expected \(17,\)"),
        (_set("components", np.zeros(5)), "'components' is float64 array of shape .*2 dim"),
        (_set("mean", np.zeros(N_FEATURES, np.int64)), "dtype of 'mean' is int64, expected a fl"),
        (_set("scale", np.ones(N_FEATURES, bool)), "dtype of 'scale' is bool"),
        (_set("mean", np.full(N_FEATURES, "1.0")), "dtype of 'mean' is <U3"),
        (_set("threshold", np.nan), "'threshold' is nan, expected a number in"),
        (_set("threshold", 1.5), "'threshold' is 1.5"),
        (_set("candidate_epsilon", "0.2"), "dtype of 'candidate_epsilon' is <U3"),
        (_set("threshold", [0.5, 0.6]), "'threshold' is float64 array of shape \\(2,\\)"),
        (_set("format", "heapgrasp-weights"), "format is 'heapgrasp-weights', not a heapgrasp"),
        (_set("version", 3), "unsupported critic version 3"),
        (_set("version", 1.0), "dtype of 'version' is float64, expected an integer"),
        (_set("metadata", "{not json"), "metadata is not valid JSON"),
        (_set("metadata", "[1, 2]"), "metadata is a JSON list, not an object"),
        (_meta(crop_shape=None), "metadata field 'crop_shape' missing"),
        (_meta(crop_shape=[7, 13, 13]), r"metadata field 'crop_shape' is \[7, 13, 13\]"),
        (_meta(model="cnn"), "metadata field 'model' is 'cnn', expected 'linear'"),
    ],
)
def test_bad_linear_critic(
    legacy: dict[str, Path],
    tmp_path: Path,
    change: Callable[[dict[str, np.ndarray]], None],
    match: str,
) -> None:
    path = _critic_with(legacy["linear"], tmp_path / "bad.npz", change)
    with pytest.raises(WeightsError, match=match) as exc:
        read_critic_arrays(path)
    assert _message(exc).startswith(f"{path}: ")


@pytest.mark.parametrize("key", ["format", "version", "mean", "scale", "components", "metadata"])
def test_missing_critic_key(legacy: dict[str, Path], tmp_path: Path, key: str) -> None:
    path = _critic_with(legacy["linear"], tmp_path / "bad.npz", lambda a: a.pop(key))
    with pytest.raises(WeightsError, match=rf"bad\.npz: missing key '{key}'"):
        convert_npz(path, tmp_path / "never.onnx")
    assert not (tmp_path / "never.onnx").exists()


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (_poke("net_fc1_w", 7, np.nan), "NaN in 'net_fc1_w'"),
        (_poke("net_conv1_b", 0, np.inf), "infinity in 'net_conv1_b'"),
        (lambda a: a.pop("net_conv2_w"), "missing key 'net_conv2_w'"),
        (
            _set("net_conv2_w", np.zeros((16, 4, 3, 3, 3))),
            r"shape of 'net_conv2_w' is \(16, 4, 3, 3, 3\), expected \(16, 8, 3, 3, 3\)",
        ),
        (_set("net_fc2_b", np.zeros((1, 1))), r"shape of 'net_fc2_b' is \(1, 1\), expected \(1,\)"),
        (_set("net_fc1_b", np.zeros(64, np.int32)), "dtype of 'net_fc1_b' is int32"),
        (_poke("scale", 0, 0.0), "zero or negative scale"),
        (_meta(model="linear"), "metadata field 'model' is 'linear', expected 'cnn'"),
    ],
)
def test_bad_cnn_critic(
    legacy: dict[str, Path],
    tmp_path: Path,
    change: Callable[[dict[str, np.ndarray]], None],
    match: str,
) -> None:
    path = _critic_with(legacy["cnn"], tmp_path / "cnn.npz", change)
    with pytest.raises(WeightsError, match=match) as exc:
        read_critic_arrays(path)
    assert _message(exc).startswith(f"{path}: ")


def test_critic_path_that_is_not_a_file(tmp_path: Path) -> None:
    with pytest.raises(WeightsError, match=r"not a file"):
        GraspCritic.load(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"nothere\.onnx"):
        GraspCritic.load(tmp_path / "nothere.onnx")
    with pytest.raises(FileNotFoundError, match=r"nothere\.npz"):
        read_critic_arrays(tmp_path / "nothere.npz")


NAN_CRITIC = "output 'logits' holds NaN or infinity on an all-zero input"


def test_bad_critic_is_a_config_error_before_any_scene(tmp_path: Path) -> None:
    path = _onnx_critic_with(tmp_path / "nan.onnx", _nan_mean)
    with pytest.raises(ConfigError, match=rf"grasp_critic: {path}: {NAN_CRITIC}") as exc:
        make_critic(RunConfig(grasp_critic=str(path)))
    assert isinstance(exc.value.__cause__, WeightsError)


def _cli_refuses(args: list[str], out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    code = main(["run", "--scenes", "2", "--quiet", "--out", str(out), *args])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert not out.exists()  # refused before the run directory is made
    return err


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, NAN_CRITIC),
        (b"", "empty file"),
        (b"PK\x03\x04garbage", "a zip archive"),
        (b"garbage", "not a valid ONNX model"),
    ],
)
def test_heapgrasp_run_refuses_a_bad_critic(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes | None, match: str
) -> None:
    path = tmp_path / "bad.onnx"
    if content is None:
        _onnx_critic_with(path, _nan_mean)
    else:
        path.write_bytes(content)
    err = _cli_refuses(["--set", f"grasp_critic={path}"], tmp_path / "out", capsys)
    assert f"grasp_critic: {path}: " in err and match in err
    assert err.count(str(path)) == 1  # one message, not one per scene


# --------------------------------------------------------------------------- the networks


@pytest.fixture(scope="module")
def nets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Small valid grasp- and view-network files."""
    torch = pytest.importorskip("torch")
    from heapgrasp.training import GraspNet, ViewNet, save_weights

    folder = tmp_path_factory.mktemp("nets")
    torch.manual_seed(0)
    grasp = GraspNet(16, encoder_channels=(4, 8, 8), decoder_channels=(8, 8, 4))
    view = ViewNet(16, view_shape=(12, 6), encoder_channels=(4, 8, 8))
    return {
        "grasp": save_weights(grasp, folder / "grasp.pt", kind="grasp", command="test"),
        "view": save_weights(view, folder / "view.pt", kind="view", command="test"),
    }


def _payload(path: Path) -> dict[str, Any]:
    import torch

    data: dict[str, Any] = torch.load(path, weights_only=True)
    return data


def _net_with(src: Path, out: Path, change: Callable[[dict[str, Any]], None]) -> Path:
    import torch

    data = _payload(src)
    change(data)
    torch.save(data, out)
    return out


def _first_weight(data: dict[str, Any]) -> str:
    return str(next(k for k, v in data["state_dict"].items() if v.ndim > 1))


def _state(fn: Callable[[dict[str, Any], str], None]) -> Callable[[dict[str, Any]], None]:
    def change(data: dict[str, Any]) -> None:
        fn(data["state_dict"], _first_weight(data))

    return change


def _fill(value: float) -> Callable[[dict[str, Any], str], None]:
    def fn(state: dict[str, Any], name: str) -> None:
        state[name] = state[name].clone()
        state[name].view(-1)[1] = value

    return fn


def _entry(key: str, value: Any) -> Callable[[dict[str, Any]], None]:
    def change(data: dict[str, Any]) -> None:
        if value is _DROP:
            del data[key]
        else:
            data[key] = value

    return change


_DROP = object()


def test_valid_network_files_load(nets: dict[str, Path]) -> None:
    from heapgrasp.training import load_grasp_net, load_view_net, read_metadata

    assert load_grasp_net(nets["grasp"]).resolution == 16
    assert load_view_net(nets["view"]).view_shape == (12, 6)
    assert read_metadata(nets["grasp"])["command"] == "test"


@pytest.mark.parametrize("kind", ["grasp", "view"])
def test_broken_network_files(nets: dict[str, Path], tmp_path: Path, kind: str) -> None:
    from heapgrasp.training import load_grasp_net, load_view_net, read_metadata

    load = load_grasp_net if kind == "grasp" else load_view_net
    data = nets[kind].read_bytes()
    cases = {
        "empty.pt": (b"", r"empty file \(0 bytes\)"),
        "truncated.pt": (data[: len(data) // 2], "corrupt or truncated .*end is missing"),
        "junk.pt": (b"not a torch file at all", "corrupt or truncated .*not a zip archive"),
    }
    for name, (content, match) in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        for reader in (load, read_metadata):
            with pytest.raises(WeightsError, match=match) as exc:
                reader(path)
            assert _message(exc).startswith(f"{path}: "), name
    # torch.load reads garbled tensor bytes without a word: the archive's CRCs catch them.
    with zipfile.ZipFile(nets[kind]) as archive:
        member = next(n for n in archive.namelist() if "/data/" in n and "pkl" not in n)
    garbled = tmp_path / "garbled.pt"
    garbled.write_bytes(_garble(data, _member_data_offset(nets[kind], member) + 8))
    match = r"garbled\.pt: corrupt weights file: member '.*' is garbled .*CRC"
    with pytest.raises(WeightsError, match=match):
        load(garbled)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (_state(_fill(float("nan"))), r"weights hold NaN in '.*' \(1 of \d+ values\)"),
        (_state(_fill(float("inf"))), r"weights hold infinity in '.*' \(1 of \d+ values\)"),
        (_state(_fill(float("-inf"))), "weights hold infinity in"),
        (
            _state(lambda s, n: s.__setitem__(n, s[n][:1].clone())),
            r"weights do not match .*size mismatch for '.*': shape \(1, .*\) in the file, .* in "
            r"the network",
        ),
        (
            _state(lambda s, n: s.__setitem__(n, s[n].double())),
            r"dtype of '.*' is torch\.float64, the network's is torch\.float32",
        ),
        (
            _state(lambda s, n: s.__setitem__(n, s[n].half())),
            r"dtype of '.*' is torch\.float16",
        ),
        (_state(lambda s, n: s.pop(n)), r"weights do not match .*: missing tensor\(s\) '"),
        (
            _state(lambda s, n: s.__setitem__("extra.weight", s[n])),
            r"unexpected tensor\(s\) 'extra\.weight'",
        ),
        (_state(lambda s, n: s.__setitem__(n, 1.0)), "state_dict holds non-tensor entries"),
    ],
)
def test_bad_network_tensors(
    nets: dict[str, Path],
    tmp_path: Path,
    change: Callable[[dict[str, Any]], None],
    match: str,
) -> None:
    from heapgrasp.training import load_grasp_net, load_view_net

    for kind, load in (("grasp", load_grasp_net), ("view", load_view_net)):
        path = _net_with(nets[kind], tmp_path / f"{kind}.pt", change)
        with pytest.raises(WeightsError, match=match) as exc:
            load(path)
        assert _message(exc).startswith(f"{path}: ")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (_entry("format", "heapgrasp-critic"), "not a heapgrasp weights file"),
        (_entry("version", 0), "unsupported weights format version 0"),
        (_entry("version", True), "unsupported weights format version True"),
        (_entry("version", "1"), "unsupported weights format version '1'"),
        (_entry("version", 2), "unsupported weights format version 2"),
        (_entry("kind", "critic"), "unknown network kind 'critic'"),
        (_entry("architecture", _DROP), "metadata field 'architecture' missing"),
        (_entry("metadata", [1, 2]), "metadata field 'metadata' is a list, not a dict"),
        (_entry("state_dict", None), "entry 'state_dict' is a NoneType, not a dict"),
        (_entry("command", _DROP), "metadata field 'command' missing"),
        (_entry("created", 20260101), "metadata field 'created' is a int, not a str"),
        (_entry("resolution", "16"), "metadata field 'resolution' is '16', not a grid side"),
        (_entry("resolution", 24), "metadata field 'resolution' is 24, the architecture's is 16"),
    ],
)
def test_bad_network_metadata(
    nets: dict[str, Path],
    tmp_path: Path,
    change: Callable[[dict[str, Any]], None],
    match: str,
) -> None:
    from heapgrasp.training import load_grasp_net

    path = _net_with(nets["grasp"], tmp_path / "meta.pt", change)
    with pytest.raises(WeightsError, match=match) as exc:
        load_grasp_net(path)
    assert _message(exc).startswith(f"{path}: ")


def test_network_payload_with_code_is_refused(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    from fractions import Fraction

    from heapgrasp.training import read_metadata

    path = tmp_path / "pickled.pt"
    torch.save({"format": "heapgrasp-weights", "x": Fraction(1, 2)}, path)
    with pytest.raises(WeightsError, match=r"pickled\.pt: corrupt or truncated .*not a heapgrasp"):
        read_metadata(path)


def test_network_path_that_is_not_a_file(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from heapgrasp.training import load_view_net

    with pytest.raises(WeightsError, match="not a file"):
        load_view_net(tmp_path)


def test_bad_network_is_a_config_error_before_any_scene(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The run loads the networks' ONNX files (heapgrasp.inference); a bad one stops it
    before any scene."""
    torch = pytest.importorskip("torch")
    onnx = pytest.importorskip("onnx")
    from heapgrasp.inference import META_SHA256, seal
    from heapgrasp.loop.stages import make_grasp_planner, make_view_scorer
    from heapgrasp.training import GraspNet, ViewNet, export_onnx
    from onnx import numpy_helper

    def nan_copy(src: Path, out: Path) -> Path:
        model = onnx.load(src)
        init = next(i for i in model.graph.initializer if numpy_helper.to_array(i).size > 10)
        a = numpy_helper.to_array(init).copy()
        a.flat[1] = np.nan
        init.CopyFrom(numpy_helper.from_array(a, init.name))
        keep = [(e.key, e.value) for e in model.metadata_props if e.key != META_SHA256]
        del model.metadata_props[:]
        for key, value in keep:
            entry = model.metadata_props.add()
            entry.key, entry.value = key, value
        out.write_bytes(seal(model.SerializeToString()))
        return out

    torch.manual_seed(0)
    small = {"encoder_channels": (4, 8, 8)}
    grasp = export_onnx(
        GraspNet(40, decoder_channels=(8, 8, 4), **small), tmp_path / "g0.onnx", provenance={}
    )
    view = export_onnx(ViewNet(40, **small), tmp_path / "v0.onnx", provenance={})
    grasp, view = nan_copy(grasp, tmp_path / "g.onnx"), nan_copy(view, tmp_path / "v.onnx")
    nan = "holds NaN or infinity on an all-zero input"
    config = RunConfig.from_mapping({"grasp_planner": "network", "grasp_weights": str(grasp)})
    with pytest.raises(ConfigError, match=rf"grasp_weights: {grasp}: output '.*' {nan}"):
        make_grasp_planner(config)
    config = RunConfig.from_mapping({"view_planner": "network", "view_weights": str(view)})
    with pytest.raises(ConfigError, match=rf"view_weights: {view}: output 'scores' {nan}"):
        make_view_scorer(config)
    args = ["--grasp-planner", "network", "--grasp-weights", str(grasp)]
    err = _cli_refuses(args, tmp_path / "out", capsys)
    assert f"grasp_weights: {grasp}: output" in err
    empty = tmp_path / "empty.onnx"
    empty.write_bytes(b"")
    args = ["--view-planner", "network", "--view-weights", str(empty)]
    err = _cli_refuses(args, tmp_path / "out2", capsys)
    assert f"view_weights: {empty}: empty file" in err


def test_copied_shipped_critic_still_loads(tmp_path: Path) -> None:
    copy = tmp_path / "critic.onnx"
    shutil.copy(DEFAULT_CRITIC, copy)
    assert GraspCritic.load(copy).threshold == pytest.approx(0.6)
