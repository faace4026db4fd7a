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
from hamnet.perception.config import student_clouds
from hamnet.perception.core import Perception
from hamnet.policy import inputs as builder
from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture
from hamnet.policy.rollout_record import cat_rows
from hamnet.safety.config import in_action_space, with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.trainer.algorithms.dagger import Demonstrations, beta_at
from hamnet.trainer.collection.seat import Seat
from hamnet.trainer.collection.sources import Collected, frozen_encoder, run_clouds
from hamnet.trainer.collection.worker import Worker
from hamnet.trainer.config import DaggerConfig
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import Arrays, Snapshot, nest, part
from hamnet.trainer.runners.stopping import always, check

ROLES = ("teacher", "student")


class DaggerWorker(Worker):
    """B environments stepped by the teacher or the student, labelled by the teacher."""

    def __init__(
        self,
        env: VectorEnv,
        perceptions: dict[str, Perception | None],
        safety: SafetyFilter,
        seed: int = 0,
    ) -> None:
        """`perceptions`: the teacher's and the student's (None for a policy without clouds)."""
        super().__init__(env, {role: Seat(perceptions[role]) for role in ROLES}, safety, seed)
        self.teacher_acts = torch.zeros(env.num_envs, dtype=torch.bool)
        """(B,) the teacher acts the environment's current episode."""
        self.undrawn = torch.ones(env.num_envs, dtype=torch.bool)
        """(B,) episodes that began since the last draw (drawn at their first step, with beta
        at that step's counter)."""

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
                    "object_velocity",
                )
            },
        )

    def _step(
        self, teacher: Policy, student: Policy, env_transitions: int, beta: float
    ) -> dict[str, Any]:
        """Draw who acts new episodes, act with both, step with the chosen action."""
        obs = self.observation
        ids, step = torch.as_tensor(obs.episode_ids), torch.as_tensor(obs.episode_step)
        carry = self.seats["student"].carry
        starts = (step == 0) | (  # begin_step's rule
            ids != (carry.episode_ids if carry is not None else -1)
        )
        policies = {"teacher": teacher, "student": student}
        self.begin(policies)
        coin = torch.rand(self.num_envs, generator=self.generator) < beta
        self.teacher_acts = torch.where(self.undrawn, coin, self.teacher_acts)
        self.undrawn[:] = False
        robot = builder.robot_observation(obs)
        inputs = {
            role: self.seats[role].inputs(policies[role], robot, self.pose_noise, self.generator)
            for role in ROLES
        }
        label = teacher.act(inputs["teacher"], deterministic=True)
        own = student.act(inputs["student"], deterministic=True)
        action = torch.where(self.teacher_acts[:, None], label.action, own.action)  # (B, A)
        result = self.env.step(self.command(action, env_transitions))
        for role, out in (("teacher", label), ("student", own)):
            self.seats[role].end(action, out.memory)
        self.undrawn[torch.as_tensor(result.reset_ids, dtype=torch.long)] = True
        self.start(result.reset_ids, result.observation)
        return {
            "inputs": inputs["student"],
            "labels": label.action,
            "label_values": label.values,
            "teacher_acted": self.teacher_acts.clone(),
            "starts": starts,
            "rewards": torch.as_tensor(result.reward_terms, dtype=torch.float32),
            "dones": torch.as_tensor(result.terminated | result.truncated),
            "success": torch.as_tensor(result.success),
            "object_velocity": torch.as_tensor(obs.object_velocity),
        }

    def snapshot(self) -> Snapshot:
        """The shared worker's state and who acts."""
        arrays, meta = super().snapshot()
        draws, draws_meta = nest(
            {"draws": ({"teacher_acts": self.teacher_acts, "undrawn": self.undrawn}, {})}
        )
        return {**arrays, **draws}, {**meta, **draws_meta}

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot` (on a worker built from the same config)."""
        super().restore(arrays, meta)
        draws = part(arrays, meta, "draws")[0]
        self.teacher_acts = torch.tensor(draws["teacher_acts"])
        self.undrawn = torch.tensor(draws["undrawn"])


STUDENT_PERCEPTION_SEED = 1
"""Added to the run's seed for the student's perception (its noise and dropout), so its
draws are not the teacher's perception's."""


def build_dagger_worker(config: RunConfig, teacher: Policy) -> DaggerWorker:
    """The run's `config.num_envs` environments in one group, with the teacher's perception
    (every surface) and the student's (`config.architecture`'s, `student_clouds()`) on one
    frozen encoder (the run's: it must be the one the teacher was trained with), and the
    training filter reading actions in the teacher's space."""
    b, seed = config.num_envs, config.seed
    student = architecture(config.architecture).config
    needs = {"teacher": teacher.config.clouds, "student": student.clouds}
    encoder = frozen_encoder(config)[0] if any(needs.values()) else None
    clouds = {"teacher": run_clouds(config), "student": run_clouds(config, student_clouds())}
    offsets = {"teacher": 0, "student": STUDENT_PERCEPTION_SEED}
    perceptions = {
        role: Perception(encoder, b, clouds[role], seed=seed + offsets[role])
        if needs[role]
        else None
        for role in ROLES
    }
    env = VectorEnv(dataclasses.replace(config.sim, num_envs=b, seed=seed))
    training = in_action_space(with_profile("training"), teacher.config.action_space)
    safety = SafetyFilter(np.zeros((b, NUM_JOINTS)), training)
    return DaggerWorker(env, perceptions, safety, seed)


class InProcessDagger:
    """DAgger's rollouts from one `DaggerWorker` in this process (a `RolloutSource` whose
    rollouts are `Demonstrations`)."""

    def __init__(self, config: RunConfig, teacher: Policy, dagger: DaggerConfig) -> None:
        self.worker = build_dagger_worker(config, teacher)
        self.teacher, self.dagger = teacher, dagger

    @property
    def num_envs(self) -> int:
        return self.worker.num_envs

    @property
    def alone_in_update(self) -> bool:
        return True

    def collect(
        self,
        policy: Policy,
        steps: int,
        env_transitions: int,
        version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:
        """T = `steps` steps of every environment, the student `policy` acting where beta's
        coin says (at the counter `env_transitions`), the teacher labelling."""
        policy.eval()
        return Collected(
            self.worker.collect(self.teacher, policy, steps, env_transitions, self.dagger, running)
        )

    def snapshot(self) -> Snapshot:
        return self.worker.snapshot()

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        self.worker.restore(arrays, meta)
