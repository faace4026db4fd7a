"""Procedural cuboid scenes: paper ranges, layout rules, hidden slots, EnvCode, Rerun file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun.chunk

from hamnet.sim import quaternion
from hamnet.sim.scene import (
    CEILING,
    ENV_CODE_COLUMNS,
    FRONT_WALL,
    NUM_BASE,
    PLATES,
    RAMPS,
    SceneBatch,
    sample_scenes,
)
from hamnet.sim.scene_config import FLOOR_Z, SCENE_PRESETS, SceneConfig
from hamnet.sim.scene_view import save_scene
from hamnet.task.cuboids import NUM_CUBOIDS, TABLE

B = 256
SEEDS = range(8)
COLUMN = {name: i for i, name in enumerate(ENV_CODE_COLUMNS)}


def scenes(seed: int, config: SceneConfig | None = None) -> tuple[SceneBatch, np.ndarray]:
    """B scenes for objects of random heights in [0.03, 0.2] m, and those heights."""
    rng = np.random.default_rng(seed)
    object_height = rng.uniform(0.03, 0.2, size=B)
    return sample_scenes(rng, object_height, config), object_height


def columns(scene: SceneBatch, *names: str) -> np.ndarray:
    return scene.env_code[:, [COLUMN[name] for name in names]]


def box_corners(scene: SceneBatch) -> np.ndarray:
    """World corners (B, N, 8, 3) of every cuboid."""
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    local = signs * scene.half_extent[:, :, None, :]  # (B, N, 8, 3)
    rotation = quaternion.to_matrix(scene.quat)  # (B, N, 3, 3)
    return scene.centre[:, :, None, :] + np.einsum("bnij,bnkj->bnki", rotation, local)


def rise(scene: SceneBatch) -> np.ndarray:
    """Highest platform (B,), m: what the ceiling is raised by."""
    return scene.env_code[:, COLUMN["plate_height_x0"] : COLUMN["plate_height_y2"] + 1].max(-1)


def test_env_code_has_25_named_columns_and_finite_arrays() -> None:
    scene, _ = scenes(0)
    assert len(ENV_CODE_COLUMNS) == 25 and scene.env_code.shape == (B, 25)
    assert scene.centre.shape == scene.half_extent.shape == (B, NUM_CUBOIDS, 3)
    assert scene.quat.shape == (B, NUM_CUBOIDS, 4) and scene.active.shape == (B, NUM_CUBOIDS)
    assert scene.friction.shape == (B,)
    for array in (scene.centre, scene.quat, scene.half_extent, scene.env_code, scene.region_z):
        assert np.all(np.isfinite(array))


@pytest.mark.parametrize("preset", ["default", "paper"])
@pytest.mark.parametrize("seed", SEEDS)
def test_every_parameter_is_within_its_range(seed: int, preset: str) -> None:
    """The paper's table, except the table's rise (authors: 0 to 0.6) and the plates'
    elevation (authors: 0.05 to 0.15) in the default configuration."""
    config = SCENE_PRESETS.get(preset, SceneConfig())
    scene, _ = scenes(seed, config)
    ranges = {
        "table_dim_x": (0.255, 0.51),
        "table_dim_y": (0.325, 0.65),
        "table_dim_z": (0.2, 0.4),
        "table_pos_x": (0.0, 0.1),
        "table_pos_y": (-0.15, 0.15),
        "table_pos_z": (0.1, 0.8) if preset == "paper" else (0.0, 0.6),
    }
    ranges |= {f"ramp_angle_{a}{j}": (0.0, math.radians(30)) for a in "xy" for j in (0, 1)}
    low = 0.0 if preset == "paper" else 0.05
    ranges |= {f"plate_height_{a}{i}": (low, 0.15) for a in "xy" for i in (0, 1, 2)}
    for name, (low, high) in ranges.items():
        values = scene.env_code[:, COLUMN[name]]
        if name.startswith("plate_height"):
            values = values[values > 0]  # bottom plates code 0
        assert np.all((values >= low) & (values <= high)), name
    assert np.all((scene.friction >= 0.2) & (scene.friction <= 0.6))
    # Table dims x, y are the table cuboid's size; the box stands on the floor.
    np.testing.assert_allclose(
        2 * scene.half_extent[:, TABLE, :2], columns(scene, "table_dim_x", "table_dim_y")
    )


@pytest.mark.parametrize("seed", SEEDS)
def test_the_table_stands_on_the_floor_with_its_top_minus_02_to_06_m_from_the_robot(
    seed: int,
) -> None:
    """The demo's table hovered 0.35 m above the robot's floor, then sank through it: the
    table's box now reaches from the floor to its top, which lies -0.2 to +0.6 m from the
    robot's base (the world origin) as in the authors' code; walls stand on the floor too."""
    scene, _ = scenes(seed)
    bottom = scene.centre[:, :, 2] - scene.half_extent[:, :, 2]  # (B, N), boxes are upright
    np.testing.assert_allclose(bottom[:, TABLE], FLOOR_Z, atol=1e-12)
    top = scene.centre[:, TABLE, 2] + scene.half_extent[:, TABLE, 2]
    np.testing.assert_allclose(top, scene.table_top)
    assert np.all((scene.table_top >= -0.2) & (scene.table_top <= 0.6))
    expected = FLOOR_Z + columns(scene, "table_pos_z")[:, 0] + columns(scene, "table_dim_z")[:, 0]
    np.testing.assert_allclose(scene.table_top, expected)
    walls = scene.active[:, FRONT_WALL:CEILING]
    np.testing.assert_allclose(bottom[:, FRONT_WALL:CEILING][walls], FLOOR_Z, atol=1e-12)


def test_open_walls_are_005_to_030_m_whatever_the_ceiling_curriculum() -> None:
    """Walls of scenes without a ceiling were as high as a (tight or nominal) ceiling would
    have been; the authors draw them U(0.05, 0.3) (gen_case.py:170-178), and the tight
    probability of the curriculum must not change them."""
    heights = []
    for p_tight in (0.0, 1.0):
        config = SceneConfig(p_tight=p_tight, p_ceiling=0.0, p_wall=1.0)
        scene = sample_scenes(np.random.default_rng(0), np.full(2048, 0.05), config)
        heights.append(columns(scene, "wall_height_front")[:, 0])
    np.testing.assert_array_equal(heights[0], heights[1])
    assert heights[0].min() >= 0.05 and heights[0].max() <= 0.3
    assert abs(heights[0].mean() - 0.175) < 0.005


def test_raised_plates_share_one_elevation_per_scene_at_the_authors_rate() -> None:
    """A plate is raised with probability 1 - p_high = 0.293 (gen_base.py:161) and all
    raised plates of a scene share one U(0.05, 0.15) height (gen_base.py:286-290)."""
    scene = sample_scenes(np.random.default_rng(0), np.full(4096, 0.1))
    height = columns(scene, *(f"plate_height_{a}{i}" for a in "xy" for i in range(3)))
    raised = height > 0
    assert abs(raised.mean() - 0.293) < 0.01
    several = raised.sum(-1) > 1
    spread = np.where(raised, height, np.nan)
    assert np.all(np.nanmax(spread[several], -1) == np.nanmin(spread[several], -1))


def test_masks_follow_their_bernoulli_probabilities() -> None:
    scene = sample_scenes(np.random.default_rng(0), np.full(4096, 0.1))
    ceiling = scene.active[:, CEILING]
    assert abs(ceiling.mean() - 0.5) < 0.03
    walls = scene.active[~ceiling, FRONT_WALL:CEILING]  # no ceiling: walls are free B(0.5)
    assert np.all(np.abs(walls.mean(axis=0) - 0.5) < 0.04)
    assert abs(scene.tight.mean() - 0.5) < 0.03
    paper = sample_scenes(np.random.default_rng(0), np.full(4096, 0.1), SCENE_PRESETS["paper"])
    is_top = columns(paper, *(f"plate_height_{a}{i}" for a in "xy" for i in range(3))) > 0
    assert abs(is_top.mean() - 0.5) < 0.02


@pytest.mark.parametrize("seed", SEEDS)
def test_planar_plates_and_ramps_tile_the_table(seed: int) -> None:
    scene, _ = scenes(seed)
    table_lo = scene.centre[:, TABLE, :2] - scene.half_extent[:, TABLE, :2]  # (B, 2)
    table_hi = scene.centre[:, TABLE, :2] + scene.half_extent[:, TABLE, :2]
    edges = scene.profile_edges  # (B, 2, 6)
    np.testing.assert_allclose(edges[..., 0], table_lo)
    np.testing.assert_allclose(edges[..., -1], table_hi)
    assert np.all(np.diff(edges, axis=-1) >= 0)
    plate_sizes = (edges[..., 1::2] - edges[..., 0::2]).sum(axis=-1)  # (B, 2)
    assert np.all(plate_sizes <= table_hi - table_lo + 1e-12)
    for axis in (0, 1):
        for slot in PLATES[axis]:
            on = scene.active[:, slot]
            low = scene.centre[on, slot, axis] - scene.half_extent[on, slot, axis]
            high = scene.centre[on, slot, axis] + scene.half_extent[on, slot, axis]
            assert np.all(low >= table_lo[on, axis] - 1e-12)
            assert np.all(high <= table_hi[on, axis] + 1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_ramps_join_the_edges_of_the_plates_they_connect(seed: int) -> None:
    """The top face of an active interim plate runs from the top edge of one planar plate
    to the top edge of the next, at the sampled tilt from the vertical."""
    scene, _ = scenes(seed)
    corners = box_corners(scene)  # (B, N, 8, 3)
    for axis in (0, 1):
        height = scene.table_top[:, None] + scene.profile_high[:, axis, 0::2]  # (B, 3)
        for j, slot in enumerate(RAMPS[axis]):
            on = scene.active[:, slot]
            assert np.array_equal(on, height[:, j] != height[:, j + 1])
            top_face = corners[on, slot, 1::2]  # (M, 4, 3): local +z corners
            ends = np.sort(top_face[..., axis], axis=-1)  # (M, 4)
            np.testing.assert_allclose(ends[:, 0], scene.profile_edges[on, axis, 2 * j + 1])
            np.testing.assert_allclose(ends[:, -1], scene.profile_edges[on, axis, 2 * j + 2])
            z = np.sort(top_face[..., 2], axis=-1)
            np.testing.assert_allclose(z[:, 0], np.minimum(height[on, j], height[on, j + 1]))
            np.testing.assert_allclose(z[:, -1], np.maximum(height[on, j], height[on, j + 1]))
            run = ends[:, -1] - ends[:, 0]
            angle = scene.env_code[on, COLUMN[f"ramp_angle_{'xy'[axis]}{j}"]]
            np.testing.assert_allclose(run, (z[:, -1] - z[:, 0]) * np.tan(angle), atol=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_ceiling_opens_the_front_wall_and_keeps_a_supporting_wall(seed: int) -> None:
    scene, _ = scenes(seed)
    ceiling = scene.active[:, CEILING]
    assert ceiling.any() and (~ceiling).any()
    assert not scene.active[ceiling, FRONT_WALL].any()
    assert np.all(scene.active[ceiling, FRONT_WALL + 1 : CEILING].any(axis=-1))
    assert np.array_equal(np.isfinite(scene.ceiling_z), ceiling)


@pytest.mark.parametrize("seed", SEEDS)
def test_tight_ceiling_is_object_height_plus_gap_plus_platform_rise(seed: int) -> None:
    config = SceneConfig(p_tight=1.0, p_ceiling=1.0)
    scene, object_height = scenes(seed, config)
    clearance = scene.ceiling_z - scene.table_top
    np.testing.assert_allclose(columns(scene, "ceiling_height")[:, 0], clearance)
    gap = clearance - rise(scene) - object_height
    assert np.all((gap >= 0.03 - 1e-12) & (gap <= 0.05 + 1e-12))
    assert rise(scene).max() > 0.1  # the rise term was exercised


@pytest.mark.parametrize("seed", SEEDS)
def test_nominal_ceiling_is_uniform_clearance_plus_platform_rise(seed: int) -> None:
    config = SceneConfig(p_tight=0.0, p_ceiling=1.0)
    scene, _ = scenes(seed, config)
    nominal = scene.ceiling_z - scene.table_top - rise(scene)
    assert np.all((nominal >= 0.3 - 1e-12) & (nominal <= 0.5 + 1e-12))


@pytest.mark.parametrize("seed", SEEDS)
def test_walls_reach_their_height_and_absent_ones_code_zero(seed: int) -> None:
    """EnvCode's wall columns are the walls' tops above the table top; under a ceiling they
    reach the ceiling's underside."""
    scene, _ = scenes(seed)
    corners = box_corners(scene)
    walls = columns(scene, *(f"wall_height_{side}" for side in ("front", "back", "right", "left")))
    on = scene.active[:, FRONT_WALL:CEILING]  # (B, 4)
    assert np.all(walls[~on] == 0)
    wall_top = corners[:, FRONT_WALL:CEILING, :, 2].max(-1) - scene.table_top[:, None]
    np.testing.assert_allclose(walls[on], wall_top[on])
    ceiling = scene.active[:, CEILING]
    under = on & ceiling[:, None]
    clearance = np.broadcast_to(columns(scene, "ceiling_height"), walls.shape)
    np.testing.assert_allclose(walls[under], clearance[under])
    assert np.all(columns(scene, "ceiling_height")[~scene.active[:, CEILING]] == 0)


@pytest.mark.parametrize("seed", SEEDS)
def test_inactive_cuboids_are_hidden_inside_the_table_beneath_its_top(seed: int) -> None:
    scene, _ = scenes(seed)
    corners = box_corners(scene)  # (B, N, 8, 3)
    table_lo = scene.centre[:, TABLE] - scene.half_extent[:, TABLE]  # (B, 3)
    table_hi = scene.centre[:, TABLE] + scene.half_extent[:, TABLE]
    hidden = ~scene.active
    assert hidden.sum() > B  # plenty of inactive slots to check
    inside = (corners >= table_lo[:, None, None]) & (corners <= table_hi[:, None, None])
    assert np.all(inside.all(axis=(-1, -2))[hidden])
    table_top = np.broadcast_to(scene.table_top[:, None], hidden.shape)  # (B, N)
    assert np.all(corners[..., 2].max(-1)[hidden] < table_top[hidden])


@pytest.mark.parametrize("seed", SEEDS)
def test_quaternions_are_unit(seed: int) -> None:
    scene, _ = scenes(seed)
    np.testing.assert_allclose(np.linalg.norm(scene.quat, axis=-1), 1.0, atol=1e-12)


def test_same_seed_gives_the_same_scenes_and_another_seed_different_ones() -> None:
    first, _ = scenes(7)
    again, _ = scenes(7)
    other, _ = scenes(8)
    for field in dataclasses.fields(SceneBatch):
        assert np.array_equal(getattr(first, field.name), getattr(again, field.name)), field.name
    assert not np.allclose(first.env_code, other.env_code)
    assert not np.allclose(first.centre, other.centre)


def test_flat_regions_match_the_tops_of_the_cuboids_in_mujoco() -> None:
    """Rays cast down in MuJoCo onto the active base cuboids hit every flat region at its
    region_z, and hit the surface max(profile_x, profile_y) anywhere on the table."""
    rng = np.random.default_rng(11)
    scene = sample_scenes(rng, np.full(24, 0.08))
    for b in range(scene.num_envs):
        model = mujoco.MjModel.from_xml_string(base_cuboids_mjcf(scene, b))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        for r in np.flatnonzero(scene.region_flat[b]):
            for xy in rng.uniform(scene.region_lo[b, r], scene.region_hi[b, r], size=(8, 2)):
                assert ray_height(model, data, xy) == pytest.approx(scene.region_z[b, r], abs=1e-9)


def base_cuboids_mjcf(scene: SceneBatch, b: int) -> str:
    geoms = "".join(
        f'<geom type="box" pos="{" ".join(map(str, scene.centre[b, n]))}" '
        f'quat="{" ".join(map(str, scene.quat[b, n]))}" '
        f'size="{" ".join(map(str, scene.half_extent[b, n]))}"/>'
        for n in range(NUM_BASE)
        if scene.active[b, n]
    )
    return f"<mujoco><worldbody>{geoms}</worldbody></mujoco>"


def ray_height(model: mujoco.MjModel, data: mujoco.MjData, xy: np.ndarray) -> float:
    geom = np.zeros(1, dtype=np.int32)
    origin = np.array([xy[0], xy[1], 5.0])
    distance = mujoco.mj_ray(model, data, origin, np.array([0.0, 0.0, -1.0]), None, 1, -1, geom)
    return 5.0 - distance


@pytest.mark.parametrize(
    "change",
    [
        {"plate_share_min": 0.34},
        {"p_tight": 1.5},
        {"table_dim_x": (0.5, 0.4)},
        {"ramp_angle": (0.0, math.radians(80))},
    ],
)
def test_inconsistent_configs_are_rejected(change: dict) -> None:
    with pytest.raises(ValueError):
        SceneConfig(**change)


def test_saved_rrd_file_holds_the_scene_boxes(tmp_path: Path) -> None:
    path = tmp_path / "scene.rrd"
    save_scene(path, seed=5)
    scene = sample_scenes(np.random.default_rng(5), np.array([0.08]))  # as save_scene draws it
    batches = {
        chunk.entity_path: chunk.to_record_batch()
        for chunk in rerun.chunk.RrdReader(path).stream().to_chunks()
    }
    assert {"/scene/base", "/scene/case", "/scene/start", "/scene/goal"} <= batches.keys()
    groups = {"/scene/base": range(NUM_BASE), "/scene/case": range(NUM_BASE, NUM_CUBOIDS)}
    for entity, slots in groups.items():
        shown = [n for n in slots if scene.active[0, n]]
        logged = batches[entity].column("Boxes3D:half_sizes")[0].as_py()
        half_sizes = np.array(logged).reshape(-1, 3)
        np.testing.assert_allclose(half_sizes, scene.half_extent[0, shown], rtol=1e-6)
