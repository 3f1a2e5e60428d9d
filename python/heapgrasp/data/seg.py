"""The segmentation network's synthetic dataset: simulated scenes rendered as RGB images
with exact 4-class label masks (:mod:`heapgrasp.sim.seg_render`), written as the folder
``heapgrasp seg train`` reads (the layout of the user's own images)::

    OUT/images/scene000012__v03.png   RGB
    OUT/masks/scene000012__v03.png    class ids: 0 background, 1 transparent,
                                      2 specular, 3 opaque
    OUT/manifest.json                 what was asked, what was made
    OUT/shard-00000.npz               the images of scenes 0 .. shard_size − 1 (done marker)

For every scene (seed derived from the dataset's root seed and the scene's index): 1 to
``max_objects`` objects of the dataset's object split, ``pile`` or ``packed``, in a
random scene group (``mixed`` half of the time, else all transparent, all specular or
all opaque), then ``views`` random camera poses (:func:`~heapgrasp.sim.seg_render.random_view`).
A scene left with no object after settling is dropped and counted.

Shards run as the other datasets' do (:mod:`heapgrasp.data.shards`: resumable, a
process pool, one PyBullet client per worker process): a shard's images are written
(each to a temporary file, then renamed), then its ``shard-*.npz`` marks it done; a
re-run redoes only unmarked shards and gives the same bytes. The train/validation split
of ``heapgrasp seg train`` keeps the views of a scene together (the stem's part before
``__``); a held-out set of other scenes is a dataset of another ``--seed``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np
import numpy.typing as npt

from heapgrasp.data.scenes import split_models
from heapgrasp.data.shards import DatasetSpec, ShardedConfig

if TYPE_CHECKING:
    from heapgrasp.sim.world import SimWorld

__all__ = ["FORMAT", "SegDataConfig", "image_stem", "scene_images"]

FORMAT = "heapgrasp-seg-data"
VERSION = 1
#: Scene groups and their probabilities.
GROUPS = (("mixed", 0.5), ("transparent", 1 / 6), ("specular", 1 / 6), ("opaque", 1 / 6))


def _settings() -> dict[str, Any]:
    from heapgrasp.sim.seg_render import CLASSES

    return {"classes": list(CLASSES)}


SPEC = DatasetSpec(FORMAT, VERSION, "segmentation dataset", _settings)


def image_stem(scene: int, view: int) -> str:
    """File stem of a scene's view (the split keeps a scene's views together)."""
    return f"scene{scene:06d}__v{view:02d}"


@dataclass(frozen=True)
class SegDataConfig(ShardedConfig):
    """What ``heapgrasp seg data`` makes."""

    views: int = 8
    """Images per scene."""
    width: int = 320
    height: int = 240
    max_objects: int = 6
    out_dir: str = ""
    """Where the images go: the dataset's directory (not part of its identity)."""

    spec: ClassVar[DatasetSpec] = SPEC

    def __post_init__(self) -> None:
        super().__post_init__()
        self.positive("views", "max_objects")
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 16 <= value <= 4096:
                raise ValueError(f"{name} must be an integer in [16, 4096], got {value!r}")

    def identity(self) -> dict[str, Any]:
        """The dataset's settings, its directory left out (a dataset may move)."""
        d = super().identity()
        d.pop("out_dir")
        return d

    def run_shard(self, shard: int) -> dict[str, Any]:
        """Writes the images of ``shard``'s scenes; returns its record."""
        return _shard(self, shard)


_WORLD: list[SimWorld] = []


def _world(library: Any) -> SimWorld:
    """This process's world (one PyBullet client per worker), holding ``library``."""
    from heapgrasp.sim.world import SimWorld

    if not _WORLD:
        _WORLD.append(SimWorld(library))
    world = _WORLD[0]
    world.library = library
    return world


def _write_png(array: npt.NDArray[np.uint8], path: Path) -> None:
    from PIL import Image

    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.png")
    try:
        Image.fromarray(array).save(tmp, format="PNG")
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def scene_images(
    config: SegDataConfig, index: int, library: Any = None
) -> list[tuple[npt.NDArray[np.uint8], npt.NDArray[np.uint8]]] | None:
    """The ``(rgb, classes)`` images of scene ``index``, or None when it is dropped."""
    from heapgrasp.sim.build import object_library
    from heapgrasp.sim.seg_render import random_view, render_view, scaled_camera

    if library is None:
        from heapgrasp.loop.config import RunConfig

        library = object_library(RunConfig())
    rng = np.random.default_rng(np.random.SeedSequence([config.root_seed, index]))
    world_seed = int(rng.integers(2**31))
    pool = split_models(library, config.split)
    n = int(rng.integers(1, config.max_objects + 1))
    chosen = [pool[i] for i in rng.choice(len(pool), size=min(n, len(pool)), replace=False)]
    layout: Literal["pile", "packed"] = "pile" if rng.random() < 0.5 else "packed"
    names = [g for g, _ in GROUPS]
    probs = np.asarray([p for _, p in GROUPS])
    group = names[int(rng.choice(len(names), p=probs / probs.sum()))]
    world = _world(library)
    world.reset(layout=layout, category=group, seed=world_seed, models=chosen)
    if not world.objects:
        return None
    camera = scaled_camera(config.width, config.height)
    out = []
    for _ in range(config.views):
        pose = random_view(rng, world.config.cube_size)
        out.append(render_view(world, pose, camera, rng))
    return out


def _shard(config: SegDataConfig, shard: int) -> dict[str, Any]:
    from heapgrasp.data.shards import run_scenes

    def sample(cfg: Any, index: int, library: Any) -> dict[str, Any] | None:
        images = scene_images(cfg, index, library)
        if images is None:
            return None
        return {"index": index, "images": images}

    if not config.out_dir:
        raise ValueError("out_dir must name the dataset's directory (where the images go)")
    out = Path(config.out_dir)
    (out / "images").mkdir(parents=True, exist_ok=True)
    (out / "masks").mkdir(parents=True, exist_ok=True)
    samples, scenes = run_scenes(config, shard, sample)
    scene_index, view = [], []
    for s in samples:
        for k, (rgb, classes) in enumerate(s["images"]):
            stem = image_stem(s["index"], k)
            _write_png(rgb, out / "images" / f"{stem}.png")
            _write_png(classes, out / "masks" / f"{stem}.png")
            scene_index.append(s["index"])
            view.append(k)
    return {
        "k": np.asarray(view, np.int64),
        "scene_index": np.asarray(scene_index, np.int64),
        "scenes": np.int64(len(scenes)),
        "dropped": np.int64(len(scenes) - len(samples)),
    }
