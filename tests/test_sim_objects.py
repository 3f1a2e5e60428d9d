"""Tests of the simulation object library (``heapgrasp.sim.objects``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import heapgrasp as hg
import numpy as np
import pybullet as pb
import pybullet_data
import pytest
import trimesh
from heapgrasp.sim.mesh_files import load_mesh
from heapgrasp.sim.object_model import (
    MAX_COLLISION_PIECES,
    ObjectModel,
    default_cache_dir,
    split_of,
)
from heapgrasp.sim.objects import ObjectLibrary, pybullet_data_models, user_models
from heapgrasp.sim.procedural import generate_procedural

DATA = Path(pybullet_data.getDataPath())


def _tri(path: Path) -> Any:
    """The mesh file as an unprocessed ``trimesh.Trimesh``."""
    mesh = trimesh.load(str(path), force="mesh", process=False)
    assert isinstance(mesh, trimesh.Trimesh)
    return mesh


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*.obj"))}


@pytest.fixture(scope="module")
def procedural(tmp_path_factory: pytest.TempPathFactory) -> list[ObjectModel]:
    return generate_procedural(tmp_path_factory.mktemp("objects"), count_per_kind=2, seed=0)


# --------------------------------------------------------------------------- procedural
def test_procedural_names_and_layout(procedural: list[ObjectModel]) -> None:
    names = [m.name for m in procedural]
    assert len(names) == len(set(names)) == 10
    assert names[0] == "procedural/box_00" and names[-1] == "procedural/cup_01"
    for m in procedural:
        assert m.source == "procedural"
        assert m.visual_mesh.name == "visual.obj"
        assert m.visual_mesh.parent.parts[-2:] == tuple(m.name.split("/"))
        assert m.split == split_of(m.name)
        assert 0.02 <= m.mass <= 0.5


def test_procedural_visual_meshes_are_valid(procedural: list[ObjectModel]) -> None:
    for m in procedural:
        mesh = _tri(m.visual_mesh)
        assert mesh.is_watertight, m.name
        assert mesh.is_winding_consistent, m.name
        assert mesh.volume > 0, m.name  # outward normals
        ext = np.asarray(m.extents)
        np.testing.assert_allclose(ext, mesh.extents, atol=1e-9)
        assert np.all((ext >= 0.02) & (ext <= 0.15)), (m.name, ext)
        assert 0.04 <= ext[2] <= 0.14, (m.name, ext)
        assert min(ext[0], ext[1]) <= 0.07, (m.name, ext)  # fits an 8 cm gripper
        # object frame = bounding-box centre
        np.testing.assert_allclose(mesh.bounds[0], -mesh.bounds[1], atol=2e-9)


def test_procedural_collision_pieces_are_convex(procedural: list[ObjectModel]) -> None:
    for m in procedural:
        assert 1 <= len(m.collision_meshes) <= MAX_COLLISION_PIECES
        visual = _tri(m.visual_mesh)
        pieces = [_tri(p) for p in m.collision_meshes]
        for p, piece in zip(m.collision_meshes, pieces, strict=True):
            assert piece.is_convex, p
            assert piece.volume > 0, p
        union = trimesh.util.concatenate(pieces)
        # the union approximates the object: same box within a few mm
        np.testing.assert_allclose(union.bounds, visual.bounds, atol=4e-3)
        if m.name.split("/")[-1].startswith(("box", "cylinder")):
            assert m.collision_meshes == (m.visual_mesh,)


def test_cups_and_bowls_are_concave(procedural: list[ObjectModel]) -> None:
    concave = [m for m in procedural if m.name.split("/")[-1].startswith(("cup", "bowl"))]
    assert len(concave) == 4
    for m in concave:
        mesh = _tri(m.visual_mesh)
        assert mesh.convex_hull.volume > 1.8 * mesh.volume, m.name
        assert len(m.collision_meshes) >= 3
        assert all(_tri(p).is_convex for p in m.collision_meshes)


def test_procedural_is_deterministic_and_idempotent(tmp_path: Path) -> None:
    a = generate_procedural(tmp_path / "a", count_per_kind=1, seed=3)
    b = generate_procedural(tmp_path / "b", count_per_kind=2, seed=3)
    files_a = _files(tmp_path / "a")
    files_b = _files(tmp_path / "b")
    assert files_a  # object i does not depend on the count
    assert all(files_b[k] == v for k, v in files_a.items())
    assert [m.extents for m in a] == [m.extents for m in b if m.name.endswith("_00")]
    # regeneration rewrites nothing
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "a").rglob("*.obj")}
    again = generate_procedural(tmp_path / "a", count_per_kind=1, seed=3)
    assert again == a
    assert {p: p.stat().st_mtime_ns for p in (tmp_path / "a").rglob("*.obj")} == stamps
    # another seed: other names, other shapes
    c = generate_procedural(tmp_path / "a", count_per_kind=1, seed=4)
    assert {m.name for m in c}.isdisjoint(m.name for m in a)
    assert c[0].name == "procedural/seed4/box_00"
    assert c[0].visual_mesh.read_bytes() != a[0].visual_mesh.read_bytes()
    assert generate_procedural(tmp_path / "d", count_per_kind=0) == []


def test_procedural_manifest_skips_regeneration(tmp_path: Path, monkeypatch) -> None:
    import heapgrasp.sim.procedural as procedural

    first = generate_procedural(tmp_path, count_per_kind=1, seed=5)
    assert (tmp_path / "procedural/seed5/manifest.json").is_file()

    def boom(rng):  # any regeneration would call a maker
        raise AssertionError("regenerated although the manifest was valid")

    with monkeypatch.context() as m:
        m.setattr(procedural, "_MAKERS", {k: boom for k in procedural.PROCEDURAL_KINDS})
        assert generate_procedural(tmp_path, count_per_kind=1, seed=5) == first
        # other arguments are another key: regenerated
        with pytest.raises(AssertionError, match="regenerated"):
            generate_procedural(tmp_path, count_per_kind=2, seed=5)
    # a file changed on disk invalidates the manifest, and regeneration restores it
    good = first[0].visual_mesh.read_bytes()
    first[0].visual_mesh.write_bytes(good + b"# edited\n")
    with monkeypatch.context() as m:
        m.setattr(procedural, "_MAKERS", {k: boom for k in procedural.PROCEDURAL_KINDS})
        with pytest.raises(AssertionError, match="regenerated"):
            generate_procedural(tmp_path, count_per_kind=1, seed=5)
    assert generate_procedural(tmp_path, count_per_kind=1, seed=5) == first
    assert first[0].visual_mesh.read_bytes() == good
    # a damaged manifest is ignored
    (tmp_path / "procedural/seed5/manifest.json").write_text("{not json")
    assert generate_procedural(tmp_path, count_per_kind=1, seed=5) == first


def test_procedural_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="count_per_kind"):
        generate_procedural(tmp_path, count_per_kind=-1)
    with pytest.raises(ValueError, match="seed"):
        generate_procedural(tmp_path, seed=-2)


def test_procedural_meshes_are_closed_in_mesh_scene(procedural: list[ObjectModel]) -> None:
    scene = hg.MeshScene()
    for m in procedural:
        vertices, faces = load_mesh(m.visual_mesh)
        mesh_id = scene.add_mesh(vertices, faces, np.eye(4))
        assert scene.is_closed(mesh_id), m.name


def test_cup_holds_a_ball_in_pybullet(procedural: list[ObjectModel]) -> None:
    """The convex pieces make a cup hollow for the physics: a ball drops inside."""
    cup = next(m for m in procedural if "cup" in m.name)
    cid = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, -9.81, physicsClientId=cid)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
        pb.createMultiBody(0, plane, physicsClientId=cid)
        parts = [str(p) for p in cup.collision_meshes]
        shape = pb.createCollisionShapeArray(
            shapeTypes=[pb.GEOM_MESH] * len(parts), fileNames=parts, physicsClientId=cid
        )
        half = cup.extents[2] / 2
        body = pb.createMultiBody(
            cup.mass,
            shape,
            -1,
            [0, 0, half + 1e-3],
            baseInertialFramePosition=[0, 0, 0],
            physicsClientId=cid,
        )
        assert len(pb.getCollisionShapeData(body, -1, physicsClientId=cid)) == len(parts)
        sphere = pb.createCollisionShape(pb.GEOM_SPHERE, radius=0.008, physicsClientId=cid)
        ball = pb.createMultiBody(0.01, sphere, -1, [0, 0, 2 * half + 0.03], physicsClientId=cid)
        for _ in range(360):
            pb.stepSimulation(physicsClientId=cid)
        z = pb.getBasePositionAndOrientation(ball, physicsClientId=cid)[0][2]
        assert 0.008 + 0.003 < z < half  # on the base, inside the cup
    finally:
        pb.disconnect(cid)


# --------------------------------------------------------------------------- pybullet_data
def test_random_urdfs_are_scaled_and_recentred(tmp_path: Path) -> None:
    models = pybullet_data_models(tmp_path, [17, 0, 17, 42], mug=False)
    assert [m.name for m in models] == ["random_urdfs/017", "random_urdfs/000", "random_urdfs/042"]
    for m in models:
        stem = m.name.split("/")[-1]
        raw = _tri(DATA / "random_urdfs" / stem / f"{stem}.obj")
        mesh = _tri(m.visual_mesh)
        assert m.visual_mesh == tmp_path / "random_urdfs" / f"{stem}.obj"
        np.testing.assert_allclose(mesh.extents, 0.015 * raw.extents, atol=1e-8)
        np.testing.assert_allclose(m.extents, mesh.extents, atol=1e-9)
        assert 0.03 <= max(m.extents) <= 0.15
        np.testing.assert_allclose(mesh.bounds[0], -mesh.bounds[1], atol=2e-9)
        assert m.collision_meshes == (m.visual_mesh,)
        assert m.mass == pytest.approx(0.1)
        assert m.source == "pybullet_data"


def test_random_urdfs_typical_size(tmp_path: Path) -> None:
    models = pybullet_data_models(tmp_path, range(0, 40), mug=False)
    assert len(models) == 40
    largest = np.array([max(m.extents) for m in models])
    assert 0.06 < np.median(largest) < 0.15


def test_mug_frame_and_collision(tmp_path: Path) -> None:
    (mug,) = pybullet_data_models(tmp_path, [], mug=True)
    assert mug.name == "pybullet_data/mug"
    assert mug.mass == pytest.approx(1.0)
    np.testing.assert_allclose(mug.extents, (0.082, 0.1216, 0.1), atol=1e-3)
    mesh = _tri(mug.visual_mesh)
    np.testing.assert_allclose(mesh.bounds[0], -mesh.bounds[1], atol=2e-9)
    (collision,) = mug.collision_meshes
    assert collision != mug.visual_mesh
    # the collision mesh is shifted by the same offset as the visual mesh
    np.testing.assert_allclose(_tri(collision).bounds, mesh.bounds, atol=1e-3)


def test_invalid_random_urdfs(tmp_path: Path) -> None:
    # random_urdfs/168 ships with NaN vertices
    assert pybullet_data_models(tmp_path, [168], mug=False) == []
    with pytest.raises(ValueError, match="non-finite"):
        pybullet_data_models(tmp_path, [168], mug=False, skip_invalid=False)
    with pytest.raises(ValueError, match="1000"):
        pybullet_data_models(tmp_path, [1000])
    with pytest.raises(ValueError, match="index must be an int"):
        pybullet_data_models(tmp_path, [1.5])  # type: ignore[list-item]


# --------------------------------------------------------------------------- split
def test_split_is_stable_with_requested_fraction() -> None:
    names = [f"random_urdfs/{i:03d}" for i in range(200)]
    splits = [split_of(n) for n in names]
    assert splits == [split_of(n, 0.2) for n in names]
    fraction = splits.count("test") / len(names)
    assert 0.12 <= fraction <= 0.28
    assert split_of("random_urdfs/007") == split_of("random_urdfs/007")
    assert all(split_of(n, 0.0) == "train" for n in names)
    assert all(split_of(n, 1.0) == "test" for n in names)
    high = [split_of(n, 0.6) for n in names].count("test") / len(names)
    assert 0.5 <= high <= 0.7
    with pytest.raises(ValueError, match="test_fraction"):
        split_of("x", 1.5)


# --------------------------------------------------------------------------- user
def _user_dir(root: Path) -> Path:
    folder = root / "mine"
    folder.mkdir()
    box = trimesh.creation.box(extents=(0.04, 0.05, 0.06))
    box.apply_translation((1.0, 2.0, 3.0))
    box.export(str(folder / "crate.obj"))
    can = trimesh.creation.cylinder(radius=0.03, height=0.1, sections=24)
    can.apply_translation((0.0, 0.0, 0.05))
    can.export(str(folder / "can.stl"))
    (folder / "notes.txt").write_text("not a mesh\n")
    return folder


def test_user_meshes_round_trip_recentred(tmp_path: Path) -> None:
    folder = _user_dir(tmp_path)
    models = user_models(folder, tmp_path / "cache")
    assert [m.name for m in models] == ["user/can", "user/crate"]
    expected = {"user/can": (0.06, 0.06, 0.1), "user/crate": (0.04, 0.05, 0.06)}
    scene = hg.MeshScene()
    for m in models:
        assert m.source == "user"
        np.testing.assert_allclose(m.extents, expected[m.name], atol=1e-6)
        vertices, faces = load_mesh(m.visual_mesh)
        np.testing.assert_allclose(vertices.min(axis=0), -vertices.max(axis=0), atol=2e-9)
        assert scene.is_closed(scene.add_mesh(vertices, faces, np.eye(4))), m.name
        assert m.collision_meshes == (m.visual_mesh,)
        assert 0.02 <= m.mass <= 0.5
    half = user_models(folder, tmp_path / "cache", scale=0.5)
    np.testing.assert_allclose(half[1].extents, (0.02, 0.025, 0.03), atol=1e-6)


def test_user_urdf_bakes_scale_and_origin(tmp_path: Path) -> None:
    folder = tmp_path / "robotish"
    folder.mkdir()
    trimesh.creation.box(extents=(0.01, 0.02, 0.03)).export(str(folder / "part.obj"))
    (folder / "thing.urdf").write_text(
        '<robot name="thing"><link name="base">'
        '<inertial><mass value="0.25"/></inertial>'
        '<visual><origin xyz="0.5 0 0" rpy="0 0 1.5707963267948966"/>'
        '<geometry><mesh filename="part.obj" scale="2 2 2"/></geometry></visual>'
        "</link></robot>"
    )
    (model,) = user_models(folder, tmp_path / "cache")  # part.obj is not added twice
    assert model.name == "user/thing"
    assert model.mass == pytest.approx(0.25)
    np.testing.assert_allclose(model.extents, (0.04, 0.02, 0.06), atol=1e-6)  # yaw 90 deg
    mesh = _tri(model.visual_mesh)
    assert mesh.is_watertight and mesh.volume > 0


def test_user_directory_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="missing"):
        user_models(tmp_path / "missing", tmp_path)
    folder = _user_dir(tmp_path)
    with pytest.raises(ValueError, match="scale"):
        user_models(folder, tmp_path, scale=0.0)
    trimesh.creation.box().export(str(folder / "can.ply"))
    with pytest.raises(ValueError, match="same name 'user/can'"):
        user_models(folder, tmp_path)


# --------------------------------------------------------------------------- load_mesh
def test_load_mesh_returns_typed_arrays(tmp_path: Path) -> None:
    path = tmp_path / "b.stl"
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(str(path))
    vertices, faces = load_mesh(path)
    assert vertices.dtype == np.float64 and vertices.shape == (8, 3)  # STL corners welded
    assert faces.dtype == np.int64 and faces.shape == (12, 3)


def test_load_mesh_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"nope\.obj"):
        load_mesh(tmp_path / "nope.obj")
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    with pytest.raises(ValueError, match="empty"):
        load_mesh(empty)
    points = tmp_path / "points.obj"
    points.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(ValueError, match="empty"):
        load_mesh(points)
    nan = tmp_path / "nan.obj"
    nan.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="non-finite"):
        load_mesh(nan)
    garbage = tmp_path / "garbage.ply"
    garbage.write_text("garbage\n")
    with pytest.raises(ValueError, match=r"garbage\.ply"):
        load_mesh(garbage)


# --------------------------------------------------------------------------- library
def test_library(tmp_path: Path) -> None:
    lib = ObjectLibrary.default(tmp_path, random_urdfs=6, procedural_per_kind=2, seed=0)
    assert len(lib) == 6 + 1 + 10
    assert len(lib.models(source="pybullet_data")) == 7
    assert len(lib.models(source="procedural")) == 10
    train, test = lib.models(split="train"), lib.models(split="test")
    assert len(train) + len(test) == len(lib)
    assert lib.get("procedural/cup_01").name == "procedural/cup_01"
    assert "random_urdfs/005" in lib
    with pytest.raises(KeyError, match="nothing"):
        lib.get("nothing")
    with pytest.raises(ValueError, match="split"):
        lib.models(split="val")
    with pytest.raises(ValueError, match="source"):
        lib.models(source="web")

    drawn = lib.sample(np.random.default_rng(7), 5)
    assert len({m.name for m in drawn}) == 5 and all(m.split == "train" for m in drawn)
    assert drawn == lib.sample(np.random.default_rng(7), 5)
    many = lib.sample(np.random.default_rng(1), 2 * len(train) + 1)
    counts = [sum(m is t for m in many) for t in train]
    assert min(counts) >= 2 and max(counts) <= 3
    assert lib.sample(np.random.default_rng(1), 0) == []
    with pytest.raises(ValueError, match="n must be"):
        lib.sample(np.random.default_rng(1), -1)

    added = lib.add_user_directory(_user_dir(tmp_path))
    assert [m.name for m in added] == ["user/can", "user/crate"]
    assert len(lib.models(source="user")) == 2
    with pytest.raises(ValueError, match="duplicate object name 'user/can'"):
        lib.add_user_directory(tmp_path / "mine")
    assert len(lib) == 17 + 2


def test_library_rejects_duplicates_and_bad_models(procedural: list[ObjectModel]) -> None:
    with pytest.raises(ValueError, match="duplicate"):
        ObjectLibrary([procedural[0], procedural[0]])
    m = procedural[0]
    with pytest.raises(ValueError, match="split"):
        ObjectModel(m.name, m.source, m.visual_mesh, m.collision_meshes, m.mass, "val", m.extents)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="collision meshes"):
        ObjectModel(m.name, m.source, m.visual_mesh, (), m.mass, m.split, m.extents)
    with pytest.raises(ValueError, match="mass"):
        ObjectModel(
            m.name, m.source, m.visual_mesh, m.collision_meshes, math.nan, m.split, m.extents
        )


def test_default_cache_dir(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("HEAPGRASP_CACHE", str(tmp_path))
    assert default_cache_dir() == tmp_path / "objects"
    monkeypatch.delenv("HEAPGRASP_CACHE")
    assert default_cache_dir() == Path.home() / ".cache" / "heapgrasp" / "objects"
