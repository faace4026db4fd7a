"""The rollout worker's core: the in-process cores of sim, perception, policy and the safety
filter's training profile in one loop, collecting T steps of B environments for PPO.

A policy without clouds (the state-only baseline) runs without perception. This is the
fast path of training (the pattern of Sample Factory's or IMPALA's actors): no
messages between the cores, the same code as the services (`VectorEnv`, `Perception`,
the policy's one input builder `hamnet.policy.inputs`, `SafetyFilter`). Per step it keeps
what the learner needs: the policy inputs, action, log-probability, value per reward term,
reward terms and episode ends, and for a truncated episode V(its final state), which the
learner adds, discounted, to that step's (scaled) reward as the authors bootstrap timeouts
(`ham/src/ham/models/rl/v6/ppo.py:826-833`), so GAE can treat every end alike. The discount
is the learner's alone: a worker needs no PPO setting. A student (a policy without
privileged inputs) reads the sim's true object pose only through the pose estimator's
error model (`PoseNoiseConfig`), as the policy service does: the sim is no estimator.
A guided run's worker (`GuideConfig`) also records the scripted pusher's action in every
state it acts in (`Rollout.guide`), read off the sim's true state.
Shapes: T steps, B environments, A action, R reward terms.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.perception.core import Perception
from hamnet.policy import inputs as builder
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.policy import Action, Policy
from hamnet.policy.rollout_record import Rollout, cat_rows, merge_environments
from hamnet.runtime.trees import take_rows
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import StepResult, VectorEnv
from hamnet.trainer.collection.scripted_pusher import ScriptedPusher
from hamnet.trainer.collection.seat import Seat, tokens_of
from hamnet.trainer.collection.worker import Worker
from hamnet.trainer.runners.stopping import always, check

POLICY = "policy"
"""The one seat of a rollout worker: the acting policy's."""


@dataclass(frozen=True)
class Pending:
    """A step between its two halves: what the policy saw and did, and the command."""

    inputs: PolicyInputs
    acted: Action
    command: Command
    guide: Tensor | None = None
    """(B, A) the scripted pusher's action in the state acted in (a guided run's)."""


@torch.no_grad()
def collect_overlapped(
    workers: tuple[RolloutWorker, RolloutWorker],
    policy: Policy,
    steps: int,
    env_transitions: int,
    running: Callable[[], bool] = always,
) -> Rollout:
    """`collect` of two workers whose physics and networks overlap: while one group's
    physics steps in a background thread (MuJoCo releases the GIL), the other group's
    perception, policy and safety run, so both cores stay busy. Environments of the first
    worker come first in the merged rollout. InterruptedError, between two steps, once
    `running()` turns False."""
    first, second = workers
    count = first.env.num_envs + second.env.num_envs
    records: tuple[list, list] = ([], [])
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="physics") as physics:
        pending = [first.act(policy, env_transitions)]
        stepping = physics.submit(first.env.step, pending[0].command)
        pending.append(second.act(policy, env_transitions))
        for t in range(steps):
            check(running)
            for index, (worker, other) in enumerate(((first, second), (second, first))):
                result = stepping.result()
                if index == 0 or t + 1 < steps:  # the other group's physics, in the background
                    stepping = physics.submit(other.env.step, pending[1 - index].command)
                records[index].append(worker.observe(policy, pending[index], result))
                if t + 1 < steps:
                    pending[index] = worker.act(policy, env_transitions + (t + 1) * count)
    return merge_environments([first.finish(policy, records[0]), second.finish(policy, records[1])])


class RolloutWorker(Worker):
    """B environments acting with a policy through the training profile's safety filter."""

    def __init__(
        self,
        env: VectorEnv,
        perception: Perception | None,
        safety: SafetyFilter,
        seed: int = 0,
        guide: ScriptedPusher | None = None,
    ) -> None:
        """`guide`: the scripted pusher whose actions a guided run's rollouts record."""
        super().__init__(env, {POLICY: Seat(perception)}, safety, seed)
        self.guide = guide

    @property
    def seat(self) -> Seat:
        """The acting policy's perception, percepts and carry."""
        return self.seats[POLICY]

    @property
    def perception(self) -> Perception | None:
        return self.seat.perception

    @torch.no_grad()
    def collect(
        self,
        policy: Policy,
        steps: int,
        env_transitions: int,
        deterministic: bool = False,
        running: Callable[[], bool] = always,
    ) -> Rollout:
        """Act `steps` times in every environment with `policy`.

        Args:
            policy: the acting policy (its log std already set for `env_transitions`).
            steps: T.
            env_transitions: the schedule counter at the start (safety's xi annealing).
            deterministic: act with the mean (evaluation) instead of sampling.
            running: checked before every step: InterruptedError once it turns False.
        """
        records = []
        for t in range(steps):
            check(running)
            pending = self.act(policy, env_transitions + t * self.env.num_envs, deterministic)
            records.append(self.observe(policy, pending, self.env.step(pending.command)))
        return self.finish(policy, records)

    def act(self, policy: Policy, env_transitions: int, deterministic: bool = False) -> Pending:
        """The first half of a step: inputs, the policy's action and the safe command (and,
        guided and sampling, the scripted pusher's action)."""
        guide = None
        if self.guide is not None and not deterministic:
            guide = self.guide.actions(self.observation, env_transitions)
        inputs = self.inputs(policy)
        acted = policy.act(inputs, deterministic, self.generator)
        return Pending(inputs, acted, self.command(acted.action, env_transitions), guide)

    def observe(self, policy: Policy, pending: Pending, result: StepResult) -> dict[str, object]:
        """The second half, after `env.step(pending.command)`: bootstrap timeouts, start new
        episodes, perceive; returns what the step records."""
        acted = pending.acted
        self.seat.end(acted.action, acted.memory)
        rewards = torch.as_tensor(result.reward_terms, dtype=torch.float32)  # (B, R)
        final_values = torch.zeros_like(rewards)
        timed_out = np.flatnonzero(result.truncated & ~result.terminated)
        if len(timed_out):
            final_values[timed_out] = self._final_values(
                policy, result.final_observation, timed_out
            )
        self.start(result.reset_ids, result.observation)
        guide = {} if pending.guide is None else {"guide": pending.guide}
        return {
            **guide,
            "inputs": pending.inputs,
            "actions": acted.action,
            "log_prob": acted.log_prob,
            "values": acted.values,
            "rewards": rewards,
            "final_values": final_values,
            "dones": torch.as_tensor(result.terminated | result.truncated),
            "success": torch.as_tensor(result.success),
        }

    def finish(self, policy: Policy, records: list[dict[str, object]]) -> Rollout:
        """The rollout of the recorded steps, with the values of the states after them."""
        next_values = policy.act(self.inputs(policy), deterministic=True).values  # (B, R)
        fields = {
            key: torch.stack([r[key] for r in records]) for key in records[0] if key != "inputs"
        }
        return Rollout(
            inputs=cat_rows([r["inputs"] for r in records]), next_values=next_values, **fields
        )

    def inputs(self, policy: Policy) -> PolicyInputs:
        """The inputs of the current observation (zeroing the carry of new episodes)."""
        self.begin({POLICY: policy})
        robot = builder.robot_observation(self.observation)
        return self.seat.inputs(policy, robot, self.pose_noise, self.generator)

    def _final_values(self, policy: Policy, final: Observation, env_ids: np.ndarray) -> Tensor:
        """(K, R) values of the final states of the episodes in `env_ids` (K,), before their
        caches make way for the next episodes."""
        rows = torch.as_tensor(env_ids)
        robot = take_rows(builder.robot_observation(final), rows)
        perception = self.seat.perception
        percepts = None if perception is None else perception.step(robot.object_pose, rows)
        carry, robot = builder.observed_state(
            policy.config, take_rows(self.seat.carry, rows), robot, self.pose_noise, self.generator
        )
        inputs = builder.policy_inputs(policy.config, carry, robot, tokens_of(percepts))
        return policy.act(inputs, deterministic=True).values
