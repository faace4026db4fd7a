"""PPO as a run's algorithm: per-term advantages of reward-scaled rollouts, then the clipped
update (`ppo.update`) with the KL-adaptive rate.

Rewards are scaled by the running std of the summed return before GAE (`ReturnScaler`), and
the bootstrap of truncated episodes is added after scaling, since values live in scaled
units. A fresh run's first rollout only fills the input statistics and the scaler (its
actions saw zeros), so every action learned from saw standardised inputs. Shapes: T steps,
B environments, R reward terms.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import partial
from typing import Any

import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.policy.chunk_codec import encode_rollout
from hamnet.policy.policy import Policy
from hamnet.policy.rollout_record import Rollout
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime import contract
from hamnet.runtime.compute import bfloat16_autocast, torch_threads, use_bfloat16
from hamnet.safety.config import with_profile
from hamnet.trainer.algorithms.gae import gae
from hamnet.trainer.algorithms.normalization import ReturnScaler
from hamnet.trainer.algorithms.ppo import Batch, UpdateStats, optimizer_for, update
from hamnet.trainer.algorithms.ppo_losses import energy_loss, policy_loss, value_loss
from hamnet.trainer.collection.sources import Collected, InProcess, RolloutSource
from hamnet.trainer.collection.streamed import ROLLOUT
from hamnet.trainer.results.evaluate import HeldOut, evaluate
from hamnet.trainer.runners.progress import ppo_line
from hamnet.trainer.runners.ranks import ONE, Ranks
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import (
    Arrays,
    Snapshot,
    nest,
    optimizer_snapshot,
    part,
    restore_optimizer,
)
from hamnet.trainer.runners.stopping import always
from hamnet.trainer.storage.rollout_chunks import Arrived, chunk_decoder


class PPO:
    """The run's PPO: its optimizer, reward scaler and minibatch generator."""

    name = "ppo"

    def __init__(self, config: RunConfig) -> None:
        """`config.ppo` sets the update, `config.seed` the minibatches' generator."""
        self.ppo, self.seed, self.guide = config.ppo, config.seed, config.guide
        self.energy = partial(energy_loss, config=with_profile("training").action_magnitude)
        """The energy loss of an action mean, read as the workers' safety profile reads it."""

    def prepare(self, config: RunConfig) -> RunConfig:
        """ValueError for the energy loss in the paddle space: it reads the action's first
        components as joint residuals."""
        if config.ppo.energy_coef and config.action_space != "joint":
            raise ValueError("--ppo.energy-coef reads joint residuals: use --action-space joint")
        return config

    def in_process(self, config: RunConfig) -> RolloutSource:
        return InProcess(config)

    @property
    def topic(self) -> contract.Topic:
        return ROLLOUT

    def encode(self, rollout: Rollout, version: int, sequence: int) -> RolloutChunk:
        return encode_rollout(rollout, version, sequence)

    def decoder(self, policy: Policy) -> Callable[[str, bytes], Arrived]:
        return chunk_decoder(policy)

    def start(self, policy: Policy, envs: int, ranks: Ranks = ONE, threads: int = 1) -> None:
        self.policy, self.ranks, self.threads = policy, ranks, threads
        self.bfloat16 = use_bfloat16(self.ppo.precision, policy.log_std.device)
        """Whether the update's passes run in bfloat16 (`PPOConfig.precision`)."""
        self.optimizer = optimizer_for(
            policy.actor_parameters(), policy.critic_parameters(), self.ppo
        )
        self.shuffle = torch.Generator().manual_seed(self.seed)
        """Draws the update's minibatches: its own stream, so a run from rollout workers
        shuffles as the same run in one process does (whose cores draw from torch's)."""
        self.scaler = ReturnScaler(envs, self.ppo.gamma)
        dim = policy.config.action_dim
        self.action_bounds = (-torch.ones(dim), torch.ones(dim))

    def learn(
        self,
        collected: Collected,
        whole: Rollout,
        env_transitions: int,
        running: Callable[[], bool] = always,
    ) -> dict[str, float]:
        """One update of this rank's rollout, or the first rollout's warm-up."""
        if self.policy.normalizer.count:
            weight = self.guide.weight(env_transitions)
            stats = self.update(collected.rollout, whole, collected.envs, running, weight)
        else:
            for t in range(len(whole.rewards)):
                self.scaler.scale(whole.rewards[t], whole.dones[t], collected.envs)
            stats = UpdateStats.none(self.optimizer.param_groups[0]["lr"])
        return {"log_std": float(self.policy.log_std.detach().mean()), **dataclasses.asdict(stats)}

    def update(
        self,
        rollout: Rollout,
        whole: Rollout | None = None,
        envs: torch.Tensor | None = None,
        running: Callable[[], bool] = always,
        guide_weight: float = 0.0,
    ) -> UpdateStats:
        """One PPO update of this rank's `rollout` (`batch`), on the learner's threads, the
        critic alone on features computed once after the actor stops (`ppo.update`), with
        the guide's imitation term at `guide_weight`."""
        batch = self.batch(rollout, whole, envs, guide_weight)
        self.policy.train()
        with torch_threads(self.threads), bfloat16_autocast(self.bfloat16):
            return update(
                self.policy.evaluate,
                self.policy.parameters(),
                self.optimizer,
                batch,
                self.action_bounds,
                self.ppo,
                generator=self.shuffle,
                energy=self.energy,
                ranks=self.ranks,
                running=running,
                critic=self.policy if self.policy.reads_value_features else None,
            )

    def gradient(self, batch: Batch, bfloat16: bool = False) -> torch.Tensor:
        """The flat gradient of the clipped surrogate and the value loss of the whole
        `batch` at the current weights, the network's pass in bfloat16 or float32: how far
        a bfloat16 update's direction is from float32's (`PPOConfig.precision`). Leaves the
        gradients set."""
        policy = self.policy.train()
        policy.zero_grad(set_to_none=True)
        with bfloat16_autocast(bfloat16):
            out = policy.evaluate(batch.inputs, batch.actions)
            loss = policy_loss(
                out.log_prob, batch.old_log_prob, batch.advantages, self.ppo.clip, True
            )
            loss = loss + value_loss(out.values, batch.returns)
        loss.backward()
        return torch.cat([p.grad.flatten() for p in policy.parameters() if p.grad is not None])

    def batch(
        self,
        rollout: Rollout,
        whole: Rollout | None = None,
        envs: torch.Tensor | None = None,
        guide_weight: float = 0.0,
    ) -> Batch:
        """Scale rewards, bootstrap, GAE per term: the update's batch of this rank's
        `rollout`; `whole` (default `rollout`): every rank's environments, which the scaler
        sees; `envs`: which environments they are (None: all); `guide_weight` > 0: with the
        rollout's scripted-pusher actions as the imitation target.

        Raises:
            ValueError: a guide weight on a rollout without the pusher's actions (the policy
                service's rollouts carry none: a guided run learns from rollout workers or
                in process).
        """
        if guide_weight and rollout.guide is None:
            raise ValueError(
                "a guided run (--guide.coef) needs rollouts with the scripted pusher's actions:"
                " train in process or from `hamnet rollout` workers given the same --guide flags"
            )
        whole = rollout if whole is None else whole
        scaled = torch.stack(
            [
                self.scaler.scale(whole.rewards[t], whole.dones[t], envs)
                for t in range(len(whole.rewards))
            ]
        )
        count = rollout.rewards.shape[1]
        scaled = scaled[:, self.ranks.rank * count : (self.ranks.rank + 1) * count]  # this rank's
        rewards = scaled + self.ppo.gamma * rollout.final_values  # (T, B, R)
        advantages, returns = gae(
            rewards,
            rollout.values,
            rollout.next_values,
            rollout.dones,
            self.ppo.gamma,
            self.ppo.gae_lambda,
        )
        flat = lambda x: x.reshape(-1, *x.shape[2:])
        robot_state = rollout.inputs.observation.base[
            :, self.policy.config.observation.columns("base", "robot_state")
        ]
        return Batch(
            rollout.inputs,
            flat(rollout.actions),
            flat(rollout.log_prob),
            flat(advantages),
            flat(returns),
            joint_velocity=robot_state[:, NUM_JOINTS:],  # (T * B, J): q, then dq
            guide=flat(rollout.guide) if guide_weight else None,
            guide_weight=guide_weight,
        )

    def progress(self, row: dict[str, float]) -> str:
        return ppo_line(row)

    def snapshot(self) -> Snapshot:
        """Adam's state and rate, the reward scaler and the minibatches' generator."""
        return nest(
            {
                "optimizer": optimizer_snapshot(self.optimizer),
                "scaler": self.scaler.snapshot(),
                "shuffle": ({"state": self.shuffle.get_state()}, {}),
            }
        )

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Adam's state as the snapshot left it, at the rates this run is configured with (a
        resumed run may change `--ppo.lr` and `--ppo.value-lr`), except an adapted actor
        rate (`lr_schedule` adaptive), which goes on from where the run had adapted it."""
        configured = [group["lr"] for group in self.optimizer.param_groups]
        restore_optimizer(self.optimizer, *part(arrays, meta, "optimizer"))
        for index, (group, lr) in enumerate(zip(self.optimizer.param_groups, configured)):
            if index or self.ppo.lr_schedule == "fixed":
                group["lr"] = lr
        self.scaler.restore(*part(arrays, meta, "scaler"))
        self.shuffle.set_state(torch.tensor(part(arrays, meta, "shuffle")[0]["state"]))

    def held_out(
        self, policy: Policy, config: RunConfig, env_transitions: int
    ) -> tuple[HeldOut, dict[str, object]]:
        return evaluate(policy, config, config.eval_episodes, env_transitions), {}

    def summary_fields(self) -> dict[str, object]:
        return {}
