"""`VectorEnv`: B simulated FR3 environments with a Gymnasium-style vector API.

`reset(seed)` draws every episode (procedural scenes or `config.domain`), and
`start_planned(plan)` starts chosen benchmark episodes (`hamnet.sim.domains.EpisodePlan`);
`step(command)` applies one safe command (joint references per control sample, gains,
torque clip) for one policy period and returns the batched observation, the reward terms,
and the termination flags. Environments whose
episode ended are reset inside `step` (auto-reset): the returned observation is then the
first of the new episode, while rewards, flags and `episode_ids` belong to the step that
ended the old one, and `final_observation` keeps the observation that ended it (to bootstrap
the value of a truncated episode). `scenes(env_ids)` describes the current episodes of some
environments: what the Scene message carries, for the shell and the trainer alike.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hamnet.fr3.model import ee_pos_rot6d
from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.messages.scene import SceneDescription
from hamnet.sim import episodes as draw
from hamnet.sim import quaternion
from hamnet.sim.config import SimConfig
from hamnet.sim.curriculum import CurriculumValues, curriculum_values, scene_config_at
from hamnet.sim.domains import EpisodePlan
from hamnet.sim.objects.library import ObjectSet
from hamnet.sim.physics import BatchPhysics
from hamnet.sim.rewards import Potentials, potentials, reward_terms
from hamnet.sim.robot_init import ArmKinematics
from hamnet.sim.termination import termination, workspace_bounds
from hamnet.sim.world import build_world
from hamnet.task.cuboids import NUM_CUBOIDS, TABLE
from hamnet.task.physics import PHYSICS_PARAM_NAMES
from hamnet.task.rewards import REWARD_NAMES

_EPISODE_ARRAYS = (
    "episode_ids",
    "episode_step",
    "object_index",
    "goal_pos",
    "goal_quat",
    "physics_params",
    "start_pose",
)
"""Per-environment arrays of `VectorEnv` a snapshot holds as they are."""

OBJECT_POINTS = 512
"""Surface points per object sent with each scene: the paper's object cloud size."""


@dataclass(frozen=True)
class StepResult:
    """One step of every environment."""

    observation: Observation
    """After any auto-reset: the first observation of a new episode where one started."""
    final_observation: Observation
    """Before any auto-reset: equal to `observation` except in the rows of `reset_ids`,
    which hold the last observation of the episode that ended there (Gymnasium's
    `final_obs`); the value of a truncated episode is bootstrapped from it."""
    reward_terms: np.ndarray
    """(B, R) float32, columns `REWARD_NAMES`."""
    terminated: np.ndarray  # (B,) bool
    truncated: np.ndarray  # (B,) bool
    success: np.ndarray  # (B,) bool
    reason: np.ndarray  # (B,) int8, termination.Reason
    episode_ids: np.ndarray
    """(B,) int64 episode each step belonged to (before any auto-reset)."""
    reset_ids: np.ndarray
    """Environments that started a new episode (their scenes are in `scenes()`)."""


class VectorEnv:
    """The sim's in-process core: no Zenoh, arrays in and out."""

    reward_names = REWARD_NAMES

    def __init__(self, config: SimConfig | None = None) -> None:
        self.config = config = config if config is not None else SimConfig()
        objects = ObjectSet.procedural(config.num_objects, config.seed, config.library)
        if config.object_folder is not None:
            objects = objects + ObjectSet.from_folder(config.object_folder, config.library)
        sized, scale = draw.sized_library(objects, config.objects, config.size_bins)
        self.library = draw.Library.of(sized, scale)
        points_rng = np.random.default_rng(config.seed)
        self.object_points = np.stack(
            [asset.sample_surface(OBJECT_POINTS, points_rng) for asset in sized]
        ).astype(np.float32)
        """(N, P, 3) surface samples of each library entry in its own frame (the object cloud)."""
        if config.backend == "warp":
            from hamnet.sim.warp_physics import WarpPhysics  # Warp only when asked

            self.world = build_world(sized, scene_body=True)
            self.physics: BatchPhysics = WarpPhysics(
                self.world, config.num_envs, config.nthread, config.warp_device
            )
        else:
            self.world = build_world(sized)
            self.physics = BatchPhysics(self.world, config.num_envs, config.nthread)
        self.kinematics = ArmKinematics()
        self.num_envs = config.num_envs
        self.rng = np.random.default_rng(config.seed)
        self.schedule = curriculum_values(0, config.curriculum)
        b = config.num_envs
        self.episode_ids = np.zeros(b, dtype=np.int64)
        self.episode_step = np.zeros(b, dtype=np.int32)
        self._next_episode = 0
        self.object_index = np.zeros(b, dtype=np.int64)
        self.goal_pos = np.zeros((b, 3))
        self.goal_quat = np.tile([1.0, 0.0, 0.0, 0.0], (b, 1))
        self.physics_params = np.zeros((b, len(PHYSICS_PARAM_NAMES)), dtype=np.float32)
        self.start_pose = np.zeros((b, 7), dtype=np.float32)
        self.workspace = (np.full((b, 3), -np.inf), np.full((b, 3), np.inf))
        self.scene_arrays: dict[str, np.ndarray] = {
            "centre": np.zeros((b, NUM_CUBOIDS, 3)),
            "quat": np.zeros((b, NUM_CUBOIDS, 4)),
            "half_extent": np.zeros((b, NUM_CUBOIDS, 3)),
            "active": np.zeros((b, NUM_CUBOIDS), bool),
            "env_code": np.zeros((b, 25), np.float32),
        }
        self.potentials = Potentials(np.zeros(b), np.zeros(b))
        self.reset_seconds = 0.0
        """Wall time spent drawing episodes so far, s."""

    def set_schedule(self, values: CurriculumValues) -> None:
        """Curriculum values for the episodes drawn from now on (the trainer's schedule)."""
        self.schedule = values

    def reset(self, seed: int | None = None) -> Observation:
        """Draw a new episode in every environment."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self._new_episodes(np.arange(self.num_envs))
        return self.observe()

    def start_planned(self, plan: EpisodePlan, env_ids: np.ndarray | None = None) -> Observation:
        """Start the planned episodes `plan` in `env_ids` (K,), every environment if None.

        Row k of the plan gives environment env_ids[k] its domain, object entry, pose pair
        and arm start (`episodes.draw_planned`), whatever `config.domain` says; the same
        rows give the same episodes, in any environment of any batch. Episodes after them
        are drawn as usual (auto-reset in `step`).
        """
        ids = np.arange(self.num_envs) if env_ids is None else np.asarray(env_ids, np.int64)
        started = time.perf_counter()
        drawn = draw.draw_planned(
            self.physics, self.kinematics, self.library, ids, plan, self.config
        )
        self._record(drawn, started)
        return self.observe()

    def step(self, command: Command) -> StepResult:
        """Apply `command` for one policy period, then score, terminate and auto-reset."""
        self.physics.set_gains(command.kp, command.kd, command.tau_limit)
        self.physics.step(command.q_ref, self.config.physics_steps_per_sample)
        self.episode_step += 1
        pos, quat = self._object_pose()
        ends = termination(
            pos,
            quat,
            self.goal_pos,
            self.goal_quat,
            self.workspace,
            self.episode_step,
            self.config.task,
        )
        current = self._potentials(pos, quat)
        rewards = reward_terms(ends.success, self.potentials, current, self.config.task)
        self.potentials = current
        stepped_ids = self.episode_ids.copy()
        done = np.flatnonzero(ends.done)
        final = self.observe()
        if len(done):
            self._new_episodes(done)
        return StepResult(
            observation=self.observe() if len(done) else final,
            final_observation=final,
            reward_terms=rewards,
            terminated=ends.terminated,
            truncated=ends.truncated,
            success=ends.success,
            reason=ends.reason,
            episode_ids=stepped_ids,
            reset_ids=done,
        )

    def observe(self) -> Observation:
        """The current batched observation."""
        w, p = self.world, self.physics
        pos, quat = self._object_pose()
        site_pos = p.bind("site_xpos")[:, w.ee_site]  # (B, 3)
        site_rot = p.bind("site_xmat")[:, w.ee_site].reshape(-1, 3, 3)  # (B, 3, 3)
        return Observation(
            episode_ids=self.episode_ids.copy(),
            episode_step=self.episode_step.copy(),
            q=p.qpos[:, w.robot_qpos].astype(np.float32),
            dq=p.qvel[:, w.robot_dof].astype(np.float32),
            tau=p.bind("qfrc_actuator")[:, w.robot_dof].astype(np.float32),
            ee_pos_rot6d=ee_pos_rot6d(site_pos, site_rot).astype(np.float32),
            goal_pose=np.concatenate([self.goal_pos, self.goal_quat], axis=1).astype(np.float32),
            object_pose=np.concatenate([pos, quat], axis=1).astype(np.float32),
            object_velocity=self._object_velocity(quat).astype(np.float32),
            physics_params=self.physics_params.copy(),
        )

    def scenes(self, env_ids: np.ndarray | None = None) -> SceneDescription:
        """The current episodes of `env_ids` (K,), every environment if None."""
        ids = np.arange(self.num_envs) if env_ids is None else np.asarray(env_ids, np.int64)
        arrays = self.scene_arrays
        entries = self.object_index[ids]  # (K,)
        return SceneDescription(
            env_ids=ids.astype(np.int64),
            episode_ids=self.episode_ids[ids].copy(),
            object_ids=tuple(self.library.objects[int(i)].name for i in entries),
            object_scale=self.library.scale[entries].astype(np.float32),
            object_points=self.object_points[entries],
            cuboid_centre=arrays["centre"][ids].astype(np.float32),
            cuboid_quat=arrays["quat"][ids].astype(np.float32),
            cuboid_half_extent=arrays["half_extent"][ids].astype(np.float32),
            cuboid_active=arrays["active"][ids].copy(),
            env_code=arrays["env_code"][ids].astype(np.float32),
            start_pose=self.start_pose[ids].copy(),
            goal_pose=np.concatenate([self.goal_pos[ids], self.goal_quat[ids]], 1).astype(
                np.float32
            ),
        )

    def snapshot(self) -> tuple[dict[str, np.ndarray], dict[str, object]]:
        """Everything a run continues from besides what the config rebuilds: the physics
        (`BatchPhysics.snapshot`, under `physics.`), the episodes' bookkeeping and drawn
        parameters (arrays), and the episode generator's state, curriculum values and
        counters (JSON-serialisable metadata)."""
        arrays = {f"physics.{name}": values for name, values in self.physics.snapshot().items()}
        arrays.update({name: getattr(self, name).copy() for name in _EPISODE_ARRAYS})
        arrays.update({f"scene.{name}": a.copy() for name, a in self.scene_arrays.items()})
        arrays["workspace.low"], arrays["workspace.high"] = (a.copy() for a in self.workspace)
        arrays["potentials.goal"] = self.potentials.goal.copy()
        arrays["potentials.contact"] = self.potentials.contact.copy()
        meta = {
            "rng": self.rng.bit_generator.state,
            "next_episode": self._next_episode,
            "schedule": self.schedule.as_dict(),
            "reset_seconds": self.reset_seconds,
        }
        return arrays, meta

    def restore(self, arrays: dict[str, np.ndarray], meta: dict[str, object]) -> None:
        """Continue from `snapshot`'s arrays and metadata, on an env of the same config."""
        physics = {name[8:]: a for name, a in arrays.items() if name.startswith("physics.")}
        self.physics.restore(physics)
        for name in _EPISODE_ARRAYS:
            getattr(self, name)[...] = arrays[name]
        for name, values in self.scene_arrays.items():
            values[...] = arrays[f"scene.{name}"]
        self.workspace[0][...] = arrays["workspace.low"]
        self.workspace[1][...] = arrays["workspace.high"]
        goal, contact = arrays["potentials.goal"], arrays["potentials.contact"]
        self.potentials = Potentials(np.array(goal), np.array(contact))
        self.rng.bit_generator.state = meta["rng"]
        self._next_episode = int(meta["next_episode"])
        self.schedule = CurriculumValues(**meta["schedule"])
        self.reset_seconds = float(meta["reset_seconds"])

    def _object_velocity(self, quat: np.ndarray) -> np.ndarray:
        """(B, 6) object linear and angular velocity in the world frame (the contract's).

        MuJoCo's free-joint qvel holds the linear velocity in the world frame but the
        angular velocity in the body frame; `quat` (B, 4) wxyz rotates it to the world."""
        qvel = self.physics.qvel[:, self.world.object_dof]  # (B, 6)
        omega = np.einsum("bij,bj->bi", quaternion.to_matrix(quat), qvel[:, 3:])  # (B, 3)
        return np.concatenate([qvel[:, :3], omega], axis=1)

    def _object_pose(self) -> tuple[np.ndarray, np.ndarray]:
        qpos = self.physics.qpos[:, self.world.object_qpos]  # (B, 7)
        return qpos[:, :3], qpos[:, 3:]

    def _potentials(self, pos: np.ndarray, quat: np.ndarray) -> Potentials:
        tip = self.physics.bind("site_xpos")[:, self.world.ee_site]  # (B, 3)
        bbox = self.library.bbox[self.object_index]  # (B, 2, 3)
        return potentials(pos, quat, self.goal_pos, self.goal_quat, bbox, tip, self.config.task)

    def _new_episodes(self, env_ids: np.ndarray) -> None:
        started = time.perf_counter()
        scene_config = scene_config_at(self.schedule, self.config.scene)
        drawn = draw.draw_episodes(
            self.rng,
            self.physics,
            self.kinematics,
            self.library,
            env_ids,
            self.config,
            scene_config,
            self.schedule.p_near_init,
        )
        self._record(drawn, started)

    def _record(self, drawn: draw.Episodes, started: float) -> None:
        """Keep what was drawn for `drawn.env_ids` and start their episodes' bookkeeping."""
        env_ids = drawn.env_ids
        self.object_index[env_ids] = drawn.object_index
        self.goal_pos[env_ids] = drawn.goal_pos
        self.goal_quat[env_ids] = drawn.goal_quat
        self.physics_params[env_ids] = drawn.physics_params
        scenes = drawn.scenes
        lo, hi = workspace_bounds(
            scenes.centre[:, TABLE], scenes.half_extent[:, TABLE], self.config.task
        )
        self.workspace[0][env_ids], self.workspace[1][env_ids] = lo, hi
        for name, array in self.scene_arrays.items():
            array[env_ids] = getattr(scenes, name)
        self.episode_ids[env_ids] = self._next_episode + np.arange(len(env_ids))
        self._next_episode += len(env_ids)
        self.episode_step[env_ids] = 0
        pos, quat = self._object_pose()
        self.start_pose[env_ids] = np.concatenate([pos, quat], axis=1)[env_ids]
        fresh = self._potentials(pos, quat)
        self.potentials.goal[env_ids] = fresh.goal[env_ids]
        self.potentials.contact[env_ids] = fresh.contact[env_ids]
        self.reset_seconds += time.perf_counter() - started
