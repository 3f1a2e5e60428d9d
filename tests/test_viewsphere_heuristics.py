"""Seed 001's heuristic policies (viewsphere.heuristics) on synthetic states."""

from __future__ import annotations

import math

import numpy as np
import pytest
from heapgrasp import grasp_region, surfel_visibility
from heapgrasp.perception.clouds import backproject, project
from heapgrasp.viewsphere.grasps import VIEWSPHERE_CAMERA
from heapgrasp.viewsphere.heuristics import (
    Heuristic2D,
    Heuristic3D,
    InformationGain,
    ViewsphereScorer,
    information_gain_viewpoints,
)
from heapgrasp.viewsphere.policies import (
    ViewState,
    run_episode,
    run_viewpoint_episode,
)
from heapgrasp.viewsphere.sphere import DIRECTIONS, DiscreteViewsphere, SpherePose

SPHERE = DiscreteViewsphere()
SCORER = ViewsphereScorer(SPHERE, VIEWSPHERE_CAMERA)
#: The camera west of the object (azimuth π), 40° from above.
WEST = SpherePose(math.pi, math.radians(40.0))


def _grid(lo: tuple[float, float, float], hi: tuple[float, float, float], step: float):
    axes = [np.arange(a, b + 1e-9, step) for a, b in zip(lo, hi, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _wall_and_hidden_block():
    """A wall of object points (x = 0.02, facing the camera in the west) and an
    unexplored block behind it, low on the table: only views from the east or from
    above see the block."""
    wall = _grid((0.02, -0.06, 0.0), (0.02, 0.06, 0.10), 0.0075)
    block = _grid((0.035, -0.04, 0.0), (0.075, 0.04, 0.04), 0.0075)
    return wall, block


def _state(pose, obj, unexplored, visited=None):
    return ViewState(pose, visited or (pose,), 0, lambda poses: (obj, unexplored))


def test_project_inverts_backproject():
    pose = SPHERE.camera_pose(WEST)
    depth = np.full((VIEWSPHERE_CAMERA.height, VIEWSPHERE_CAMERA.width), 0.4, dtype=np.float32)
    depth[:, :100] = 0.0  # nothing measured there
    points = backproject(depth, VIEWSPHERE_CAMERA, pose)
    u, v, inside = project(points, VIEWSPHERE_CAMERA, pose)
    assert inside.all()
    assert u.min() == 100 and u.max() == VIEWSPHERE_CAMERA.width - 1
    assert v.min() == 0 and v.max() == VIEWSPHERE_CAMERA.height - 1
    # Out of range, behind the camera or off the image: not in view.
    far = pose[:3, 3] + 4.0 * pose[:3, 2]
    behind = pose[:3, 3] - 0.5 * pose[:3, 2]
    aside = pose[:3, 3] + 0.5 * pose[:3, 2] + 2.0 * pose[:3, 0]
    assert not project(np.array([far, behind, aside]), VIEWSPHERE_CAMERA, pose)[2].any()
    with pytest.raises(ValueError, match="NaN"):
        project(np.array([[np.nan, 0.0, 0.0]]), VIEWSPHERE_CAMERA, pose)


def test_next_views_skip_fallbacks_and_a_double_step_covers_twice_the_arc():
    low = SpherePose(0.0, math.radians(80.0))  # south of it is off the sphere
    one = SCORER.next_views(low)
    assert DIRECTIONS.index("S") not in [d for d, _ in one]
    for steps in (1, 2):
        for _, p in SCORER.next_views(WEST, steps):
            assert SPHERE.arc(WEST, p) == pytest.approx(steps * SPHERE.step)


def test_targets_keep_the_object_box_above_the_table():
    pts = np.array([[0.0, 0.0, 0.05], [0.2, 0.0, 0.05], [0.0, 0.0, -0.005], [0.0, 0.1, 0.35]])
    np.testing.assert_array_equal(SCORER.targets(pts), pts[:1])


def test_the_2d_heuristic_looks_past_the_wall():
    wall, block = _wall_and_hidden_block()
    h = Heuristic2D(SCORER)
    scores = {d: h.score(wall, block, p) for d, p in SCORER.next_views(WEST)}
    # Stepping north (up, toward the pole) looks over the wall; south hides the block.
    assert scores[DIRECTIONS.index("N")] > scores[DIRECTIONS.index("S")]
    assert h.choose(_state(WEST, wall, block)) in {DIRECTIONS.index(d) for d in ("N", "NE", "NW")}
    assert h.score(wall, np.zeros((0, 3)), WEST) == 0
    with pytest.raises(ValueError, match="closing_px"):
        Heuristic2D(SCORER, closing_px=0)


def test_surfels_hide_the_block_from_the_west_and_not_from_the_east():
    wall, block = _wall_and_hidden_block()
    normals = np.tile([-1.0, 0.0, 0.0], (len(wall), 1))
    east = SpherePose(0.0, math.radians(40.0))
    low_west = SpherePose(math.pi, math.radians(80.0))
    eyes = np.array([SPHERE.position(low_west), SPHERE.position(east)])
    clear = surfel_visibility(wall, normals, eyes, block, radius=0.0075)
    assert not clear[0].any()  # low in the west: the wall hides it all
    assert clear[1].all()


def test_the_grasp_region_follows_the_normals():
    wall, block = _wall_and_hidden_block()
    normals = np.tile([-1.0, 0.0, 0.0], (len(wall), 1))
    inside = grasp_region(wall, normals, block, half_length=0.08, radius=0.015)
    assert inside.all()  # the block lies along the wall's normals, within 8 cm
    beyond = block + np.array([0.1, 0.0, 0.0])
    assert not grasp_region(wall, normals, beyond, half_length=0.08, radius=0.015).any()


def test_the_3d_heuristic_heads_where_the_useful_points_show():
    wall, block = _wall_and_hidden_block()
    h = Heuristic3D(SCORER)
    h.reset(0)
    d = h.choose(_state(WEST, wall, block))
    assert d in {DIRECTIONS.index(x) for x in ("N", "NE", "NW")}
    # A cap on the useful points draws them at random, repeatably with the seed.
    small = Heuristic3D(SCORER, max_points=10)
    normals = SCORER.normals(wall)
    small.reset(3)
    first = small.useful(wall, normals, block)
    small.reset(3)
    np.testing.assert_array_equal(first, small.useful(wall, normals, block))
    assert len(first) == 10
    with pytest.raises(ValueError, match="lookahead_share"):
        Heuristic3D(SCORER, lookahead_share=1.5)


def test_the_3d_heuristic_looks_two_steps_ahead_when_one_shows_too_little():
    """From low in the west, no single step sees over a tall wall to the block; two
    steps north do, so the look-ahead picks north."""
    wall = _grid((0.02, -0.15, 0.0), (0.02, 0.15, 0.30), 0.0075)
    block = _grid((0.035, -0.03, 0.0), (0.06, 0.03, 0.02), 0.0075)
    low = SpherePose(math.pi, math.radians(80.0))
    h = Heuristic3D(SCORER)
    normals = SCORER.normals(wall)
    one = SCORER.visible_counts(wall, normals, block, [p for _, p in SCORER.next_views(low)])
    assert max(one) <= 0.15 * len(block)
    assert h.choose(_state(low, wall, block)) == DIRECTIONS.index("N")


def test_information_gain_viewpoints_are_the_papers_34():
    views = information_gain_viewpoints()
    assert len(views) == 34 and all(SPHERE.valid(v) for v in views)
    polar = np.round(np.degrees([v.polar for v in views]), 6)
    assert sorted(set(polar.tolist())) == pytest.approx(
        sorted({round(180 / 6.5, 6), 22.5, 45.0, 67.5})
    )
    assert [int((polar == p).sum()) for p in (22.5, 45.0, 67.5)] == [9, 12, 12]
    azimuths = np.degrees([v.azimuth for v in views if abs(math.degrees(v.polar) - 45.0) < 1e-9])
    assert not ((azimuths > 161) & (azimuths < 199)).any()


def test_information_gain_flies_to_the_best_view_and_counts_its_arc():
    wall, block = _wall_and_hidden_block()
    policy = InformationGain(SCORER)
    best = policy.choose_view(_state(WEST, wall, block))
    # The best view sees the block from the east (azimuth within 90° of 0).
    assert math.cos(best.azimuth) > 0
    found_after = {1}

    def grasp_found(keys):
        return len(keys) - 1 in found_after

    episode = run_viewpoint_episode(
        policy, grasp_found, start=WEST, observe=lambda poses: (wall, block)
    )
    assert episode.found and episode.steps == 1 and episode.directions == ()
    assert episode.travelled == pytest.approx(SPHERE.arc(WEST, episode.poses[1]))

    class Stuck:
        name = "stuck"

        def reset(self, seed):
            pass

        def choose_view(self, state):
            return state.pose

    with pytest.raises(ValueError, match="stuck chose"):
        run_viewpoint_episode(Stuck(), lambda keys: False, start=WEST)


def test_a_stepping_episode_travels_a_step_per_move():
    wall, block = _wall_and_hidden_block()
    episode = run_episode(
        Heuristic2D(SCORER),
        lambda keys: len(keys) == 3,
        start=WEST,
        observe=lambda poses: (wall, block),
    )
    assert episode.steps == 2
    assert episode.travelled == pytest.approx(2 * SPHERE.step)


# ----------------------------------------------------------- HEAPGrasp's view scoring
def _box_world():
    import trimesh
    from heapgrasp.viewsphere.world import ViewsphereWorld

    box = trimesh.creation.box(extents=(0.04, 0.16, 0.10))
    box.apply_translation((0.0, 0.0, 0.05))
    return ViewsphereWorld([(box.vertices, box.faces)])


def test_heapgrasp_views_carve_silhouettes_and_the_oracle_scores_them():
    from heapgrasp.viewsphere.heapgrasp_views import HeapgraspViewPolicy

    world = _box_world()
    policy = HeapgraspViewPolicy(
        world.sphere, world.camera, world.silhouette, "oracle", scene=world.objects_scene
    )
    start = world.start
    policy.carve((start,))
    before = policy.grid.count_high_confidence()
    assert before > 0
    policy.carve((start,))  # carved once
    assert policy.grid.count_high_confidence() == before
    views = policy._views.next_views(start)
    scores = policy.oracle_scores([p for _, p in views])
    assert scores.shape == (len(views),) and (scores >= 0).all() and scores.max() > 0
    # The chosen direction is the best-scoring one.
    d = policy.choose(ViewState(start, (start,), 0))
    assert d == views[int(np.argmax(scores))][0]
    # Carving the chosen view leaves less to carve: its own score drops to ~0.
    chosen = dict(views)[d]
    policy.carve((chosen,))
    assert policy.oracle_scores([chosen])[0] == pytest.approx(0.0, abs=1e-6)
    policy.reset(0)
    assert policy.grid.count_high_confidence() == 0
    with pytest.raises(ValueError, match="scene"):
        HeapgraspViewPolicy(world.sphere, world.camera, world.silhouette, "oracle")


def test_the_view_network_scores_the_nearest_candidates():
    from heapgrasp.inference import shipped_weights
    from heapgrasp.planning.view_network import NetworkViewScorer
    from heapgrasp.viewsphere.heapgrasp_views import HeapgraspViewPolicy

    path = shipped_weights("view-network")
    assert path is not None, "the view network ships with the package"
    world = _box_world()
    network = NetworkViewScorer(str(path))
    policy = HeapgraspViewPolicy(
        world.sphere,
        world.camera,
        world.silhouette,
        "network",
        scene=world.objects_scene,
        network=network,
    )
    policy.carve((world.start,))
    u_n, v_n = network.view_shape
    # Two views in one candidate's cell read the same score; a view below the lowest
    # ring reads the lowest ring's.
    cell = 2 * math.pi / u_n
    a = SpherePose(3 * cell, math.radians(10.0))
    b = SpherePose(3 * cell + 0.3 * cell, math.radians(10.5))
    low = SpherePose(3 * cell, math.radians(80.0))
    edge = SpherePose(3 * cell, math.radians(36.0) * (v_n - 1) / v_n)
    s = policy.network_scores(world.start, [a, b, low, edge])
    assert s[0] == s[1] and s[2] == s[3]
    policy.choose(ViewState(world.start, (world.start,), 0))
    assert len(policy.agreement) == 1
