"""DAgger's rollout core: B environments where teacher and student see every state side by
side and one of them acts, chosen per environment and per episode with probability beta.

The teacher reads its privileged inputs and clouds of every surface (perception as in
PPO); the student reads only what the real robot gives: the pose estimate
(`PoseNoiseConfig`, through the one input builder) and clouds as the four cameras see them
(a second `Perception` on the same frozen encoder, `student_clouds()`). Both act with their
mean: the teacher's mean is the label of every visited state, and the student is judged,
and meant to be served, by its mean (sampling with its scheduled std would visit states the
deployed student never reaches). The executed action becomes both policies' previous
action, as it is on the robot.

Who acts is drawn per episode, not per step: an episode acted by the student alone shows
the states its own errors lead to and the recoveries the teacher labels there, which is
what DAgger exists for; a per-step coin would let the teacher undo each error a step later
and feed the GRU a history no single policy produced. Shapes: T steps, B environments,
A action components, R reward terms.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.perception.config import CloudConfig, student_clouds
from hamnet.perception.core import Perception, Percepts
from hamnet.policy import inputs as builder
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture
from hamnet.policy.rollout_record import cat_rows
from hamnet.safety.config import with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.trainer.algorithms.dagger import Demonstrations, beta_at
from hamnet.trainer.collection.rollout_worker import scenes_of, tokens_of
from hamnet.trainer.collection.sources import frozen_encoder
from hamnet.trainer.config import DaggerConfig
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import (
    Arrays,
    Snapshot,
    array_dataclass,
    fields_of,
    generator_state,
    nest,
    part,
    set_generator_state,
    tensor_dataclass,
)
from hamnet.trainer.runners.stopping import always, check

ROLES = ("teacher", "student")


class DaggerWorker:
    """B environments stepped by the teacher or the student, labelled by the teacher."""

    def __init__(
        self,
        env: VectorEnv,
        perceptions: dict[str, Perception | None],
        safety: SafetyFilter,
        seed: int = 0,
    ) -> None:
        """`perceptions`: the teacher's and the student's (None for a policy without clouds)."""
        self.env, self.safety, self.perceptions = env, safety, perceptions
        self.observation: Observation = env.reset(seed=seed)
        every = np.arange(env.num_envs)
        self.safety.start_episodes(every, self.observation.q.astype(np.float64))
        self.percepts: dict[str, Percepts | None] = dict.fromkeys(ROLES)
        self._perceive(every)
        self.carries: dict[str, builder.Carry | None] = dict.fromkeys(ROLES)
        self.generator = torch.Generator().manual_seed(seed)
        """Of who acts each episode and of the student's pose-estimate error."""
        self.pose_noise = PoseNoiseConfig()
        self.teacher_acts = torch.zeros(env.num_envs, dtype=torch.bool)
        """(B,) the teacher acts the environment's current episode."""
        self.undrawn = torch.ones(env.num_envs, dtype=torch.bool)
        """(B,) episodes that began since the last draw (drawn at their first step, with beta
        at that step's counter)."""

    @property
    def num_envs(self) -> int:
        return self.env.num_envs

    @torch.no_grad()
    def collect(
        self,
        teacher: Policy,
        student: Policy,
        steps: int,
        env_transitions: int,
        config: DaggerConfig,
        running: Callable[[], bool] = always,
    ) -> Demonstrations:
        """`steps` steps of every environment from the counter `env_transitions`;
        InterruptedError once `running()` turns False before they are done."""
        records = []
        for t in range(steps):
            check(running)
            counter = env_transitions + t * self.num_envs
            records.append(self._step(teacher, student, counter, beta_at(counter, config)))
        stack = lambda key: torch.stack([r[key] for r in records])
        return Demonstrations(
            inputs=cat_rows([r["inputs"] for r in records]),
            first=records[0]["starts"],
            **{
                key: stack(key)
                for key in (
                    "labels",
                    "label_values",
                    "teacher_acted",
                    "rewards",
                    "dones",
                    "success",
                )
            },
        )

    def _step(
        self, teacher: Policy, student: Policy, env_transitions: int, beta: float
    ) -> dict[str, Any]:
        """Draw who acts new episodes, act with both, step with the chosen action."""
        obs = self.observation
        ids, step = torch.as_tensor(obs.episode_ids), torch.as_tensor(obs.episode_step)
        for role, policy in zip(ROLES, (teacher, student), strict=True):
            if self.carries[role] is None:
                self.carries[role] = builder.initial_carry(policy, self.num_envs)
        starts = (step == 0) | (ids != self.carries["student"].episode_ids)  # begin_step's rule
        self.carries = {role: builder.begin_step(c, ids, step) for role, c in self.carries.items()}
        coin = torch.rand(self.num_envs, generator=self.generator) < beta
        self.teacher_acts = torch.where(self.undrawn, coin, self.teacher_acts)
        self.undrawn[:] = False
        robot = builder.robot_observation(obs)
        inputs = {
            role: builder.policy_inputs(
                policy.config,
                self.carries[role],
                robot,
                tokens_of(self.percepts[role]),
                pose_noise=self.pose_noise,
                generator=self.generator,
            )
            for role, policy in zip(ROLES, (teacher, student), strict=True)
        }
        label = teacher.act(inputs["teacher"], deterministic=True)
        own = student.act(inputs["student"], deterministic=True)
        action = torch.where(self.teacher_acts[:, None], label.action, own.action)  # (B, A)
        safe = self.safety.command(
            action.numpy().astype(np.float64),
            obs.q.astype(np.float64),
            obs.dq.astype(np.float64),
            env_transitions,
        )
        result = self.env.step(Command(safe.q_ref, safe.kp, safe.kd, safe.tau_limit))
        for role, out in (("teacher", label), ("student", own)):
            self.carries[role] = builder.end_step(self.carries[role], action, out.memory)
        if len(result.reset_ids):
            self.safety.start_episodes(
                result.reset_ids, result.observation.q[result.reset_ids].astype(np.float64)
            )
            self.undrawn[torch.as_tensor(result.reset_ids)] = True
        self.observation = result.observation
        self._perceive(result.reset_ids)
        return {
            "inputs": inputs["student"],
            "labels": label.action,
            "label_values": label.values,
            "teacher_acted": self.teacher_acts.clone(),
            "starts": starts,
            "rewards": torch.as_tensor(result.reward_terms, dtype=torch.float32),
            "dones": torch.as_tensor(result.terminated | result.truncated),
            "success": torch.as_tensor(result.success),
        }

    def _perceive(self, started: np.ndarray) -> None:
        """Both policies' percepts of the current observation; new caches for `started`."""
        pose = torch.as_tensor(self.observation.object_pose)
        for role, perception in self.perceptions.items():
            if perception is None:
                continue
            if len(started):
                perception.start_episodes(scenes_of(self.env, started))
            self.percepts[role] = perception.step(pose)

    def snapshot(self) -> Snapshot:
        """The whole state this worker continues from: env, safety filter, both perceptions,
        percepts and carries, the observation, the generator and who acts."""
        parts = {
            "env": self.env.snapshot(),
            "safety": self.safety.snapshot(),
            "observation": (fields_of(self.observation), {}),
            "generator": ({"state": generator_state(self.generator)}, {}),
            "draws": ({"teacher_acts": self.teacher_acts, "undrawn": self.undrawn}, {}),
        }
        for role, perception in self.perceptions.items():
            if perception is not None:
                parts[f"{role}.perception"] = perception.snapshot()
                parts[f"{role}.percepts"] = (fields_of(self.percepts[role]), {})
            if self.carries[role] is not None:
                parts[f"{role}.carry"] = (fields_of(self.carries[role]), {})
        return nest(parts)

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot` (on a worker built from the same config)."""
        self.env.restore(*part(arrays, meta, "env"))
        self.safety.restore(*part(arrays, meta, "safety"))
        self.observation = array_dataclass(Observation, part(arrays, meta, "observation")[0])
        set_generator_state(self.generator, part(arrays, meta, "generator")[0]["state"])
        draws = part(arrays, meta, "draws")[0]
        self.teacher_acts = torch.tensor(draws["teacher_acts"])
        self.undrawn = torch.tensor(draws["undrawn"])
        for role, perception in self.perceptions.items():
            if perception is not None:
                perception.restore(*part(arrays, meta, f"{role}.perception"))
                self.percepts[role] = tensor_dataclass(
                    Percepts, part(arrays, meta, f"{role}.percepts")[0]
                )
            self.carries[role] = None
            if f"{role}.carry" in meta:
                carry = part(arrays, meta, f"{role}.carry")[0]
                self.carries[role] = tensor_dataclass(builder.Carry, carry)


STUDENT_PERCEPTION_SEED = 1
"""Added to the run's seed for the student's perception (its noise and dropout), so its
draws are not the teacher's perception's."""


def build_dagger_worker(config: RunConfig, teacher: Policy) -> DaggerWorker:
    """The run's `config.num_envs` environments in one group, with the teacher's perception
    (every surface) and the student's (`config.architecture`'s, `student_clouds()`) on one
    frozen encoder (the run's: it must be the one the teacher was trained with)."""
    b, seed = config.num_envs, config.seed
    student = architecture(config.architecture).config
    needs = {"teacher": teacher.config.clouds, "student": student.clouds}
    encoder = frozen_encoder(config)[0] if any(needs.values()) else None
    clouds = {"teacher": CloudConfig(), "student": student_clouds()}
    offsets = {"teacher": 0, "student": STUDENT_PERCEPTION_SEED}
    perceptions = {
        role: Perception(encoder, b, clouds[role], seed=seed + offsets[role])
        if needs[role]
        else None
        for role in ROLES
    }
    env = VectorEnv(dataclasses.replace(config.sim, num_envs=b, seed=seed))
    safety = SafetyFilter(np.zeros((b, NUM_JOINTS)), with_profile("training"))
    return DaggerWorker(env, perceptions, safety, seed)
