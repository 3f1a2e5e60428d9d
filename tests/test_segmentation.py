"""The 4-class segmentation network (HEAPGrasp §V): data folder checks, IoU, training →
ONNX export → the onnxruntime segmenter, the synthetic renderer, the CLI and the
``segmenter`` setting. Tiny: a resnet18 DeepLabv3+ on a handful of 64×64 images."""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")

from heapgrasp.cli import main
from heapgrasp.inference.errors import WeightsError
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.perception import segnet
from heapgrasp.perception.frames import Frame
from heapgrasp.perception.segnet import NetworkSegmenter
from heapgrasp.training import segmentation as seg
from heapgrasp.training.common import read_safetensors
from PIL import Image


def _toy_image(rng: np.random.Generator, h: int = 64, w: int = 64) -> tuple[Any, Any]:
    """Noise with a few coloured rectangles of classes 1..3."""
    rgb = rng.integers(60, 120, (h, w, 3)).astype(np.uint8)
    mask = np.zeros((h, w), np.uint8)
    colours = {1: (40, 200, 250), 2: (230, 230, 230), 3: (220, 30, 40)}
    for cls in (1, 2, 3):
        y, x = rng.integers(0, h - 16), rng.integers(0, w - 16)
        rgb[y : y + 14, x : x + 14] = colours[cls]
        mask[y : y + 14, x : x + 14] = cls
    return rgb, mask


def _write_folder(root: Path, n: int = 6, seed: int = 0) -> Path:
    rng = np.random.default_rng(seed)
    (root / "images").mkdir(parents=True)
    (root / "masks").mkdir()
    for i in range(n):
        rgb, mask = _toy_image(rng)
        Image.fromarray(rgb).save(root / "images" / f"img{i}.png")
        Image.fromarray(mask).save(root / "masks" / f"img{i}.png")
    return root


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("seg")
    data = _write_folder(base / "data")
    config = seg.SegTrainConfig(
        encoder="resnet18", epochs=1, batch=2, lr=1e-3, val_fraction=0.34, device="cpu"
    )
    seg.train(data, base / "run", config, progress=False)
    return base / "run"


# --------------------------------------------------------------------------- data


def test_constants_agree_across_layers() -> None:
    from heapgrasp.sim import seg_render

    assert seg.CLASSES == segnet.CLASSES == seg_render.CLASSES
    assert seg.SEG_KIND == segnet.SEG_KIND


def test_folder_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nowhere"):
        seg.SegFolder.open(tmp_path / "nowhere")
    root = _write_folder(tmp_path / "d", n=3)
    assert len(seg.SegFolder.open(root)) == 3
    (root / "masks" / "img1.png").unlink()
    with pytest.raises(ValueError, match=r"img1\.png: no mask"):
        seg.SegFolder.open(root)
    Image.fromarray(np.zeros((10, 12), np.uint8)).save(root / "masks" / "img1.png")
    with pytest.raises(ValueError, match=r"img1\.png: mask is 12x10"):
        seg.SegFolder.open(root)
    bad = np.zeros((64, 64), np.uint8)
    bad[3, 3] = 7
    Image.fromarray(bad).save(root / "masks" / "img1.png")
    with pytest.raises(ValueError, match=r"img1\.png: class id 7"):
        seg.SegFolder.open(root)


def test_split_is_deterministic_and_keeps_groups_together(tmp_path: Path) -> None:
    root = tmp_path / "d"
    (root / "images").mkdir(parents=True)
    (root / "masks").mkdir()
    for s in range(10):
        for v in range(3):
            Image.fromarray(np.zeros((16, 16, 3), np.uint8)).save(
                root / "images" / f"scene{s}__v{v}.png"
            )
            Image.fromarray(np.zeros((16, 16), np.uint8)).save(
                root / "masks" / f"scene{s}__v{v}.png"
            )
    folder = seg.SegFolder.open(root)
    train, val = folder.split(0.3)
    assert (train, val) == folder.split(0.3)
    assert val and train and not set(train) & set(val)
    scenes_val = {folder.stems[i].split("__")[0] for i in val}
    scenes_train = {folder.stems[i].split("__")[0] for i in train}
    assert not scenes_val & scenes_train


def test_iou_is_exact_on_hand_made_masks() -> None:
    truth = np.array([[0, 0, 1, 1], [2, 2, 3, 3]])
    pred = np.array([[0, 1, 1, 1], [2, 0, 3, 0]])
    m = seg.iou_metrics(seg.confusion(pred, truth))
    # background: TP 1, FP 2 (pred 0 at truth 2, 3), FN 1 → 1/4
    assert m["iou_background"] == pytest.approx(1 / 4)
    assert m["iou_transparent"] == pytest.approx(2 / 3)
    assert m["iou_specular"] == pytest.approx(1 / 2)
    assert m["iou_opaque"] == pytest.approx(1 / 2)
    assert m["miou"] == pytest.approx((1 / 4 + 2 / 3 + 1 / 2 + 1 / 2) / 4)
    assert m["miou_objects"] == pytest.approx((2 / 3 + 1 / 2 + 1 / 2) / 3)
    assert m["pixel_accuracy"] == pytest.approx(5 / 8)
    # objects vs background: truth objects 6, predicted objects 5, both 4
    assert m["silhouette_iou"] == pytest.approx(4 / 7)
    empty = seg.iou_metrics(seg.confusion(np.zeros(4), np.zeros(4)))
    assert np.isnan(empty["iou_opaque"]) and empty["miou"] == 1.0


# --------------------------------------------------------------------------- model


def test_building_the_model_never_touches_the_network(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("a network connection was attempted")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    for encoder in seg.ENCODERS:
        net = seg.build_model(encoder)
        assert net.hparams() == {"encoder": encoder, "classes": 4}
    with pytest.raises(ValueError, match="'vgg16'"):
        seg.build_model("vgg16")


def test_encoder_weights_from_a_local_file(tmp_path: Path) -> None:
    import torch

    donor = seg.build_model("resnet18")
    state = {k: v.clone() for k, v in donor.model.encoder.state_dict().items()}
    state["fc.weight"] = torch.zeros(1000, 512)  # a torchvision checkpoint's classifier
    path = tmp_path / "resnet18.pth"
    torch.save(state, path)
    net = seg.build_model("resnet18", encoder_weights_file=path)
    got = net.model.encoder.state_dict()
    assert all(torch.equal(got[k], v) for k, v in donor.model.encoder.state_dict().items())
    with pytest.raises(WeightsError, match=r"resnet18\.pth.*not mobilenet_v2 encoder weights"):
        seg.build_model("mobilenet_v2", encoder_weights_file=path)
    with pytest.raises(FileNotFoundError, match=r"absent\.pth"):
        seg.build_model("resnet18", encoder_weights_file=tmp_path / "absent.pth")


def test_train_export_and_onnx_segmenter_match_torch(run_dir: Path) -> None:
    import torch

    for name in ("segmentation.onnx", "metrics.json", "metrics.png", "checkpoint.safetensors"):
        assert (run_dir / name).is_file(), name
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert set(metrics["val"]) >= {"iou_transparent", "miou", "pixel_accuracy", "confusion"}
    net = NetworkSegmenter(run_dir / "segmentation.onnx")
    assert net.classes == seg.CLASSES and net.name == "network"
    assert net.hparams["encoder"] == "resnet18"
    # the best epoch's weights, as the ONNX file holds them
    tnet = seg.build_model("resnet18")
    weights, _ = read_safetensors(run_dir / "best.safetensors", "weights")
    tnet.load_state_dict(weights)
    rgb, _ = _toy_image(np.random.default_rng(5), 70, 90)  # not a multiple of 16: padded
    got = net.logits(rgb)
    h, w = rgb.shape[:2]
    x, _ = seg._batch([(rgb, np.zeros((h, w), np.uint8))])
    with torch.no_grad():
        ref = tnet.eval()(x)[0, :, :h, :w].numpy()
    assert got.shape == (4, 70, 90)
    np.testing.assert_allclose(got, ref, atol=1e-3)
    labels = net.labels(Frame(np.eye(4), _camera(), rgb=rgb))
    assert labels.dtype == np.uint8 and labels.shape == (70, 90)
    np.testing.assert_array_equal(labels, seg.torch_predict(tnet)(rgb))
    mask = net.segment(Frame(np.eye(4), _camera(), rgb=rgb))
    np.testing.assert_array_equal(mask, labels != 0)
    with pytest.raises(ValueError, match="needs RGB frames"):
        net.segment(Frame(np.eye(4), _camera()))
    with pytest.raises(seg.TrainSetupError, match="--resume"):
        seg.train(
            run_dir.parent / "data",
            run_dir,
            seg.SegTrainConfig(encoder="resnet18", epochs=1, batch=2, val_fraction=0.34),
            progress=False,
        )


def _camera() -> Any:
    from heapgrasp.geometry.camera import CameraSpec

    return CameraSpec.continuous()


def test_bad_segmentation_files_raise_weights_errors(tmp_path: Path) -> None:
    from heapgrasp.inference import weights_dir

    with pytest.raises(FileNotFoundError, match=r"nothing\.onnx"):
        NetworkSegmenter(tmp_path / "nothing.onnx")
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"\x00not onnx at all" * 10)
    with pytest.raises(WeightsError, match=r"garbage\.onnx: not a valid ONNX model"):
        NetworkSegmenter(garbage)
    with pytest.raises(WeightsError, match="holds a 'grasp-critic'"):
        NetworkSegmenter(weights_dir() / "critic.onnx")


def test_garbled_segmentation_file_is_refused(run_dir: Path, tmp_path: Path) -> None:
    data = bytearray((run_dir / "segmentation.onnx").read_bytes())
    data[len(data) // 2] ^= 0xFF
    bad = tmp_path / "garbled.onnx"
    bad.write_bytes(bytes(data))
    with pytest.raises(WeightsError, match="garbled"):
        NetworkSegmenter(bad)


# --------------------------------------------------------------------------- synthetic data


def test_renderer_is_deterministic_and_labels_match_the_world() -> None:
    from heapgrasp.loop.config import RunConfig as RC
    from heapgrasp.sim.build import object_library, scene_world
    from heapgrasp.sim.seg_render import random_view, render_view, scaled_camera

    config = RC(objects=4, category="mixed", layout="packed")
    camera = scaled_camera(96, 72)
    library = object_library(config)
    results = []
    for _ in range(2):
        with scene_world(config, 3, "mixed", library=library) as world:
            rng = np.random.default_rng(11)
            views = []
            for _ in range(3):
                pose = random_view(rng)
                rgb, classes = render_view(world, pose, camera, rng)
                truth = world.capture(pose, camera, depth=False)
                np.testing.assert_array_equal(classes > 0, truth.mask)
                cats = {obj.category.value for obj in world.objects.values()}
                views.append((rgb, classes))
            results.append(views)
    for (a_rgb, a_cls), (b_rgb, b_cls) in zip(*results, strict=True):
        np.testing.assert_array_equal(a_rgb, b_rgb)
        np.testing.assert_array_equal(a_cls, b_cls)
    seen = set(np.unique(np.concatenate([c.ravel() for _, c in results[0]])).tolist())
    names = {seg.CLASSES[i] for i in seen}
    assert names >= {"background", *cats}, (names, cats)
    assert {"transparent", "specular", "opaque"} <= cats


def test_data_seg_writes_a_folder_seg_train_reads(tmp_path: Path) -> None:
    out = tmp_path / "synth"
    argv = ["seg", "data", str(out), "--scenes", "2", "--views", "2", "--size", "64x48"]
    argv += ["--workers", "1", "--shard-size", "1", "--quiet"]
    assert main(argv) == 0
    folder = seg.SegFolder.open(out)
    assert len(folder) == 4 and folder.read(0)[0].shape == (48, 64, 3)
    first = (out / "images" / "scene000000__v00.png").read_bytes()
    (out / "shard-00000.npz").unlink()  # redo one shard: the same bytes
    assert main(argv) == 0
    assert (out / "images" / "scene000000__v00.png").read_bytes() == first
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["complete"] and manifest["samples"] == 4


# --------------------------------------------------------------------------- CLI and config


def test_seg_cli_errors_exit_2_naming_the_value(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["seg", "train", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "missing" in capsys.readouterr().err
    args = ["seg", "train", str(tmp_path), "--out", str(tmp_path / "o"), "--encoder", "vgg"]
    assert main(args) == 2
    assert "'vgg'" in capsys.readouterr().err
    assert main(["seg", "train", str(tmp_path), "--out", "o", "--batch", "1"]) == 2
    assert "must be >= 2" in capsys.readouterr().err
    assert (
        main(
            [
                "seg",
                "predict",
                str(tmp_path / "w.onnx"),
                str(tmp_path / "x.png"),
                "--out",
                str(tmp_path / "p"),
            ]
        )
        == 2
    )
    assert "x.png" in capsys.readouterr().err
    img = tmp_path / "x.png"
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(img)
    assert main(["seg", "predict", str(tmp_path / "w.onnx"), str(img), "--out", "p"]) == 2
    assert "w.onnx" in capsys.readouterr().err
    assert main(["seg", "data", str(tmp_path / "d"), "--size", "10x10"]) == 2
    assert "10x10" in capsys.readouterr().err


def test_seg_eval_and_predict(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    onnx = str(run_dir / "segmentation.onnx")
    data = run_dir.parent / "data"
    assert (
        main(["seg", "eval", onnx, str(data), "--json", str(tmp_path / "m.json"), "--quiet"]) == 0
    )
    out = capsys.readouterr().out
    assert "mIoU" in out and "transparent" in out
    doc = json.loads((tmp_path / "m.json").read_text())
    assert doc["images"] == 6 and 0.0 <= doc["pixel_accuracy"] <= 1.0
    img = data / "images" / "img0.png"
    assert main(["seg", "predict", onnx, str(img), "--out", str(tmp_path / "p"), "--quiet"]) == 0
    pred = json.loads((tmp_path / "p" / "predictions.json").read_text())
    assert sum(pred["images"][str(img)].values()) == pytest.approx(1.0)
    assert (tmp_path / "p" / "img0_mask.png").is_file()


class _NoTruth:
    def silhouette(self, frame: object) -> np.ndarray:
        raise AssertionError("not called here")


def test_segmenter_setting(run_dir: Path, tmp_path: Path) -> None:
    from heapgrasp.loop.stages import make_segmenter
    from heapgrasp.perception.segmenters import IdealSegmenter

    assert RunConfig().segmenter == "truth"
    with pytest.raises(ConfigError, match="segmenter: must be one of truth, network"):
        RunConfig(segmenter="magic")
    with pytest.raises(ConfigError, match="seg_weights: segmenter = 'network' needs"):
        RunConfig(segmenter="network")
    with pytest.raises(ConfigError, match=r"seg_weights: file not found: .*absent\.onnx"):
        RunConfig(segmenter="network", seg_weights=str(tmp_path / "absent.onnx"))
    onnx = str(run_dir / "segmentation.onnx")
    with pytest.raises(ConfigError, match="noise"):
        RunConfig(segmenter="network", seg_weights=onnx, noise=0.05)
    config = RunConfig(segmenter="network", seg_weights=onnx)
    assert isinstance(make_segmenter(config, truth=None), NetworkSegmenter)
    with pytest.raises(ConfigError, match="scene truth"):  # the simulator's needs its truth
        make_segmenter(RunConfig(), truth=None)
    assert isinstance(make_segmenter(RunConfig(), truth=_NoTruth()), IdealSegmenter)
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"junk")
    with pytest.raises(ConfigError, match=r"seg_weights: .*bad\.onnx"):
        make_segmenter(RunConfig(segmenter="network", seg_weights=str(bad)), truth=None)
