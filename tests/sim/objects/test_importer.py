"""Importing a folder of meshes: units, decomposition, cache entries, and cache hits."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
import trimesh

from hamnet.sim.objects import ObjectCache, ObjectLibraryConfig, ObjectSet, ShapeConfig, importer
from hamnet.sim.objects.mesh import convex_hull, union
from hamnet.sim.objects.shapes import generate


def write_meshes(folder: Path) -> dict[str, np.ndarray]:
    """An L in millimetres (STL), a mug in metres (OBJ, in a subfolder) and a 1 m box (GLB).

    Returns:
        The extents, m, each should import with.
    """
    (folder / "sub").mkdir(parents=True)
    ell = generate("l_shape", np.random.default_rng(1), ShapeConfig()).mesh.to_trimesh()
    mug = generate("mug", np.random.default_rng(2), ShapeConfig()).mesh.to_trimesh()
    expected = {"ell_mm": ell.extents.copy(), "sub-mug": mug.extents.copy()}
    ell.apply_scale(1000.0)
    ell.export(folder / "ell_mm.stl")
    mug.export(folder / "sub" / "mug.obj")
    trimesh.creation.box([1.0, 0.5, 0.3]).export(folder / "unit_box.glb")
    expected["unit_box"] = np.array([0.2, 0.1, 0.06])  # longest side clamped to 0.2 m
    (folder / "notes.txt").write_text("not a mesh")
    return expected


@pytest.fixture
def folder(tmp_path: Path) -> tuple[Path, dict[str, np.ndarray]]:
    return tmp_path / "meshes", write_meshes(tmp_path / "meshes")


def test_import_guesses_units_and_decomposes(
    folder: tuple[Path, dict[str, np.ndarray]], tmp_path: Path
) -> None:
    path, expected = folder
    objects = ObjectSet.from_folder(path, ObjectLibraryConfig(cache_dir=tmp_path / "cache"))
    assert objects.names == ("ell_mm", "sub-mug", "unit_box")
    for asset in objects:
        np.testing.assert_allclose(
            np.ptp(asset.mesh.vertices, axis=0), expected[asset.name], rtol=1e-6
        )
        assert asset.mesh.to_trimesh().is_watertight
        np.testing.assert_allclose(asset.mesh.to_trimesh().center_mass, 0.0, atol=1e-9)
        assert len(asset.orientations) >= 1
    for name in ("ell_mm", "sub-mug"):  # non-convex: CoACD parts, convex, filling the shape
        asset = objects[name]
        assert len(asset.parts) >= 2
        for part in asset.parts:
            assert convex_hull(part.vertices).volume == pytest.approx(part.volume, rel=1e-6)
        assert union(list(asset.parts)).volume == pytest.approx(asset.volume, rel=0.1)
    assert len(objects["unit_box"].parts) == 1


def test_second_import_reads_the_cache_and_computes_nothing(
    folder: tuple[Path, dict[str, np.ndarray]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, _ = folder
    config = ObjectLibraryConfig(cache_dir=tmp_path / "cache")
    cache = ObjectCache(config.resolved_cache_dir())
    first = ObjectSet.from_folder(path, config, cache)
    assert (cache.hits, cache.misses) == (0, 3)
    assert len(list((tmp_path / "cache").rglob("*.npz"))) == 3

    def recompute(*args: object) -> None:
        raise AssertionError("a cached object was rebuilt")

    monkeypatch.setattr(importer, "_build", recompute)
    again = ObjectSet.from_folder(path, config, cache)
    assert (cache.hits, cache.misses) == (3, 3)
    assert again.names == first.names
    for a, b in zip(first, again):
        assert np.array_equal(a.mesh.vertices, b.mesh.vertices)
        assert all(np.array_equal(p, q) for p, q in zip(a.parts[0].vertices, b.parts[0].vertices))
        assert np.array_equal(a.orientations, b.orientations)
        assert a.source == b.source


def test_changed_file_or_settings_miss_the_cache(tmp_path: Path) -> None:
    path = tmp_path / "meshes" / "box.obj"
    path.parent.mkdir()
    trimesh.creation.box([0.1, 0.08, 0.05]).export(path)
    cache = ObjectCache(tmp_path / "cache")
    ObjectSet.from_folder(path.parent, ObjectLibraryConfig(), cache)
    ObjectSet.from_folder(
        path.parent, ObjectLibraryConfig(shapes=ShapeConfig(extent=(0.05, 0.15))), cache
    )
    trimesh.creation.box([0.1, 0.08, 0.06]).export(path)
    ObjectSet.from_folder(path.parent, ObjectLibraryConfig(), cache)
    assert (cache.hits, cache.misses) == (0, 3)
    ObjectSet.from_folder(path.parent, ObjectLibraryConfig(), cache)
    assert (cache.hits, cache.misses) == (1, 3)


def test_unreadable_files_are_skipped_with_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    (tmp_path / "broken.obj").write_text("v 1 2\nf 1 2 3 4 garbage\n")
    (tmp_path / "empty.stl").write_text("solid x\nendsolid x\n")
    trimesh.creation.box([0.1, 0.08, 0.05]).export(tmp_path / "good.obj")
    with caplog.at_level(logging.WARNING):
        objects = ObjectSet.from_folder(tmp_path, ObjectLibraryConfig(use_cache=False))
    assert objects.names == ("good",)
    assert "broken.obj" in caplog.text and "empty.stl" in caplog.text


def test_open_surface_is_closed_before_use(tmp_path: Path) -> None:
    """A box with a missing face has no inside; it must still import as a closed solid."""
    box = trimesh.creation.box([0.1, 0.08, 0.05])
    box.update_faces(np.arange(2, len(box.faces)))
    box.export(tmp_path / "open.obj")
    asset = importer.import_mesh(tmp_path / "open.obj", ObjectLibraryConfig(use_cache=False), None)
    assert asset.mesh.to_trimesh().is_watertight
    assert asset.volume == pytest.approx(0.1 * 0.08 * 0.05, rel=1e-3)
