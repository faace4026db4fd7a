"""The contact dataset: balanced, a function of its seed, resumable, refused when unfinished."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import trimesh

from hamnet.pretrain.config import GenerateConfig, PairConfig
from hamnet.pretrain.dataset import chunk_path, draw_chunk, generate, load_pairs, read_chunk
from hamnet.pretrain.pairs import sample_pair
from hamnet.runtime.errors import ConfigError
from hamnet.sim.objects.config import ShapeConfig
from hamnet.sim.objects.shapes import generate as generate_shape


def test_about_half_of_the_pairs_interpenetrate() -> None:
    """The paper's balance: touch, then a small perturbation, clips about half the pairs."""
    rng = np.random.default_rng(3)
    pairs = [sample_pair(rng, PairConfig()) for _ in range(150)]
    share = np.mean([p.colliding for p in pairs])
    assert 0.35 <= share <= 0.65, share
    # Missing pairs never have a point inside the other shape.
    assert not any(p.labels_a.any() or p.labels_b.any() for p in pairs if not p.colliding)


def test_pairs_hold_clouds_of_the_configured_size_from_both_sources() -> None:
    rng = np.random.default_rng(0)
    pairs = [sample_pair(rng, PairConfig(num_points=64, cuboid_share=0.5)) for _ in range(20)]
    assert all(p.points_a.shape == (64, 3) and p.points_a.dtype == np.float32 for p in pairs)
    kinds = {p.kind_a for p in pairs} | {p.kind_b for p in pairs}
    assert "cuboid" in kinds and len(kinds) > 2


def test_a_chunk_depends_only_on_seed_and_index() -> None:
    pair = PairConfig(num_points=32)
    first, again, other = (
        draw_chunk(pair, 7, 2, 5),
        draw_chunk(pair, 7, 2, 5),
        draw_chunk(pair, 8, 2, 5),
    )
    assert all(np.array_equal(first[k], again[k]) for k in first)
    assert not np.array_equal(first["points_a"], other["points_a"])


def test_generation_is_the_same_with_two_workers(tmp_path) -> None:
    config = GenerateConfig(
        out=tmp_path / "one", pairs=12, chunk_size=4, pair=PairConfig(num_points=32)
    )
    generate(config)
    generate(dataclasses.replace(config, out=tmp_path / "two", workers=2))
    one, two = load_pairs(tmp_path / "one"), load_pairs(tmp_path / "two")
    assert np.array_equal(one.points_b, two.points_b) and np.array_equal(one.labels_a, two.labels_a)


def test_resume_skips_finished_chunks_and_redraws_missing_ones(tmp_path) -> None:
    """An interruption leaves some chunks: a second run must not rewrite them (mtime kept)
    and must draw the missing one exactly as the first run did."""
    config = GenerateConfig(out=tmp_path, pairs=9, chunk_size=3, pair=PairConfig(num_points=32))
    generate(config)
    kept, lost = chunk_path(tmp_path, 0), chunk_path(tmp_path, 1)
    before, original = kept.stat().st_mtime_ns, read_chunk(lost)
    lost.unlink()
    generate(config)
    assert kept.stat().st_mtime_ns == before
    assert np.array_equal(read_chunk(lost)["points_a"], original["points_a"])
    assert len(load_pairs(tmp_path)) == 9 and len(load_pairs(tmp_path, max_pairs=4)) == 4


def test_a_folder_of_another_seed_or_an_unfinished_one_is_refused(tmp_path) -> None:
    config = GenerateConfig(out=tmp_path, pairs=2, chunk_size=2, pair=PairConfig(num_points=32))
    generate(config)
    with pytest.raises(ConfigError, match="another seed"):
        generate(dataclasses.replace(config, seed=1))
    (tmp_path / "manifest.json").write_text('{"format": 1, "complete": false}')
    with pytest.raises(ConfigError, match="unfinished"):
        load_pairs(tmp_path)
    with pytest.raises(ConfigError, match="not a contact dataset"):
        load_pairs(tmp_path / "nothing")


def test_imported_meshes_join_the_library_objects(tmp_path) -> None:
    """`--pair.meshes FOLDER`: mesh files imported as the sim imports them are drawn as library
    objects (an L and a box written as files), labelled against their convex parts; a folder
    without a usable mesh is refused."""
    folder = tmp_path / "meshes"
    folder.mkdir()
    generate_shape("l_shape", np.random.default_rng(1), ShapeConfig()).mesh.to_trimesh().export(
        folder / "ell.obj"
    )
    trimesh.creation.box([0.08, 0.05, 0.03]).export(folder / "box.stl")
    config = PairConfig(meshes=folder, mesh_share=1.0, cuboid_share=0.0)
    rng = np.random.default_rng(0)
    pairs = [sample_pair(rng, config) for _ in range(12)]
    kinds = {p.kind_a for p in pairs} | {p.kind_b for p in pairs}
    assert kinds == {"mesh:ell", "mesh:box"}
    assert any(p.colliding for p in pairs) and not all(p.colliding for p in pairs)
    assert any(p.labels_a.any() or p.labels_b.any() for p in pairs if p.colliding)
    assert not any(p.labels_a.any() or p.labels_b.any() for p in pairs if not p.colliding)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConfigError, match="no mesh file there imports"):
        sample_pair(rng, dataclasses.replace(config, meshes=tmp_path / "empty"))
