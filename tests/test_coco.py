"""COCO annotations → the segmentation folder (heapgrasp.data.coco, ``heapgrasp seg coco``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from heapgrasp.cli import main
from heapgrasp.data.coco import CocoError, convert, parse_class_map
from PIL import Image


def _coco(tmp_path: Path, annotations: list[dict[str, object]]) -> Path:
    images = tmp_path / "photos"
    images.mkdir()
    Image.fromarray(np.full((20, 30, 3), 90, np.uint8)).save(images / "a.jpg")
    data = {
        "images": [{"id": 7, "file_name": "a.jpg", "width": 30, "height": 20}],
        "categories": [
            {"id": 1, "name": "glass"},
            {"id": 2, "name": "can"},
            {"id": 3, "name": "box"},
        ],
        "annotations": annotations,
    }
    path = tmp_path / "labels.json"
    path.write_text(json.dumps(data))
    return path


CLASSES = ["transparent=glass", "specular=can", "opaque=box"]


def test_polygons_and_rle_become_class_ids_smaller_objects_on_top(tmp_path: Path) -> None:
    # a 10 x 6 box (opaque) with a 4 x 2 glass (transparent) in front of it; a can by RLE
    box = [[2, 2, 12, 2, 12, 8, 2, 8]]
    glass = [[4, 4, 8, 4, 8, 6, 4, 6]]
    mask = np.zeros((20, 30), bool)
    mask[15:18, 20:25] = True  # rows 15-17, columns 20-24
    flat = mask.T.ravel()  # COCO's RLE runs down the columns
    runs, value, n = [], False, 0
    for v in flat:
        if v == value:
            n += 1
        else:
            runs.append(n)
            value, n = v, 1
    runs.append(n)
    counts = runs
    ann = [
        {"id": 1, "image_id": 7, "category_id": 1, "segmentation": glass, "area": 8},
        {"id": 2, "image_id": 7, "category_id": 3, "segmentation": box, "area": 60},
        {
            "id": 3,
            "image_id": 7,
            "category_id": 2,
            "segmentation": {"counts": counts, "size": [20, 30]},
            "area": 15,
            "iscrowd": 1,
        },
    ]
    path = _coco(tmp_path, ann)
    summary = convert(path, tmp_path / "photos", tmp_path / "out", parse_class_map(CLASSES))
    labels = np.asarray(Image.open(tmp_path / "out" / "masks" / "a.png"))
    assert labels.shape == (20, 30) and labels.dtype == np.uint8
    assert (labels[2:8, 2:12][labels[2:8, 2:12] != 1] == 3).all()  # the box, but the glass
    assert (labels[4:6, 4:8] == 1).all()  # drawn after the larger box
    assert (labels[15:18, 20:25] == 2).all()
    assert summary["pixels"]["specular"] == 15 and summary["pixels"]["transparent"] == 8
    assert summary["pixels"]["opaque"] == 60 - 8
    assert (tmp_path / "out" / "images" / "a.png").is_file()
    # the folder seg train reads
    from heapgrasp.training.segmentation import SegFolder

    assert len(SegFolder.open(tmp_path / "out").stems) == 1


def test_bad_input_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = _coco(tmp_path, [{"image_id": 7, "category_id": 1, "segmentation": [[1, 1, 2, 2]]}])
    with pytest.raises(CocoError, match="mapped to no class: box, can"):
        convert(path, tmp_path / "photos", tmp_path / "o", parse_class_map(["transparent=glass"]))
    with pytest.raises(CocoError, match=r"annotations\[0\]: polygon 0 needs at least 3"):
        convert(path, tmp_path / "photos", tmp_path / "o", parse_class_map(CLASSES))
    with pytest.raises(CocoError, match="CLASS one of"):
        parse_class_map(["glassy=glass"])
    path.write_text(
        json.dumps(
            {
                "images": [{"id": 7, "file_name": "a.jpg", "width": 31, "height": 20}],
                "categories": [{"id": 1, "name": "glass"}],
                "annotations": [],
            }
        )
    )
    with pytest.raises(CocoError, match=r"is 30 x 20, the file says 31 x 20"):
        convert(path, tmp_path / "photos", tmp_path / "o", {"glass": "transparent"})
    args = ["seg", "coco", str(path), "--images", str(tmp_path), "--out", str(tmp_path / "c")]
    assert main([*args, "--class", "transparent=glass"]) == 2
    assert "not found" in capsys.readouterr().err


def _write(tmp_path: Path, data: dict[str, object]) -> Path:
    path = tmp_path / "labels.json"
    path.write_text(json.dumps(data))
    return path


def test_images_of_one_stem_and_a_repeated_id_lose_nothing(tmp_path: Path) -> None:
    photos = tmp_path / "photos"
    photos.mkdir()
    for name, grey in (("a.jpg", 90), ("a.png", 160), ("b.png", 30)):
        Image.fromarray(np.full((20, 30, 3), grey, np.uint8)).save(photos / name)
    box = [[2, 2, 12, 2, 12, 12, 2, 12]]
    images = [
        {"id": 1, "file_name": "a.jpg", "width": 30, "height": 20},
        {"id": 2, "file_name": "a.png", "width": 30, "height": 20},
        {"id": 3, "file_name": "b.png", "width": 30, "height": 20},
    ]
    data = {
        "images": images,
        "categories": [{"id": 1, "name": "glass"}],
        "annotations": [{"image_id": 2, "category_id": 1, "segmentation": box}],
    }
    out = tmp_path / "out"
    summary = convert(_write(tmp_path, data), photos, out, {"glass": "transparent"})
    written = sorted(p.name for p in (out / "images").iterdir())
    assert summary["images"] == 3 and written == ["a_jpg.png", "a_png.png", "b.png"]
    assert sorted(p.name for p in (out / "masks").iterdir()) == written
    # the annotation is on a.png's mask only
    assert np.asarray(Image.open(out / "masks" / "a_png.png")).any()
    assert not np.asarray(Image.open(out / "masks" / "a_jpg.png")).any()
    # one id for two images: refused before anything is written
    data["images"] = [images[0], {**images[2], "id": 1}]
    again = tmp_path / "again"
    with pytest.raises(CocoError, match=r"images\[1\]: image id 1 appears twice"):
        convert(_write(tmp_path, data), photos, again, {"glass": "transparent"})
    assert not again.exists()


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"categories": [{"name": "glass"}]}, r"categories\[0\]: no 'id'"),
        ({"categories": ["glass"]}, r"categories\[0\]: must be an object"),
        ({"images": [{"id": 7, "width": 30, "height": 20}]}, r"'file_name' must be"),
        ({"images": [{"id": 7, "file_name": "a.jpg", "height": 20}]}, r"no 'width'"),
        ({"images": [{"id": "a", "file_name": "a.jpg"}]}, r"'id' must be a whole number"),
        (
            {"annotations": [{"image_id": 7, "category_id": 1, "area": "a", "segmentation": []}]},
            r"annotations\[0\]: 'area' must be a number, got 'a'",
        ),
    ],
)
def test_malformed_entries_are_named(tmp_path: Path, change: dict[str, object], named: str) -> None:
    path = _coco(tmp_path, [])
    data = {**json.loads(path.read_text()), **change}
    classes = parse_class_map(CLASSES)
    with pytest.raises(CocoError, match=named):
        convert(_write(tmp_path, data), tmp_path / "photos", tmp_path / "o", classes)
    assert not (tmp_path / "o").exists()
