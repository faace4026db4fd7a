"""What every rollout worker holds: B environments, the safety filter's training profile
between the policies and the sim, and one `Seat` per policy that reads the environments.

PPO's `RolloutWorker` seats the acting policy; DAgger's `DaggerWorker` seats the teacher and
the student side by side. Both start episodes, perceive, turn an action into a safe command
and snapshot their state the same way, here; what a step records is theirs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.safety.filter import SafeOutput, SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.trainer.collection.seat import Seat
from hamnet.trainer.runners.snapshots import (
    Arrays,
    Snapshot,
    array_dataclass,
    fields_of,
    generator_state,
    nest,
    part,
    set_generator_state,
)


class Worker:
    """B environments, their safety filter and the seats of the policies that read them."""

    def __init__(
        self, env: VectorEnv, seats: dict[str, Seat], safety: SafetyFilter, seed: int = 0
    ) -> None:
        """Reset the environments with `seed` and perceive their first state."""
        if env.num_envs != safety.num_envs or any(
            seat.perception is not None and seat.perception.num_envs != env.num_envs
            for seat in seats.values()
        ):
            raise ValueError("env, perception and safety must hold the same environments")
        self.env, self.seats, self.safety = env, seats, safety
        self.observation: Observation = env.reset(seed=seed)
        every = np.arange(env.num_envs)
        self.safety.start_episodes(every, self.observation.q.astype(np.float64))
        self.perceive(every)
        self.generator = torch.Generator().manual_seed(seed)
        """Of the action noise, of who acts (DAgger) and of a student's pose-estimate error."""
        self.pose_noise = PoseNoiseConfig()
        """The estimator's error on a student's object pose (a teacher reads the true one)."""

    @property
    def num_envs(self) -> int:
        return self.env.num_envs

    def perceive(self, started: np.ndarray) -> None:
        """Every seat's percepts of the current observation; new caches for `started`."""
        pose = torch.as_tensor(self.observation.object_pose)
        for seat in self.seats.values():
            seat.perceive(self.env, started, pose)

    def begin(self, policies: dict[str, Any]) -> None:
        """Start a step for every seat's policy (`policies`: role -> policy)."""
        obs = self.observation
        ids, step = torch.as_tensor(obs.episode_ids), torch.as_tensor(obs.episode_step)
        for role, seat in self.seats.items():
            seat.begin(policies[role], ids, step)

    def safe(self, action: torch.Tensor, env_transitions: int) -> SafeOutput:
        """What the safety filter makes of `action` (B, A) at the schedule counter
        `env_transitions` (its command, and whether it stopped following the policy)."""
        obs = self.observation
        return self.safety.command(
            action.numpy().astype(np.float64),
            obs.q.astype(np.float64),
            obs.dq.astype(np.float64),
            env_transitions,
        )

    def command(self, action: torch.Tensor, env_transitions: int) -> Command:
        """The safe command of `action` (B, A) at the schedule counter `env_transitions`."""
        safe = self.safe(action, env_transitions)
        return Command(safe.q_ref, safe.kp, safe.kd, safe.tau_limit)

    def start(self, reset_ids: np.ndarray, observation: Observation) -> None:
        """Take a step's `observation`; episodes that began get fresh filters and caches."""
        if len(reset_ids):
            self.safety.start_episodes(reset_ids, observation.q[reset_ids].astype(np.float64))
        self.observation = observation
        self.perceive(reset_ids)

    def snapshot(self) -> Snapshot:
        """The whole state the worker continues from: env, safety filter, observation,
        generator and every seat."""
        parts = {
            "env": self.env.snapshot(),
            "safety": self.safety.snapshot(),
            "observation": (fields_of(self.observation), {}),
            "generator": ({"state": generator_state(self.generator)}, {}),
            **{f"seat.{role}": seat.snapshot() for role, seat in self.seats.items()},
        }
        return nest(parts)

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot` (on a worker built from the same config)."""
        self.env.restore(*part(arrays, meta, "env"))
        self.safety.restore(*part(arrays, meta, "safety"))
        self.observation = array_dataclass(Observation, part(arrays, meta, "observation")[0])
        set_generator_state(self.generator, part(arrays, meta, "generator")[0]["state"])
        for role, seat in self.seats.items():
            seat.restore(*part(arrays, meta, f"seat.{role}"))
