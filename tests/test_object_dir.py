"""Users bring their own objects (issue 38 §5): ``--object-dir DIR`` whose subfolders are
PyBullet objects (``model.urdf`` beside its meshes), concave collision meshes used as
their convex decomposition, and a clear message for every kind of bad input."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from heapgrasp.cli import main
from heapgrasp.loop.config import ConfigError, RunConfig
from heapgrasp.sim.build import object_library
from heapgrasp.sim.mesh_files import load_mesh
from heapgrasp.sim.object_model import MAX_COLLISION_PIECES
from heapgrasp.sim.objects import user_models
from scipy.spatial import ConvexHull

#: Small and fast: two upright objects, one grasp attempt (tests/test_rundir.py).
QUICK = ["--method", "no-vp", "--objects", "2", "--layout", "packed", "--quiet"]
QUICK_SETS = ["--set", "max_attempts=1"]
BENCH_QUICK = ["--scenes", "1", "--workers", "1", "--quiet", "--no-figures"]

ROLL_90 = "1.5707963267948966 0 0"
YAW_90 = "0 0 1.5707963267948966"


def _urdf(name: str, visual: str, collision: str | None = None) -> str:
    parts = [f'<robot name="{name}"><link name="base">', f"<visual>{visual}</visual>"]
    if collision is not None:
        parts.append(f"<collision>{collision}</collision>")
    return "".join([*parts, "</link></robot>"])


def _mesh_el(filename: str, xyz: str, rpy: str, scale: str) -> str:
    return (
        f'<origin xyz="{xyz}" rpy="{rpy}"/>'
        f'<geometry><mesh filename="{filename}" scale="{scale}"/></geometry>'
    )


def _u_mesh() -> trimesh.Trimesh:
    """A closed U (millimetres): 80 wide (x), 20 deep (y), 80 tall (z), arms 20 thick."""
    outline = [(0, 0), (80, 0), (80, 20), (80, 80), (60, 80), (60, 20), (20, 20), (20, 80)]
    outline += [(0, 80), (0, 20)]
    caps = [(0, 1, 2), (0, 2, 5), (0, 5, 6), (0, 6, 9), (9, 6, 7), (9, 7, 8), (5, 2, 3)]
    caps += [(5, 3, 4)]
    n = len(outline)
    vertices = [(x, 0.0, z) for x, z in outline] + [(x, 20.0, z) for x, z in outline]
    faces = [*caps, *[(c + n, b + n, a + n) for a, b, c in caps]]
    for i in range(n):
        j = (i + 1) % n
        faces += [(j, i, n + i), (j, n + i, n + j)]
    mesh = trimesh.Trimesh(np.array(vertices, dtype=float), np.array(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(80_000.0)
    return mesh


def _object_dir(root: Path) -> Path:
    """Two objects, YCB's layout: a convex box (its collision mesh a separate file with
    its own origin, coinciding with the visual) and a concave U in millimetres."""
    folder = root / "objects"
    box = folder / "box"
    box.mkdir(parents=True)
    trimesh.creation.box(extents=(0.08, 0.1, 0.12)).export(str(box / "box.obj"))
    shifted = trimesh.creation.box(extents=(0.08, 0.1, 0.12))
    shifted.apply_translation((0.2, 0.0, 0.0))
    shifted.export(str(box / "box_collision.stl"))
    (box / "model.urdf").write_text(
        _urdf(
            "box",
            _mesh_el("box.obj", "0.1 0 0", ROLL_90, "0.5 0.5 0.5"),
            # scale 0.5 and the same roll take the file's +0.2 m in x to +0.1 m: undone
            _mesh_el("box_collision.stl", "0 0 0", ROLL_90, "0.5 0.5 0.5"),
        )
    )
    u = folder / "ushape"
    u.mkdir()
    _u_mesh().export(str(u / "u.obj"))
    el = _mesh_el("u.obj", "0.3 -0.2 0.05", YAW_90, "0.001 0.001 0.001")
    (u / "model.urdf").write_text(_urdf("ushape", el, el))
    return folder


def _bounds(path: Path) -> np.ndarray:
    vertices, _ = load_mesh(path)
    return np.stack([vertices.min(axis=0), vertices.max(axis=0)])


def _inside(hull: ConvexHull, point: list[float]) -> bool:
    return bool(np.all(hull.equations[:, :3] @ np.asarray(point) + hull.equations[:, 3] < 0))


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path / "cache"
    monkeypatch.setenv("HEAPGRASP_CACHE", str(root))
    return root / "objects"


# ------------------------------------------------------------------------ the loader
def test_subfolders_load_with_origins_scales_and_convex_pieces(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = _object_dir(tmp_path)
    t0 = time.perf_counter()
    box, u = user_models(folder, cache)
    first_s = time.perf_counter() - t0
    assert (box.name, u.name) == ("user/box", "user/ushape")

    # The box: scale 0.5, rolled 90 deg about x; its collision mesh (another file, its own
    # origin) is convex, used as it is, and lies exactly on the visual mesh.
    np.testing.assert_allclose(box.extents, (0.04, 0.06, 0.05), atol=1e-6)
    assert len(box.collision_meshes) == 1 and box.collision_meshes[0] != box.visual_mesh
    np.testing.assert_allclose(
        _bounds(box.collision_meshes[0]), _bounds(box.visual_mesh), atol=1e-6
    )

    # The U: millimetres scaled to metres, turned 90 deg about z; concave, so its
    # collision is its convex decomposition: several convex pieces on the U that leave
    # its opening (y in +-2 cm, z above -2 cm in the object frame) empty.
    np.testing.assert_allclose(u.extents, (0.02, 0.08, 0.08), atol=1e-6)
    assert 1 < len(u.collision_meshes) <= MAX_COLLISION_PIECES
    visual = _bounds(u.visual_mesh)
    volume = 0.0
    for piece in u.collision_meshes:
        vertices, faces = load_mesh(piece)
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        assert mesh.is_convex, piece
        bounds = _bounds(piece)
        assert np.all(bounds[0] >= visual[0] - 0.003) and np.all(bounds[1] <= visual[1] + 0.003)
        for point in ([0.0, 0.0, 0.02], [0.0, 0.01, 0.0], [0.0, -0.01, 0.03]):
            assert not _inside(ConvexHull(vertices), point), (piece, point)
        volume += mesh.volume
    assert 8e-5 * 0.9 < volume < 1.28e-4 * 0.9  # the U is 80 cm³, its convex hull 128 cm³

    # Cached by content: the second load runs no decomposition and gives the same files.
    import heapgrasp.sim.decomposition as decomposition

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("pybullet.vhacd ran again")

    before = {p: p.read_bytes() for m in (box, u) for p in (m.visual_mesh, *m.collision_meshes)}
    monkeypatch.setattr(decomposition, "_vhacd", refuse)
    t0 = time.perf_counter()
    again = user_models(folder, cache)
    assert time.perf_counter() - t0 < max(0.5, first_s / 4)
    assert again == [box, u]
    assert {p: p.read_bytes() for p in before} == before
    # The same mesh elsewhere (a plain file, already in metres and centred) is the same
    # content: the same cached decomposition.
    flat = tmp_path / "flat"
    flat.mkdir()
    shutil.copy(u.visual_mesh, flat / "u_again.obj")
    (same,) = user_models(flat, cache)
    assert same.name == "user/u_again" and same.collision_meshes == u.collision_meshes


def test_the_run_library_holds_the_users_objects_only_in_the_evaluated_split(
    tmp_path: Path, cache: Path
) -> None:
    folder = _object_dir(tmp_path)
    (folder / "notes").mkdir()  # no model.urdf: skipped, said
    skipped: list[str] = []
    for split in ("test", "train"):
        config = RunConfig(object_dir=str(folder), split=split)
        library = object_library(config, on_skip=skipped.append)
        assert [m.name for m in library] == ["user/box", "user/ushape"]
        assert [m.split for m in library] == [split, split]
    assert len(skipped) == 2
    assert all(s.startswith(f"skipped {folder / 'notes'}: no model.urdf, ") for s in skipped)
    with pytest.warns(UserWarning, match="notes: no model.urdf"):
        user_models(folder, cache)  # the library's default: a warning


# ------------------------------------------------------------------------ the command line
def test_run_object_dir_smoke_records_the_dir_and_the_objects(
    tmp_path: Path, cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _object_dir(tmp_path)
    out = tmp_path / "run"
    # two scenes in two worker processes: the option reaches them through the config
    argv = ["run", "--object-dir", str(folder), *QUICK, *QUICK_SETS, "--out", str(out)]
    assert main([*argv, "--scenes", "2", "--workers", "2"]) == 0
    capsys.readouterr()
    results = json.loads((out / "results.json").read_text())
    assert results["object_dir"] == str(folder) == results["config"]["object_dir"]
    assert results["scenes_completed"] == 2 and not results["scenes_failed"]
    used = results["objects_used"]
    assert used and set(used) <= {"user/box", "user/ushape"}
    records = [json.loads(line) for line in (out / "scenes.jsonl").read_text().splitlines()]
    assert sorted({o["name"] for r in records for o in r["world"]["objects"]}) == used
    assert json.loads((out / "config.json").read_text())["object_dir"] == str(folder)

    # An object that cannot be used is skipped by name, the others still run (as in
    # viewsphere bench); the results already written are not touched.
    written = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    (folder / "broken").mkdir()
    (folder / "broken" / "model.urdf").write_text(
        _urdf("broken", _mesh_el("gone.obj", "0 0 0", "0 0 0", "1 1 1"))
    )
    assert main(["run", "--resume", "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "skipped user/broken: broken/model.urdf: mesh file not found" in err
    assert "Traceback" not in err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == written
    # Nothing usable left: refused, naming each object and its problem.
    only = tmp_path / "only-broken"
    shutil.copytree(folder / "broken", only / "broken")
    argv = ["run", "--object-dir", str(only), *QUICK, "--out", str(tmp_path / "r2")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "none of the 1 objects in" in err and "mesh file not found" in err
    assert not (tmp_path / "r2" / "scenes.jsonl").exists()


def test_help_says_scenes_are_the_users_objects_only(capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["run", "--help"], ["bench", "sim", "--help"]):
        assert main(argv) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "--object-dir DIR" in text
        assert "Scenes are drawn from these objects only, all of them treated as the " in text
        assert "evaluated split" in text


def _bad(root: Path, case: str) -> Path:
    folder = root / case
    folder.mkdir()
    if case == "no-urdf":
        (folder / "textures").mkdir()
        return folder
    obj = folder / case
    obj.mkdir()
    if case == "no-mesh":
        box = '<geometry><box size="0.05 0.05 0.05"/></geometry>'
        (obj / "model.urdf").write_text(_urdf(case, box, box))
    elif case == "bad-mesh":
        (obj / "scan.ply").write_text("garbage\n")
        (obj / "model.urdf").write_text(
            _urdf(case, _mesh_el("scan.ply", "0 0 0", "0 0 0", "1 1 1"))
        )
    else:  # too large: 45 cm, or a 6 cm box written in millimetres
        size = 0.45 if case == "too-large" else 60.0
        trimesh.creation.box(extents=(size, size / 2, size / 3)).export(str(obj / "m.stl"))
        (obj / "model.urdf").write_text(_urdf(case, _mesh_el("m.stl", "0 0 0", "0 0 0", "1 1 1")))
    return folder


@pytest.mark.parametrize(
    ("case", "says"),
    [
        ("missing", ["object_dir: user object directory not found: ", "missing"]),
        ("no-urdf", ["skipped ", "no-urdf/textures: no model.urdf", "no objects in "]),
        ("no-mesh", ["no-mesh/model.urdf: URDF ", "has no link with a <visual> mesh"]),
        ("bad-mesh", ["bad-mesh/model.urdf: cannot load mesh ", "scan.ply"]),
        ("too-large", ["user/too-large is 0.450 x 0.225 x 0.150 m, larger than the 0.3 m"]),
        ("millimetres", ["60.000 x 30.000 x 20.000 m", "looks like millimetres", "0.001"]),
    ],
)
def test_bad_object_dirs_exit_2_naming_the_file_and_the_problem(
    tmp_path: Path, cache: Path, capsys: pytest.CaptureFixture[str], case: str, says: list[str]
) -> None:
    folder = tmp_path / "missing" if case == "missing" else _bad(tmp_path, case)
    out = tmp_path / "run"
    for argv in (
        ["run", "--object-dir", str(folder), *QUICK, "--out", str(out)],
        [
            "bench",
            "sim",
            "--object-dir",
            str(folder),
            "--methods",
            "no-vp",
            *BENCH_QUICK,
            "--out",
            str(out),
        ],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        for text in says:
            assert text in err, (argv[0], text, err)
        assert "Traceback" not in err
    assert not (out / "scenes.jsonl").exists()
    with pytest.raises(ConfigError, match="object_dir: must be a directory path"):
        RunConfig(object_dir="")


def test_objects_named_in_any_script_load(tmp_path: Path, cache: Path) -> None:
    # the name went into an ASCII-only OBJ header and the object was skipped
    folder = tmp_path / "unicode"
    folder.mkdir()
    trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(str(folder / "objé.obj"))
    trimesh.creation.box(extents=(0.04, 0.06, 0.07)).export(str(folder / "my object ü 🍎.obj"))
    models = user_models(folder, cache)
    assert [m.name for m in models] == ["user/my object ü 🍎", "user/objé"]
    assert all(m.visual_mesh.is_file() for m in models)


def test_a_flat_mesh_is_skipped_not_decomposed(tmp_path: Path, cache: Path) -> None:
    # one triangle: V-HACD ran for minutes on it (no output); now refused by name at once
    folder = tmp_path / "flat"
    folder.mkdir()
    (folder / "sheet.obj").write_text("v 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nf 1 2 3\n")
    trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(str(folder / "box.obj"))
    bad: list[tuple[str, str]] = []
    models = user_models(folder, cache, on_bad=lambda name, problem: bad.append((name, problem)))
    assert [m.name for m in models] == ["user/box"]
    assert [name for name, _ in bad] == ["user/sheet"] and "sheet.obj" in bad[0][1]


def test_a_junk_mesh_file_is_named_as_such(tmp_path: Path, cache: Path) -> None:
    # random bytes under .stl: trimesh reached for an optional text decoder, and the
    # message was "No module named 'charset_normalizer'"
    folder = tmp_path / "junk"
    folder.mkdir()
    (folder / "noise.stl").write_bytes(np.random.default_rng(0).bytes(3000))
    trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(str(folder / "box.obj"))
    bad: list[tuple[str, str]] = []
    models = user_models(folder, cache, on_bad=lambda name, problem: bad.append((name, problem)))
    assert [m.name for m in models] == ["user/box"]
    ((name, problem),) = bad
    assert name == "user/noise" and "noise.stl" in problem
    assert "not a valid STL file" in problem and "module" not in problem


def test_a_decomposition_that_runs_too_long_is_stopped(tmp_path: Path) -> None:
    # V-HACD is C code that cannot be interrupted where it runs: it runs in a child
    # process, stopped at the bound, and the object is skipped with the reason
    from heapgrasp.sim.decomposition import _vhacd

    mesh = trimesh.creation.annulus(r_min=0.02, r_max=0.04, height=0.05)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    with pytest.raises(ValueError, match=r"ran past 0.01 s and was stopped"):
        _vhacd(vertices, faces, tmp_path, timeout=0.01)
    assert len(_vhacd(vertices, faces, tmp_path)) > 1  # unbounded enough: the pieces


def test_the_common_download_layouts_load_without_a_urdf(tmp_path: Path, cache: Path) -> None:
    folder = tmp_path / "ycb"
    layouts = {
        "003_cracker_box": "google_16k/textured.obj",  # YCB's download
        "004_sugar_box": "poisson/nontextured.ply",
        "scanned_shoe": "meshes/model.obj",  # Google Scanned Objects
        "005_tomato_soup_can": "textured_simple.obj",  # iGibson's copy
    }
    for name, path in layouts.items():
        (folder / name / path).parent.mkdir(parents=True)
        trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(str(folder / name / path))
    # Both scans present: the finer one is taken.
    trimesh.creation.box(extents=(0.02, 0.02, 0.02)).export(
        str(folder / "003_cracker_box" / "google_16k" / "nontextured.ply")
    )
    (folder / "003_cracker_box" / "tsdf").mkdir()
    trimesh.creation.box(extents=(0.01, 0.01, 0.01)).export(
        str(folder / "003_cracker_box" / "tsdf" / "textured.obj")
    )
    (folder / "notes").mkdir()
    (folder / "notes" / "readme.txt").write_text("not an object")
    skipped: list[str] = []
    models = user_models(folder, cache, on_skip=skipped.append)
    assert [m.name for m in models] == [f"user/{n}" for n in sorted(layouts)]
    for m in models:
        v, _ = load_mesh(m.visual_mesh)
        np.testing.assert_allclose(sorted(np.ptp(v, axis=0)), [0.05, 0.06, 0.08], atol=1e-6)
    assert len(skipped) == 1 and "notes" in skipped[0]
    assert "google_16k/textured.obj" in skipped[0] and "meshes/model.obj" in skipped[0]


def test_a_folder_with_several_urdfs_and_no_known_mesh_asks_which(
    tmp_path: Path, cache: Path
) -> None:
    folder = tmp_path / "objs"
    sub = folder / "019_pitcher_base"
    sub.mkdir(parents=True)
    trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(str(sub / "base.stl"))
    for urdf in ("base.urdf", "rescale_base.urdf"):
        (sub / urdf).write_text(_urdf("b", '<geometry><mesh filename="base.stl"/></geometry>'))
    skipped: list[str] = []
    with pytest.raises(ValueError, match="no objects"):
        user_models(folder, cache, on_skip=skipped.append)
    assert "base.urdf, rescale_base.urdf" in skipped[0] and "which one?" in skipped[0]
    # With the download's mesh beside them, the mesh is the object.
    trimesh.creation.box(extents=(0.05, 0.06, 0.08)).export(str(sub / "nontextured.ply"))
    (model,) = user_models(folder, cache)
    assert model.name == "user/019_pitcher_base"
