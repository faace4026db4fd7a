"""The nine benchmark domains (`hamnet.sim.domains`): scenes that build, stand where they say,
keep objects clear of their cuboids, hold objects still in MuJoCo, start the arm clear of
them, and planned episodes that replay from their seeds."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun.chunk

from hamnet.fr3 import limits as fr3_limits
from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.sim import quaternion
from hamnet.sim.config import SimConfig
from hamnet.sim.domains import DOMAIN_NAMES, EpisodePlan, domain_builder, pair_placement
from hamnet.sim.domains.containers import SINK
from hamnet.sim.env import VectorEnv
from hamnet.sim.placement import Placement, sample_placements
from hamnet.sim.robot_init import RETRACTED, Cuboids, arm_in_contact, inside_cuboids
from hamnet.sim.scene import SceneBatch, sample_scenes
from hamnet.sim.scene_view import save_scene
from hamnet.task.cuboids import NUM_CUBOIDS, TABLE

B = 16
SEEDS = range(3)
SETTLE_STEPS = 10
"""Policy steps of 0.1 s an object is left to settle: one second."""
PAIR = pair_placement(SimConfig().task)
"""Start and goal apart by >= 0.05 m and >= 0.1 rad, both."""


def build(name: str, seed: int) -> tuple[SceneBatch, np.ndarray]:
    """B scenes of domain `name` for objects 3 to 20 cm tall, and those heights."""
    rng = np.random.default_rng(seed)
    height = rng.uniform(0.03, 0.2, size=B)
    return domain_builder(name)(rng, height), height


def stand_in(rng: np.random.Generator, count: int) -> tuple[np.ndarray, ...]:
    """Upright stand-in objects, one pose each: quat (K, 1, 4), planar radius, rest and top
    height (K, 1), m; up to the library's 0.1 m radius and 0.2 m height."""
    radius = rng.uniform(0.03, 0.1, size=(count, 1))
    rest = rng.uniform(0.015, 0.1, size=(count, 1))
    return np.tile([1.0, 0.0, 0.0, 0.0], (count, 1, 1)), radius, rest, 2 * rest


def place(name: str, seed: int) -> tuple[SceneBatch, tuple[np.ndarray, ...], Placement]:
    rng = np.random.default_rng(seed)
    objects = stand_in(rng, B)
    scene = domain_builder(name)(rng, objects[3][:, 0])
    return scene, objects, sample_placements(rng, scene, *objects, PAIR)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", DOMAIN_NAMES)
def test_every_domain_builds_finite_scenes_with_flat_start_and_goal_cells(
    name: str, seed: int
) -> None:
    scene, height = build(name, seed)
    for field in dataclasses.fields(SceneBatch):
        value = getattr(scene, field.name)
        assert len(value) == B, field.name
        if field.name != "ceiling_z":
            assert np.all(np.isfinite(value)), field.name
    assert not np.any(np.isnan(scene.ceiling_z))
    np.testing.assert_allclose(np.linalg.norm(scene.quat, axis=-1), 1.0)
    assert np.all((scene.region_flat & scene.region_start).any(axis=1))
    assert np.all((scene.region_flat & scene.region_goal).any(axis=1))
    table = scene.centre[:, TABLE, 2] + scene.half_extent[:, TABLE, 2]
    np.testing.assert_allclose(scene.table_top, table)
    assert np.all(scene.ceiling_z > scene.table_top + height)
    hidden = ~scene.active  # parked inside the support, beneath its top
    top = (scene.centre[..., 2] + scene.half_extent[..., 2])[hidden]
    assert np.all(top < np.broadcast_to(scene.table_top[:, None], hidden.shape)[hidden])


def test_the_fixture_moves_a_few_centimetres_and_every_domain_differs() -> None:
    """Two seeds shift one fixture by at most 3 cm (x, y) and 2 cm (z), and no two domains
    share their cuboids."""
    a, _ = build("cabinet", 0)
    b, _ = build("cabinet", 1)
    shift = np.abs(a.centre[:, TABLE] - b.centre[:, TABLE]).max(axis=0)
    assert np.all(shift <= [0.06, 0.06, 0.04]) and np.all(shift > 0)
    parts = {name: build(name, 0)[0].active[0].sum() for name in DOMAIN_NAMES}
    assert parts["circular_bin"] == 13 and parts["flat"] == 1 and max(parts.values()) <= 16


@pytest.mark.parametrize("name", DOMAIN_NAMES)
def test_flat_cells_match_the_tops_of_the_cuboids_in_mujoco(name: str) -> None:
    """Rays cast down from under the ceiling onto every active cuboid hit each flat cell at
    its region_z: the profile says where the cuboids really are."""
    scene, _ = build(name, 4)
    rng = np.random.default_rng(0)
    for b in range(4):
        model = mujoco.MjModel.from_xml_string(cuboids_mjcf(scene, b))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        start_z = min(scene.ceiling_z[b], scene.table_top[b] + 2.0) - 1e-3
        for r in np.flatnonzero(scene.region_flat[b]):
            for xy in rng.uniform(scene.region_lo[b, r], scene.region_hi[b, r], size=(8, 2)):
                assert ray_height(model, data, xy, start_z) == pytest.approx(scene.region_z[b, r])


def cuboids_mjcf(scene: SceneBatch, b: int) -> str:
    geoms = "".join(
        f'<geom type="box" pos="{" ".join(map(str, scene.centre[b, n]))}" '
        f'quat="{" ".join(map(str, scene.quat[b, n]))}" '
        f'size="{" ".join(map(str, scene.half_extent[b, n]))}"/>'
        for n in range(NUM_CUBOIDS)
        if scene.active[b, n]
    )
    return f"<mujoco><worldbody>{geoms}</worldbody></mujoco>"


def ray_height(model: mujoco.MjModel, data: mujoco.MjData, xy: np.ndarray, z: float) -> float:
    geom = np.zeros(1, dtype=np.int32)
    origin = np.array([xy[0], xy[1], z])
    return z - mujoco.mj_ray(model, data, origin, np.array([0.0, 0.0, -1.0]), None, 1, -1, geom)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("name", DOMAIN_NAMES)
def test_placed_objects_keep_clear_of_every_cuboid_and_their_pair_apart(
    name: str, seed: int
) -> None:
    """Points on each placed object's bounding cylinder (planar radius, from 1 mm above its
    face to its top) lie inside no active cuboid, and start and goal differ by at least
    both thresholds."""
    scene, (_, radius, rest, top), placement = place(name, seed)
    assert placement.valid.mean() >= 0.9
    ok = placement.valid
    cuboids = Cuboids(scene.centre[ok], scene.quat[ok], scene.half_extent[ok], scene.active[ok])
    angle = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=-1)  # (64, 3)
    for pos in (placement.start_pos[ok], placement.goal_pos[ok]):
        face = pos[:, 2] - rest[ok, 0]  # (K,), m
        for fraction in (0.0, 0.5, 0.999):  # the axis, a middle ring and the rim
            xy = pos[:, None, :2] + ring[None, :, :2] * radius[ok, :, None] * fraction
            for level in np.linspace(0.001, 1.0, 6):
                z = face + 0.001 + level * (top[ok, 0] - 0.001)  # (K,), m
                height = np.broadcast_to(z[:, None, None], (*xy.shape[:2], 1))
                cloud = np.concatenate([xy, height], axis=-1)  # (K, 64, 3)
                assert not inside_cuboids(cloud, cuboids, np.full(3, -1e-6)).any()
    distance = np.linalg.norm(placement.start_pos - placement.goal_pos, axis=1)[ok]
    turn = quaternion.angle_between(placement.start_quat, placement.goal_quat)[ok]
    assert np.all(distance >= PAIR.min_position_separation)
    assert np.all(turn >= PAIR.min_orientation_separation)


def test_sink_and_grill_keep_start_and_goal_on_opposite_sides() -> None:
    """Sink: one of start and goal in the basin (below the counter), the other on the
    counter, each way round; grill: start and goal on either side of the bars."""
    scene, _, placement = place("sink", 0)
    ok = placement.valid
    counter = scene.table_top[ok] + SINK.depth  # (K,), m
    below = [pos[ok, 2] < counter for pos in (placement.start_pos, placement.goal_pos)]
    assert np.all(below[0] != below[1]) and below[0].any() and below[1].any()
    scene, _, placement = place("grill", 0)
    ok = placement.valid
    middle = (scene.profile_edges[ok, 1, 1] + scene.profile_edges[ok, 1, 2]) / 2  # (K,), m
    side = [np.sign(pos[ok, 1] - middle) for pos in (placement.start_pos, placement.goal_pos)]
    assert np.all(side[0] == -side[1]) and len(np.unique(side[0])) == 2


def test_procedural_scenes_let_start_and_goal_use_every_region() -> None:
    scene = sample_scenes(np.random.default_rng(0), np.full(8, 0.1))
    assert scene.region_start.all() and scene.region_goal.all()


def test_an_unknown_domain_is_a_value_error_that_names_the_domains() -> None:
    with pytest.raises(ValueError, match="cabinet, cabinet_top, sink"):
        SimConfig(domain="kitchen")
    with pytest.raises(ValueError, match="circular_bin"):
        domain_builder("bin")
    with pytest.raises(ValueError, match="unknown domain"):
        EpisodePlan.named(["flat", "oven"], [0, 0], [0, 0], [0, 0])
    with pytest.raises(ValueError):
        EpisodePlan(np.array([len(DOMAIN_NAMES)]), np.array([0]), np.array([0]), np.array([0]))


def make_env(**overrides) -> VectorEnv:
    return VectorEnv(SimConfig(num_envs=3, num_objects=3, nthread=1, **overrides))


def hold(q: np.ndarray) -> Command:
    """Hold the arm at `q` (B, J), rad, for one policy step."""
    kp = np.full_like(q, 100.0)
    tau = np.tile(fr3_limits.FR3.tau_max, (len(q), 1))
    return Command(np.repeat(q[:, None, :], 8, axis=1), kp, 2 * np.sqrt(kp), tau)


def settle(env: VectorEnv, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hold the arm at `q` (B, J) for a second of physics; the object's pose after it."""
    command = hold(q)
    env.physics.set_gains(command.kp, command.kd, command.tau_limit)
    for _ in range(SETTLE_STEPS):
        env.physics.step(command.q_ref, env.config.physics_steps_per_sample)
    pose = env.physics.qpos[:, env.world.object_qpos]  # (B, 7)
    return pose[:, :3], pose[:, 3:]


def assert_still(env: VectorEnv, q: np.ndarray, pos: np.ndarray, quat: np.ndarray) -> None:
    after_pos, after_quat = settle(env, q)
    assert np.linalg.norm(after_pos - pos, axis=1).max() < 0.01
    assert quaternion.angle_between(after_quat, quat).max() < 0.1


@pytest.mark.parametrize("name", DOMAIN_NAMES)
def test_objects_rest_at_start_and_goal_and_the_arm_starts_clear(name: str) -> None:
    """With --sim.domain set, the arm starts touching nothing, the object stays within 1 cm
    and 0.1 rad of its start for a second with the arm held still, and so does it when put
    at its goal (the arm retracted), where a step then succeeds; start and goal differ by
    both thresholds."""
    env = make_env(domain=name)
    observation = env.reset(seed=2)
    ids = np.arange(env.num_envs)
    assert not arm_in_contact(env.physics, ids).any()
    start = observation.object_pose.astype(np.float64)  # (B, 7)
    distance = np.linalg.norm(start[:, :3] - env.goal_pos, axis=1)  # (B,), m
    assert distance.min() >= PAIR.min_position_separation - 1e-6  # float32 observation
    turn = quaternion.angle_between(start[:, 3:], env.goal_quat)  # (B,), rad
    assert turn.min() >= PAIR.min_orientation_separation - 1e-3
    assert_still(env, observation.q.astype(np.float64), start[:, :3], start[:, 3:])
    retracted = np.tile(RETRACTED, (env.num_envs, 1))
    env.physics.set_state(ids, retracted, env.goal_pos, env.goal_quat)
    assert_still(env, retracted, env.goal_pos, env.goal_quat)
    result = env.step(hold(retracted))  # at the goal: success, and a new episode drawn
    assert result.success.all() and np.isfinite(result.reward_terms).all()
    assert np.isfinite(result.observation.object_pose).all()


PLAN = EpisodePlan.named(["sink", "grill", "cabinet"], [0, 4, 8], [7, 8, 9], [1, 2, 3])


def episode(env: VectorEnv, observation: Observation) -> dict[str, np.ndarray]:
    """What a planned episode fixes: scene, start, goal, physics and the arm's start."""
    return {
        "centre": env.scene_arrays["centre"].copy(),
        "half_extent": env.scene_arrays["half_extent"].copy(),
        "start": observation.object_pose.copy(),
        "goal": observation.goal_pose.copy(),
        "physics": observation.physics_params.copy(),
        "q": observation.q.copy(),
    }


def test_a_plan_replays_the_same_episodes_in_any_environment() -> None:
    """The same plan gives the same scenes, poses, physics and arm starts after other
    episodes and in other environments of another batch with the same library (rows
    reversed); the env's config.domain does not matter."""
    env = make_env()
    first = episode(env, env.start_planned(PLAN))
    env.reset(seed=3)
    again = episode(env, env.start_planned(PLAN))
    other = make_env(domain="flat")  # the same seed: the same procedural library
    reversed_ids = np.arange(3)[::-1]
    moved = episode(other, other.start_planned(PLAN, reversed_ids))
    for name, values in first.items():
        np.testing.assert_array_equal(again[name], values, err_msg=name)
        np.testing.assert_array_equal(moved[name][reversed_ids], values, err_msg=name)
    assert not arm_in_contact(env.physics, np.arange(3)).any()


def test_another_init_seed_moves_only_the_arm() -> None:
    env = make_env()
    first = episode(env, env.start_planned(PLAN))
    plan = dataclasses.replace(PLAN, init_seed=PLAN.init_seed + 100)
    second = episode(env, env.start_planned(plan))
    for name in ("centre", "half_extent", "start", "goal", "physics"):
        np.testing.assert_array_equal(second[name], first[name], err_msg=name)
    assert np.all(np.abs(second["q"] - first["q"]).max(axis=1) > 1e-3)
    plan = dataclasses.replace(PLAN, pair_seed=PLAN.pair_seed + 100)
    third = episode(env, env.start_planned(plan))
    assert np.all(np.abs(third["goal"] - first["goal"]).max(axis=1) > 1e-3)


def test_planned_episodes_follow_their_domain_and_object() -> None:
    env = make_env()
    env.start_planned(PLAN)
    np.testing.assert_array_equal(env.object_index, PLAN.object_index)
    active = env.scene_arrays["active"].sum(axis=1)
    np.testing.assert_array_equal(active, [5, 8, 5])  # sink, grill, cabinet cuboids
    with pytest.raises(ValueError, match="one row per environment"):
        env.start_planned(PLAN, np.array([0, 1]))


def test_saved_rrd_file_shows_a_domain(tmp_path: Path) -> None:
    path = tmp_path / "bin.rrd"
    save_scene(path, seed=5, domain="circular_bin")
    chunks = rerun.chunk.RrdReader(path).stream().to_chunks()
    boxes = sum(
        len(chunk.to_record_batch().column("Boxes3D:half_sizes")[0].as_py())
        for chunk in chunks
        if chunk.entity_path in ("/scene/base", "/scene/case")
    )
    assert boxes == 13  # the bottom and 12 sides
