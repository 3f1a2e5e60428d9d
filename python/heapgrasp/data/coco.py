"""COCO annotations → the segmentation folder ``heapgrasp seg train`` reads.

A COCO instance file (``images``, ``annotations``, ``categories``) labels objects with
polygons (or uncompressed RLE for crowds); the 4-class network (HEAPGrasp §V) needs one
class id per pixel: 0 background, 1 transparent, 2 specular, 3 opaque. :func:`convert`
maps every COCO category to one of those classes by name, rasterises each annotation
(COCO's pixel grid: ``(0, 0)`` is the top-left corner of the top-left pixel; a pixel
is inside where its centre is)
in decreasing area, so that a small object in front of a large one keeps its pixels,
and writes ``OUT/images/NAME.png`` and ``OUT/masks/NAME.png`` (grey, class ids).

Errors name the file and the entry: a category mapped to no class (unless
``unmapped="background"``), an image missing on disk or of another size than the file
says, an annotation of an unknown image, a polygon with fewer than 3 points, compressed
RLE (decode it with pycocotools first).
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["CLASS_IDS", "CocoError", "convert", "parse_class_map"]

#: The network's object classes and their ids in the masks.
CLASS_IDS = {"background": 0, "transparent": 1, "specular": 2, "opaque": 3}


class CocoError(ValueError):
    """A COCO file that cannot be converted; the message names the file and the entry."""


def parse_class_map(items: list[str]) -> dict[str, str]:
    """``["transparent=glass,bottle", "opaque=box"]`` → ``{"glass": "transparent", ...}``:
    COCO category name → class."""
    out: dict[str, str] = {}
    for item in items:
        cls, sep, names = item.partition("=")
        cls = cls.strip()
        if not sep or cls not in CLASS_IDS:
            raise CocoError(
                f"--class {item!r}: expected CLASS=NAME[,NAME...] with CLASS one of "
                f"{', '.join(CLASS_IDS)}"
            )
        for name in (n.strip() for n in names.split(",")):
            if not name:
                continue
            if name in out and out[name] != cls:
                raise CocoError(f"--class: category {name!r} is both {out[name]} and {cls}")
            out[name] = cls
    return out


def _rle(counts: Any, h: int, w: int, where: str) -> npt.NDArray[np.bool_]:
    if isinstance(counts, str):
        raise CocoError(f"{where}: compressed RLE; decode it with pycocotools first")
    runs = np.asarray(counts, dtype=np.int64)
    if runs.ndim != 1 or (runs < 0).any() or int(runs.sum()) != h * w:
        raise CocoError(f"{where}: RLE counts do not add up to the image's {h} x {w} pixels")
    flat = np.zeros(h * w, dtype=bool)
    pos = 0
    for i, n in enumerate(runs):
        if i % 2:
            flat[pos : pos + n] = True
        pos += int(n)
    return flat.reshape(w, h).T  # COCO's RLE runs down the columns


def _polygons(polys: Any, h: int, w: int, where: str) -> npt.NDArray[np.bool_]:
    """The pixels whose centres lie inside any of the polygons (COCO's coordinates:
    pixel ``(u, v)`` spans ``[u, u + 1) × [v, v + 1)``, its centre at ``+0.5``)."""
    from matplotlib.path import Path as Polygon

    out = np.zeros((h, w), dtype=bool)
    for k, poly in enumerate(polys):
        xy = np.asarray(poly, dtype=np.float64).reshape(-1)
        if len(xy) < 6 or len(xy) % 2 or not np.isfinite(xy).all():
            raise CocoError(f"{where}: polygon {k} needs at least 3 finite (x, y) points")
        pts = xy.reshape(-1, 2)
        u0, v0 = np.clip(np.floor(pts.min(axis=0)).astype(int), 0, [w, h])
        u1, v1 = np.clip(np.ceil(pts.max(axis=0)).astype(int), 0, [w, h])
        if u1 <= u0 or v1 <= v0:
            continue
        uu, vv = np.meshgrid(np.arange(u0, u1) + 0.5, np.arange(v0, v1) + 0.5)
        inside = Polygon(pts).contains_points(np.column_stack([uu.ravel(), vv.ravel()]))
        out[v0:v1, u0:u1] |= inside.reshape(vv.shape)
    return out


def _integer(obj: Any, key: str, where: str) -> int:
    """``obj[key]`` as an integer; a :class:`CocoError` naming ``where`` and the key
    where it is missing or not a whole number."""
    if not isinstance(obj, dict):
        raise CocoError(f"{where}: must be an object, got {obj!r:.60}")
    if key not in obj:
        raise CocoError(f"{where}: no {key!r}")
    value = obj[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or value != int(value):
        raise CocoError(f"{where}: {key!r} must be a whole number, got {value!r:.60}")
    return int(value)


def _number(obj: dict[str, Any], key: str, where: str) -> float:
    value = obj[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise CocoError(f"{where}: {key!r} must be a number, got {value!r:.60}")
    return float(value)


def _text(obj: Any, key: str, where: str) -> str:
    if not isinstance(obj, dict):
        raise CocoError(f"{where}: must be an object, got {obj!r:.60}")
    value = obj.get(key)
    if not isinstance(value, str) or not value:
        raise CocoError(f"{where}: {key!r} must be a non-empty string, got {value!r:.60}")
    return value


def _output_stems(images: Mapping[int, dict[str, Any]], src: Path) -> dict[int, str]:
    """The output name of every image: its ``file_name`` without the extension, folders
    joined by ``__``; images that would share a name (``a.png`` and ``a.jpg``) keep their
    extension in it (``a_png``, ``a_jpg``); the same file named twice is an error."""
    plain = {
        i: Path(str(im["file_name"])).with_suffix("").as_posix().replace("/", "__")
        for i, im in images.items()
    }
    count: dict[str, int] = {}
    for stem in plain.values():
        count[stem] = count.get(stem, 0) + 1
    out: dict[int, str] = {}
    seen: dict[str, int] = {}
    for i, stem in plain.items():
        if count[stem] > 1:
            suffix = Path(str(images[i]["file_name"])).suffix.lstrip(".").lower()
            stem = f"{stem}_{suffix}" if suffix else stem
        if stem in seen:
            raise CocoError(
                f"{src}: images {seen[stem]} and {i} are the same file "
                f"{images[i]['file_name']!r}: each would overwrite the other's mask"
            )
        seen[stem] = i
        out[i] = stem
    return out


def convert(
    annotations: str | os.PathLike[str],
    images_dir: str | os.PathLike[str],
    out: str | os.PathLike[str],
    class_map: Mapping[str, str],
    *,
    unmapped: str = "error",
) -> dict[str, Any]:
    """Writes the segmentation folder of a COCO file (module docstring) and returns a
    summary: images written, annotations drawn, pixels per class."""
    src = Path(annotations)
    try:
        data = json.loads(src.read_text())
    except FileNotFoundError:
        raise CocoError(f"{src}: not found") from None
    except json.JSONDecodeError as exc:
        raise CocoError(f"{src}: not JSON: {exc}") from None
    if not isinstance(data, dict) or not all(
        isinstance(data.get(k), list) for k in ("images", "annotations", "categories")
    ):
        raise CocoError(f"{src}: a COCO file has lists 'images', 'annotations', 'categories'")
    if unmapped not in ("error", "background"):
        raise CocoError(f"unmapped must be 'error' or 'background', got {unmapped!r}")
    classes: dict[int, int] = {}
    missing = []
    for c, cat in enumerate(data["categories"]):
        where = f"{src}: categories[{c}]"
        cat_id = _integer(cat, "id", where)
        name = _text(cat, "name", where)
        if cat_id in classes:
            raise CocoError(f"{where}: category id {cat_id} appears twice")
        cls = class_map.get(name)
        if cls is None:
            missing.append(name)
            cls = "background"
        if cls not in CLASS_IDS:
            raise CocoError(f"category {name!r} maps to {cls!r}, not one of {', '.join(CLASS_IDS)}")
        classes[cat_id] = CLASS_IDS[cls]
    if missing and unmapped == "error":
        raise CocoError(
            f"{src}: categories mapped to no class: {', '.join(sorted(missing))} (map them "
            "with --class CLASS=NAME, or pass --unmapped background)"
        )
    images: dict[int, dict[str, Any]] = {}
    for i, im in enumerate(data["images"]):
        where = f"{src}: images[{i}]"
        image_id = _integer(im, "id", where)
        if image_id in images:  # one image's annotations would be painted on the other
            raise CocoError(f"{where}: image id {image_id} appears twice")
        _text(im, "file_name", where)
        _integer(im, "width", where)
        _integer(im, "height", where)
        images[image_id] = im
    stems = _output_stems(images, src)
    by_image: dict[int, list[dict[str, Any]]] = {i: [] for i in images}
    for a, ann in enumerate(data["annotations"]):
        where = f"{src}: annotations[{a}]"
        image_id = _integer(ann, "image_id", where)
        if image_id not in images:
            raise CocoError(f"{where} names an unknown image {image_id}")
        _integer(ann, "category_id", where)
        if "area" in ann:
            _number(ann, "area", where)
        by_image[image_id].append({**ann, "_index": a})
    root = Path(images_dir)
    out_dir = Path(out)
    (out_dir / "images").mkdir(parents=True, exist_ok=True)
    (out_dir / "masks").mkdir(parents=True, exist_ok=True)
    from PIL import Image

    pixels = np.zeros(len(CLASS_IDS), dtype=np.int64)
    drawn = 0
    for image_id, im in images.items():
        path = root / str(im["file_name"])
        if not path.is_file():
            raise CocoError(f"{src}: image {image_id}: {path} not found")
        with Image.open(path) as img:
            w, h = img.size
        if (w, h) != (int(im["width"]), int(im["height"])):
            raise CocoError(
                f"{src}: image {image_id}: {path} is {w} x {h}, the file says "
                f"{im['width']} x {im['height']}"
            )
        mask = np.zeros((h, w), dtype=np.uint8)
        anns = sorted(by_image[image_id], key=lambda x: -float(x.get("area", 0.0)))
        for ann in anns:
            where = f"{src}: annotations[{ann['_index']}]"
            seg = ann.get("segmentation")
            if isinstance(seg, dict):
                region = _rle(seg.get("counts"), h, w, where)
            elif isinstance(seg, list):
                region = _polygons(seg, h, w, where)
            else:
                raise CocoError(f"{where}: no polygon or RLE segmentation")
            class_id = classes.get(int(ann.get("category_id", -1)))
            if class_id is None:
                raise CocoError(f"{where}: unknown category {ann.get('category_id')}")
            mask[region] = class_id
            drawn += 1
        stem = stems[image_id]
        if path.suffix.lower() == ".png":
            shutil.copyfile(path, out_dir / "images" / f"{stem}.png")
        else:
            with Image.open(path) as img:
                img.convert("RGB").save(out_dir / "images" / f"{stem}.png")
        Image.fromarray(mask).save(out_dir / "masks" / f"{stem}.png")
        pixels += np.bincount(mask.ravel(), minlength=len(CLASS_IDS))[: len(CLASS_IDS)]
    return {
        "images": len(images),
        "annotations": drawn,
        "pixels": {name: int(pixels[i]) for name, i in CLASS_IDS.items()},
        "unmapped_as_background": sorted(missing),
    }
