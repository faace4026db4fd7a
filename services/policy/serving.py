"""One batch of actions for a paired state and tokens, without Zenoh: the policy service's
step core for one sim worker.

Consumes decoded states and tokens (`hamnet.messages`, checked by `hamnet.policy.messages`) and the EnvCode of reset
environments; produces the network inputs it acted on and the `Action`. What is carried
between steps (previous action, memory resets, EnvCode cache) is the one input builder's
(`hamnet.policy.inputs`), so the service and an in-process trainer see the same inputs. A
student's object pose gets the pose estimator's error model unless `pose_noise` is None.
The service's options (`PolicyLoopConfig`: sampling, device, pairing, rollouts) are here too.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
import torch

from hamnet.messages.robot_state import StateIn
from hamnet.messages.tokens import TokensIn
from hamnet.policy import inputs as builder
from hamnet.policy.messages import robot_observation
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import PoseNoiseConfig, RobotObservation
from hamnet.policy.policy import Action, Policy
from hamnet.runtime.cli import Flattened
from hamnet.runtime.shell_config import ComputeConfig, ReportConfig

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class PolicyLoopConfig:
    """Inference options of the shell."""

    deterministic: bool = False
    """Serve the distribution's mean (evaluation) instead of samples (rollouts)."""
    compute: Annotated[ComputeConfig, Flattened] = field(default_factory=ComputeConfig)
    pending: int = 8
    """Steps that may wait for their other half (state or tokens) before the oldest is
    dropped."""
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)
    student_pose_noise: bool = True
    """Add the pose estimator's error model (`PoseNoiseConfig`) to a student's object pose:
    on against the sim, off where the pose already comes from an estimator."""
    rollout_horizon: int = 0
    """T > 0: also publish RolloutChunks of T steps for `hamnet trainer` (what was served,
    joined with the sim's transitions); 0: off."""

    def __post_init__(self) -> None:
        if self.pending < 1:
            raise ValueError(f"pending must be >= 1, got {self.pending}")
        if self.rollout_horizon < 0:
            raise ValueError(f"rollout_horizon must be >= 0, got {self.rollout_horizon}")


class Serving:
    """The carry of every environment and the sampling noise, on one device."""

    def __init__(
        self, env_code_dim: int, device: torch.device, seed: int, pose_noise: PoseNoiseConfig | None
    ) -> None:
        self.device, self.pose_noise = device, pose_noise
        self.generator = torch.Generator(device).manual_seed(seed)
        """Of the sampling noise and the pose noise."""
        self.env_code = torch.zeros(0, env_code_dim, device=device)
        """(E, 25) latest EnvCode of every environment (rows grow as scenes arrive)."""
        self.carry: builder.Carry | None = None
        """Previous action and memory of every environment (None before the first step)."""

    def scene(self, env_ids: np.ndarray, env_code: np.ndarray) -> None:
        """Store the EnvCode (K, 25) of environments `env_ids` (K,)."""
        self.env_code = builder.store_env_code(
            self.env_code, torch.from_numpy(env_ids).long(), torch.from_numpy(env_code)
        )

    def restart(self) -> None:
        """Forget every carry: the sim's next run starts every episode afresh."""
        self.carry = None

    def act(
        self, policy: Policy, state: StateIn, tokens: TokensIn, deterministic: bool
    ) -> tuple[PolicyInputs, Action] | None:
        """The inputs of a pair and `policy`'s action on them; the carry moves on. None when
        state and tokens disagree on episode ids (logged; the pair is dropped)."""
        if not np.array_equal(state.episode_ids, tokens.episode_ids):
            log.warning("state and tokens of step %d disagree on episode ids: dropped", state.step)
            return None
        with torch.inference_mode():
            inputs = self._inputs(policy, state, tokens)
            action = policy.act(inputs, deterministic, self.generator)
        self.carry = builder.end_step(self.carry, action.action, action.memory)
        return inputs, action

    def _inputs(self, policy: Policy, state: StateIn, tokens: TokensIn) -> PolicyInputs:
        """The network inputs of a pair, on the device (the builder zeroes the carry of
        environments whose episode started)."""
        observed = robot_observation(state, policy.config.privileged)
        robot = RobotObservation(
            **{
                name: None if value is None else value.to(self.device)
                for name, value in vars(observed).items()
            }
        )
        b, config = len(state.episode_ids), policy.config
        if self.carry is None or len(self.carry.episode_ids) != b:
            self.carry = builder.initial_carry(policy, b)
        ids = torch.from_numpy(state.episode_ids).to(self.device)
        steps = torch.from_numpy(state.episode_step).to(self.device)
        self.carry = builder.begin_step(self.carry, ids, steps)
        if config.scene_input == "env_code" and len(self.env_code) < b:
            log.warning(
                "no scene yet for environments %d..%d: their EnvCode is zero",
                len(self.env_code),
                b - 1,
            )
            self.scene(np.arange(b), np.zeros((b, self.env_code.shape[1]), np.float32))
        self.carry, robot = builder.observed_state(
            config, self.carry, robot, self.pose_noise, self.generator
        )
        return builder.policy_inputs(
            config,
            self.carry,
            robot,
            tuple(torch.from_numpy(t).to(self.device) for t in tokens.tokens),
            self.env_code,
        )
