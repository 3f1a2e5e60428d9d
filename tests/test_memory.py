"""Scene memory: a phase starting from what the previous phases carved
(``SilhouettePerception(memory=True)``, ``RunConfig.scene_memory``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from box_scenes import Box, box_scene
from fake_robot import FrameMasks, MaskedFrame
from heapgrasp.geometry.camera import CameraSpec
from heapgrasp.geometry.grid import GridFrame
from heapgrasp.geometry.motion import look_at
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.perception.segmenters import IdealSegmenter
from heapgrasp.perception.silhouette import SilhouettePerception
from scipy import ndimage

MASKS = IdealSegmenter(FrameMasks())

FRAME = GridFrame((-0.15, -0.15, 0.0), 0.30, 40)
SPEC = CameraSpec()
BOX_A = ((-0.05, 0.0, 0.0225), (0.05, 0.05, 0.045))
BOX_B = ((0.05, 0.0, 0.03), (0.04, 0.04, 0.06))


def _frames(boxes: list[Box], eyes: list[np.ndarray]) -> list[MaskedFrame]:
    """Ideal frames of axis-aligned boxes ``(centre, extents)`` from ``eyes``, each
    looking at the middle of the table."""
    scene = box_scene(boxes)
    out = []
    for eye in eyes:
        pose = look_at(eye, (0.0, 0.0, 0.0))
        mask = scene.render_mask(SPEC.core(), pose)
        out.append(MaskedFrame(cam2world=pose, camera=SPEC, mask=mask))
    return out


def _circle(n: int = 8, theta: float = math.radians(36.0), r: float = 0.33) -> list[np.ndarray]:
    return [
        r
        * np.array(
            [
                math.sin(theta) * math.cos(2 * math.pi * k / n),
                math.sin(theta) * math.sin(2 * math.pi * k / n),
                math.cos(theta),
            ]
        )
        for k in range(n)
    ]


TOP = [np.array([0.0, 0.001, 0.6])]


def _high(p: SilhouettePerception) -> np.ndarray:
    return p.grid.high_confidence(p.lam) > 0


def _voxels_of(box: Box) -> np.ndarray:
    """Grid cells whose centres lie inside ``box``."""
    (c, e) = box
    r, size = FRAME.resolution, FRAME.size
    steps = (np.arange(r) + 0.5) * size / r
    inside = [np.abs(FRAME.origin[i] + steps - c[i]) <= e[i] / 2 for i in range(3)]
    return inside[0][:, None, None] & inside[1][None, :, None] & inside[2][None, None, :]


def test_a_phase_keeps_what_the_last_one_carved_and_loses_the_object_taken() -> None:
    memory = SilhouettePerception(FRAME, MASKS, memory=True)
    memory.update(_frames([BOX_A, BOX_B], _circle()))
    phase1 = _high(memory)
    seen1 = memory.grid.counts()[1] > 0
    assert phase1[_voxels_of(BOX_A)].all() and phase1[_voxels_of(BOX_B)].all()
    memory.remember()
    memory.reset()
    assert memory.frames_seen == 0 and memory.memory_record is None
    # Box A was taken; the next phase's first frame looks from above.
    top = _frames([BOX_B], TOP)
    memory.update(top)
    assert memory.memory_record == {"restored_voxels": 0, "kept": True}
    kept = _high(memory)
    assert not kept[_voxels_of(BOX_A)].any()  # the object taken is carved
    assert kept[_voxels_of(BOX_B)].all()  # the one left is all there ...
    # ... and as tight as the eight views of the last phase left it (within a voxel of
    # the margin), where the top frame alone leaves a tall column over it.
    fresh = SilhouettePerception(FRAME, MASKS)
    fresh.update(top)
    # (Voxels the last phase never saw, high above the tables, are the new frames' to
    # fill.)
    assert (kept[seen1] <= ndimage.binary_dilation(phase1)[seen1]).all()
    assert kept[seen1].sum() < 0.6 * _high(fresh)[seen1].sum()
    # The critic's camera positions are the phase's own (where the object was taken,
    # only they have carved).
    assert len(memory.camera_positions()) == 1


def test_an_object_that_moved_into_remembered_space_drops_the_memory() -> None:
    memory = SilhouettePerception(FRAME, MASKS, memory=True)
    memory.update(_frames([BOX_A, BOX_B], _circle()))
    memory.remember()
    memory.reset()
    moved = ((0.05, 0.08, 0.03), (0.04, 0.04, 0.06))  # box B pushed 8 cm along y
    top = _frames([BOX_A, moved], TOP)
    memory.update(top)
    record = memory.memory_record
    assert record is not None and not record["kept"]
    assert record["restored_voxels"] > memory.memory_tolerance
    fresh = SilhouettePerception(FRAME, MASKS)
    fresh.update(top)
    np.testing.assert_array_equal(memory.grid.high_confidence(0.9), fresh.grid.high_confidence(0.9))
    assert _high(memory)[_voxels_of(moved)].all()


def test_without_memory_a_phase_starts_from_nothing() -> None:
    plain = SilhouettePerception(FRAME, MASKS)
    plain.update(_frames([BOX_A, BOX_B], _circle()))
    plain.remember()
    plain.reset()
    assert plain.grid.count_high_confidence(0.9) == 0
    plain.update(_frames([BOX_B], TOP))
    assert plain.memory_record is None


def test_forget_drops_the_remembered_hull() -> None:
    memory = SilhouettePerception(FRAME, MASKS, memory=True)
    memory.update(_frames([BOX_A, BOX_B], _circle()))
    memory.remember()
    memory.forget()
    memory.reset()
    assert memory.grid.count_high_confidence(0.9) == 0
    assert len(memory.camera_positions()) == 0


@pytest.mark.parametrize("bad", [-1, 2.5, True])
def test_a_bad_memory_tolerance_is_refused(bad: object) -> None:
    with pytest.raises(ValueError, match="memory_tolerance"):
        SilhouettePerception(FRAME, MASKS, memory=True, memory_tolerance=bad)  # type: ignore[arg-type]


def test_scene_memory_must_be_a_boolean() -> None:
    with pytest.raises(ConfigError, match="scene_memory"):
        RunConfig().replace({"scene_memory": "yes"})
    assert RunConfig().replace({"scene_memory": True}).scene_memory
