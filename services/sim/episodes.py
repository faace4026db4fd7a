"""Drawing new episodes for a set of environments: object, size and physics, scene, goal and
start poses, and the arm's start, written into the batched physics.

Scenes are procedural or, with `SimConfig.domain`, one benchmark domain
(`hamnet.sim.domains`); `draw_planned` starts the episodes of an `EpisodePlan`, each from
its own seeds. An environment whose placement fails (no pose fits its scene) gets a new
scene until one fits. Objects come in `size_bins` discrete sizes (meshes are compiled once), so the library the
world is built from holds every object at every size; `Library` keeps, per entry, the
stable poses and heights that placement and the tight ceiling need.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from hamnet.fr3.limits import Q_HOME
from hamnet.sim import domains, quaternion, robot, robot_init
from hamnet.sim.config import SimConfig
from hamnet.sim.objects.library import ObjectSet
from hamnet.sim.objects.randomization import ObjectRandomization, max_rule_frictions
from hamnet.sim.objects.spec import restitution_solref
from hamnet.sim.physics import BatchPhysics
from hamnet.sim.placement import Placement, PlacementConfig, sample_placements
from hamnet.sim.scene import SceneBatch, sample_scenes
from hamnet.sim.scene_config import SceneConfig

log = logging.getLogger(__name__)

SCENES_PER_ROUND = 8
"""Candidate scenes drawn at once for an environment whose placement is still pending:
one batched draw instead of many small ones (a large object fits in few scenes)."""

T = TypeVar("T", SceneBatch, Placement)
D = TypeVar("D")

SceneSampler = Callable[[np.random.Generator, np.ndarray], SceneBatch]
"""(rng, object_height (K,)) -> K scenes: `sample_scenes` or a domain's builder, configured."""


def sized_library(
    objects: ObjectSet, sizes: ObjectRandomization, bins: int
) -> tuple[ObjectSet, np.ndarray]:
    """Every object at `bins` sizes spread over `sizes.radius` (bounding radius, m) or, when
    that is None, over `sizes.scale`; entries are named `<name>@x<scale>`.

    Returns:
        The sized set and the scale of each entry relative to its object, (N * bins,).
    """
    entries, scales = [], []
    for asset in objects:
        if sizes.radius is not None:
            factors = np.linspace(*sizes.radius, bins) / asset.radius  # (bins,)
        else:
            factors = np.linspace(*sizes.scale, bins)  # (bins,)
        for factor in factors:
            entries.append(
                dataclasses.replace(asset.scaled(factor), name=f"{asset.name}@x{factor:.3f}")
            )
            scales.append(factor)
    return ObjectSet(tuple(entries)), np.array(scales)


@dataclass(frozen=True, eq=False)
class Library:
    """Per library entry (N entries, K stable poses padded), what episodes are drawn from."""

    objects: ObjectSet
    stable_quat: np.ndarray
    """(N, K, 4) stable orientations, wxyz."""
    probability: np.ndarray
    """(N, K) how often each orientation occurs (0 for padding)."""
    planar_radius: np.ndarray
    """(N, K) m."""
    rest_height: np.ndarray
    """(N, K) centre above the support, m."""
    top_height: np.ndarray
    """(N, K) top above the support, m."""
    bbox: np.ndarray
    """(N, 2, 3) bounding box in the object frame, m."""
    scale: np.ndarray
    """(N,) size relative to the generated or imported object."""

    @classmethod
    def of(cls, objects: ObjectSet, scale: np.ndarray) -> Library:
        table = objects.stable_table()
        top = np.stack(
            [
                [(_rotate(asset.mesh.vertices, q)[:, 2]).max() for q in orientations]
                for asset, orientations in zip(objects, table.orientations, strict=True)
            ]
        )  # (N, K), centre to top
        return cls(
            objects=objects,
            stable_quat=table.orientations,
            probability=table.probabilities,
            planar_radius=table.planar_radii,
            rest_height=table.resting_heights,
            top_height=table.resting_heights + top,
            bbox=np.stack([asset.bbox for asset in objects]),
            scale=scale,
        )


def _rotate(points: np.ndarray, quat: np.ndarray) -> np.ndarray:
    return points @ quaternion.to_matrix(quat).T


@dataclass(frozen=True, eq=False)
class Episodes:
    """What was drawn for K environments."""

    env_ids: np.ndarray
    object_index: np.ndarray
    """(K,) library entry."""
    scenes: SceneBatch
    goal_pos: np.ndarray
    """(K, 3) m."""
    goal_quat: np.ndarray
    """(K, 4) wxyz."""
    physics_params: np.ndarray
    """(K, P): the columns `hamnet.task.physics.PHYSICS_PARAM_NAMES` names."""
    near_start: np.ndarray
    """(K,) bool: the arm started near the object."""
    start_fallback: np.ndarray
    """(K,) bool: no drawn start was collision-free; the arm starts retracted (or at home)."""


def draw_episodes(
    rng: np.random.Generator,
    physics: BatchPhysics,
    kinematics: robot_init.ArmKinematics,
    library: Library,
    env_ids: np.ndarray,
    config: SimConfig,
    scene_config: SceneConfig,
    p_near_init: float,
) -> Episodes:
    """Draw and apply new episodes for `env_ids`: procedural scenes from `scene_config`, or
    the benchmark domain `config.domain`; their state is reset at rest."""
    entry = rng.integers(len(library.objects), size=len(env_ids))  # (K,)
    if config.domain:
        builder = domains.domain_builder(config.domain)
        sampler = functools.partial(builder, config=scene_config)
        placement_config = domains.pair_placement(config.task)
    else:
        sampler = functools.partial(sample_scenes, config=scene_config)
        placement_config = config.start_goal_placement
    scenes, placement = _scenes_and_placements(
        rng, library, entry, sampler, placement_config, config.placement.max_scene_draws
    )
    drawn = (entry, scenes, placement)
    return _apply(rng, rng, physics, kinematics, library, env_ids, drawn, config, p_near_init)


def draw_planned(
    physics: BatchPhysics,
    kinematics: robot_init.ArmKinematics,
    library: Library,
    env_ids: np.ndarray,
    plan: domains.EpisodePlan,
    config: SimConfig,
) -> Episodes:
    """Apply the planned episodes `plan` (K rows) to `env_ids` (K,), each from its own seeds.

    Row k's pair seed draws its domain's scene, start and goal (apart in position and in
    orientation, `domains.pair_placement`), then the object's and arm's physics; its init
    seed draws a random, collision-free arm start (`_arm_starts`, no near starts, as the
    paper's benchmark). Rows are drawn one at a time, so a row's episode never depends on
    the others.
    """
    if len(plan) != len(env_ids) or np.any(plan.object_index >= len(library.objects)):
        raise ValueError("the plan needs one row per environment and entries of the library")
    placement_config = domains.pair_placement(config.task)
    drawn = []
    for k in range(len(env_ids)):
        pair = np.random.default_rng(int(plan.pair_seed[k]))
        builder = domains.domain_builder(domains.DOMAIN_NAMES[plan.domain[k]])
        sampler = functools.partial(builder, config=config.scene)
        entry = plan.object_index[k : k + 1]  # (1,)
        scenes, placement = _scenes_and_placements(
            pair, library, entry, sampler, placement_config, config.placement.max_scene_draws
        )
        arm = np.random.default_rng(int(plan.init_seed[k]))
        episode = (entry, scenes, placement)
        ids = env_ids[k : k + 1]
        drawn.append(_apply(pair, arm, physics, kinematics, library, ids, episode, config, 0.0))
    return _concatenate(drawn)


def _apply(
    rng: np.random.Generator,
    arm_rng: np.random.Generator,
    physics: BatchPhysics,
    kinematics: robot_init.ArmKinematics,
    library: Library,
    env_ids: np.ndarray,
    drawn: tuple[np.ndarray, SceneBatch, Placement],
    config: SimConfig,
    p_near_init: float,
) -> Episodes:
    """Draw the physics of episodes whose object `entry` (K,), scenes and placement are
    drawn, with `rng`, and the arm's starts with `arm_rng` (the same generator but for
    planned episodes); write them all into `physics` for `env_ids` (K,)."""
    entry, scenes, placement = drawn
    count = len(env_ids)
    draws = _object_draws(rng, config, count)
    robot_friction, object_friction, scene_friction = max_rule_frictions(
        draws["hand_friction"], draws["friction"], scenes.friction
    )  # PhysX's averages under MuJoCo's max rule
    physics.set_scene(env_ids, scenes.centre, scenes.quat, scenes.half_extent, scene_friction)
    solref = restitution_solref(draws["restitution"])
    physics.set_object(env_ids, entry, draws["mass"], object_friction, solref)
    physics.set_robot_friction(env_ids, robot_friction)
    joint_dynamics = robot.draw_joint_dynamics(rng, config.joint_dynamics, count)  # (K, 3)
    physics.set_joint_dynamics(env_ids, joint_dynamics)
    near = rng.random(count) < p_near_init  # (K,)
    radius = library.planar_radius[entry].max(axis=1)  # (K,)
    cuboids = robot_init.Cuboids(scenes.centre, scenes.quat, scenes.half_extent, scenes.active)
    q, fallback = _arm_starts(
        arm_rng, physics, kinematics, env_ids, near, placement, radius, cuboids, config
    )
    physics.set_state(env_ids, q, placement.start_pos, placement.start_quat)
    columns = [draws[name] for name in ("mass", "friction", "restitution", "hand_friction")]
    columns += [scenes.friction, library.scale[entry], *joint_dynamics.T]
    params = np.stack(columns, axis=1).astype(np.float32)  # (K, P), PHYSICS_PARAM_NAMES
    return Episodes(
        env_ids, entry, scenes, placement.goal_pos, placement.goal_quat, params, near, fallback
    )


def _scenes_and_placements(
    rng: np.random.Generator,
    library: Library,
    entry: np.ndarray,
    sampler: SceneSampler,
    placement_config: PlacementConfig,
    max_scene_draws: int,
) -> tuple[SceneBatch, Placement]:
    """A scene from `sampler` and valid goal and start poses for each object `entry` (K,).

    `sample_placements` gives up on a scene where no candidate fits (rows with `valid`
    False hold unchecked poses, e.g. overhanging a plate); those environments get a new
    scene, up to `max_scene_draws` in all. The object is kept, so large objects are drawn
    as often as small ones.

    Raises:
        RuntimeError: some object found no placement in `max_scene_draws` scenes.
    """
    height = library.top_height[entry].max(axis=1)  # (K,), tallest resting pose
    rows = np.arange(len(entry))  # environments still without a valid placement
    scenes = placement = None
    per_round = SCENES_PER_ROUND
    for _ in range(-(-max_scene_draws // per_round)):
        # `per_round` candidate scenes per pending environment in one batched draw.
        tries = np.repeat(rows, per_round)  # (R * per_round,)
        drawn = entry[tries]
        new_scenes = sampler(rng, height[tries])
        new_placement = sample_placements(
            rng,
            new_scenes,
            library.stable_quat[drawn],
            library.planar_radius[drawn],
            library.rest_height[drawn],
            library.top_height[drawn],
            placement_config,
            pose_weight=library.probability[drawn],
        )
        valid = new_placement.valid.reshape(len(rows), per_round)  # (R, per_round)
        pick = np.arange(len(rows)) * per_round + valid.argmax(axis=1)  # first valid, else 0
        new_scenes, new_placement = _take(new_scenes, pick), _take(new_placement, pick)
        if scenes is None:
            scenes, placement = new_scenes, new_placement
        else:
            scenes = _with_rows(scenes, rows, new_scenes)
            placement = _with_rows(placement, rows, new_placement)
        rows = rows[~valid.any(axis=1)]
        if len(rows) == 0:
            return scenes, placement
    names = sorted({library.objects[int(i)].name for i in entry[rows]})
    raise RuntimeError(
        f"no valid placement in {max_scene_draws} scenes for {names}: "
        "lower objects.radius or raise placement.max_scene_draws"
    )


def _take(batch: T, rows: np.ndarray) -> T:
    """`batch` (a dataclass of (K, ...) arrays) restricted to `rows`."""
    values = {field.name: getattr(batch, field.name)[rows] for field in dataclasses.fields(batch)}
    return dataclasses.replace(batch, **values)


def _with_rows(batch: T, rows: np.ndarray, new: T) -> T:
    """`batch` (a dataclass of (K, ...) arrays) with rows `rows` taken from `new` (R, ...)."""
    values = {}
    for field in dataclasses.fields(batch):
        value = getattr(batch, field.name).copy()
        value[rows] = getattr(new, field.name)
        values[field.name] = value
    return dataclasses.replace(batch, **values)


def _concatenate(parts: list[D]) -> D:
    """One dataclass of arrays (nested ones included) from `parts`, rows after rows."""
    values = {}
    for field in dataclasses.fields(parts[0]):
        column = [getattr(part, field.name) for part in parts]
        nested = dataclasses.is_dataclass(column[0])
        values[field.name] = _concatenate(column) if nested else np.concatenate(column)
    return dataclasses.replace(parts[0], **values)


def _object_draws(rng: np.random.Generator, config: SimConfig, count: int) -> dict[str, np.ndarray]:
    ranges = config.objects
    return {
        "mass": rng.uniform(*ranges.mass, size=count),
        "friction": rng.uniform(*ranges.friction, size=count),
        "restitution": rng.uniform(*ranges.restitution, size=count),
        "hand_friction": rng.uniform(*ranges.hand_friction, size=count),
    }


def _arm_starts(
    rng: np.random.Generator,
    physics: BatchPhysics,
    kinematics: robot_init.ArmKinematics,
    env_ids: np.ndarray,
    near: np.ndarray,
    placement: Placement,
    object_radius: np.ndarray,
    cuboids: robot_init.Cuboids,
    config: SimConfig,
) -> tuple[np.ndarray, np.ndarray]:
    """(K, J) collision-free arm starts with the object at its start: near or random draws,
    then the fallbacks; and (K,) whether each environment fell back."""
    object_pos, object_quat = placement.start_pos, placement.start_quat  # (K, 3), (K, 4)
    goal_pos = placement.goal_pos  # (K, 3)
    init = config.robot_init
    q = np.tile(robot_init.RETRACTED, (len(env_ids), 1))
    pending = np.ones(len(env_ids), dtype=bool)
    fell_back = np.zeros(len(env_ids), dtype=bool)
    draws = [None] * init.rounds + [robot_init.RETRACTED, Q_HOME]
    for round_index, fallback in enumerate(draws):
        fell_back |= pending & (fallback is not None)
        rows = np.flatnonzero(pending)
        if len(rows) == 0:
            break
        if fallback is None:
            candidate = robot_init.random_configurations(rng, len(rows), init.range_fraction)
            reached = np.ones(len(rows), dtype=bool)
            is_near = np.flatnonzero(near[rows])
            if len(is_near):
                chosen = rows[is_near]
                scene = robot_init.Cuboids(*(field[chosen] for field in vars(cuboids).values()))
                targets = robot_init.near_targets(
                    rng,
                    object_pos[chosen],
                    object_radius[chosen],
                    scene,
                    init,
                    round_index,
                    goal_pos[chosen],
                )
                start, found = robot_init.near_seeds(
                    rng,
                    robot_init.posture_buffer(init.posture_count, init.range_fraction),
                    targets,
                    object_pos[chosen],
                    object_radius[chosen],
                    scene,
                    init.posture_candidates,
                    nearest=round_index == 0,
                )
                start[~found] = robot_init.ik_seeds(
                    rng, int((~found).sum()), init.ik_seed_spread, init.range_fraction
                )
                candidate[is_near], distance = robot_init.solve_ik(kinematics, start, targets, init)
                reached[is_near] = distance <= init.ik_tolerance
        else:
            candidate, reached = np.tile(fallback, (len(rows), 1)), np.ones(len(rows), dtype=bool)
        ids = env_ids[rows]
        physics.set_state(ids, candidate, object_pos[rows], object_quat[rows])
        ok = reached & ~robot_init.arm_in_contact(physics, ids)
        q[rows[ok]] = candidate[ok]
        pending[rows[ok]] = False
    if pending.any():
        log.warning("%d arm start(s) in contact after every draw: retracted", int(pending.sum()))
    return q, fell_back
