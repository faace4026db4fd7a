"""The whole in-process training loop on one page, top to bottom, as CleanRL writes PPO: the
sim steps, perception turns the scene into UniCORN tokens, the policy acts, the safety
filter makes the action a command the arm may take, and after T steps GAE and one PPO update.

It calls the same cores as `hamnet trainer --inprocess` (whose `RolloutWorker` and `Runner`
add what a real run needs: overlapped physics, the value of timed-out episodes, resumable
snapshots, metrics, checkpoints, several workers and ranks). Read it to see the order of
things; train with `hamnet trainer`.

    python examples/train_loop.py --iterations 3 --num-envs 8 --steps 16
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.messages.robot_state import Observation
from hamnet.messages.safe_command import Command
from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.perception.core import Perception
from hamnet.policy import inputs as builder
from hamnet.policy.registry import build
from hamnet.policy.rollout_record import cat_rows
from hamnet.safety.config import with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.trainer.algorithms.gae import gae
from hamnet.trainer.algorithms.normalization import ReturnScaler
from hamnet.trainer.algorithms.ppo import Batch, optimizer_for, update
from hamnet.trainer.collection.seat import scenes_of, tokens_of
from hamnet.trainer.config import PPOConfig
from hamnet.trainer.runners.run_config import stage_sim


def train(iterations: int, num_envs: int, steps: int, seed: int = 0) -> list[dict[str, float]]:
    """`iterations` rounds of T = `steps` steps of `num_envs` environments and one PPO update
    each; returns one row of figures per round."""
    torch.manual_seed(seed)
    # The cores: the easy stage's environments, the shipped frozen UniCORN encoder, HAMnet,
    # and the safety filter's training profile.
    env = VectorEnv(dataclasses.replace(stage_sim("easy"), num_envs=num_envs, seed=seed))
    encoder, _ = load_checkpoint(SHIPPED_ENCODER)
    perception = Perception(encoder.requires_grad_(False), num_envs, seed=seed)
    policy = build("hamnet", seed=seed)
    safety = SafetyFilter(np.zeros((num_envs, NUM_JOINTS)), with_profile("training"))
    ppo = PPOConfig()
    optimizer = optimizer_for(policy.actor_parameters(), policy.critic_parameters(), ppo)
    scaler = ReturnScaler(num_envs, ppo.gamma)
    bounds = (-torch.ones(policy.config.action_dim), torch.ones(policy.config.action_dim))

    def observe(carry: builder.Carry, observation: Observation) -> tuple[builder.Carry, object]:
        """Perception (the object's cloud at its pose -> UniCORN tokens), then the policy's
        inputs of this step (robot state, goal, tokens, the carried previous action)."""
        percepts = perception.step(torch.as_tensor(observation.object_pose))
        ids, step = (
            torch.as_tensor(observation.episode_ids),
            torch.as_tensor(observation.episode_step),
        )
        carry = builder.begin_step(carry, ids, step)
        robot = builder.robot_observation(observation)
        return carry, builder.policy_inputs(policy.config, carry, robot, tokens_of(percepts))

    observation = env.reset(seed=seed)
    every = np.arange(num_envs)
    safety.start_episodes(every, observation.q.astype(np.float64))
    perception.start_episodes(scenes_of(env, every))
    carry = builder.initial_carry(policy, num_envs)
    generator = torch.Generator().manual_seed(seed)
    transitions, rows = 0, []
    for iteration in range(iterations):
        policy.eval()
        record: dict[str, list] = {
            k: [] for k in ("inputs", "actions", "log_prob", "values", "rewards", "dones")
        }
        with torch.no_grad():
            for _ in range(steps):
                # Perception and policy inputs (robot state, goal, tokens, previous action).
                carry, inputs = observe(carry, observation)
                acted = policy.act(inputs, generator=generator)
                # Safety: the raw action -> joint targets and gains the arm may take.
                safe = safety.command(
                    acted.action.numpy().astype(np.float64),
                    observation.q.astype(np.float64),
                    observation.dq.astype(np.float64),
                    transitions,
                )
                # Sim: one control step of every environment; ended episodes restart.
                result = env.step(Command(safe.q_ref, safe.kp, safe.kd, safe.tau_limit))
                carry = builder.end_step(carry, acted.action, acted.memory)
                if len(result.reset_ids):
                    safety.start_episodes(
                        result.reset_ids, result.observation.q[result.reset_ids].astype(np.float64)
                    )
                    perception.start_episodes(scenes_of(env, result.reset_ids))
                observation = result.observation
                dones = torch.as_tensor(result.terminated | result.truncated)
                rewards = torch.as_tensor(result.reward_terms, dtype=torch.float32)  # (B, R)
                for key, value in (
                    ("inputs", inputs),
                    ("actions", acted.action),
                    ("log_prob", acted.log_prob),
                    ("values", acted.values),
                    ("rewards", scaler.scale(rewards, dones)),
                    ("dones", dones),
                ):
                    record[key].append(value)
                transitions += num_envs
            carry, last = observe(carry, observation)
            next_values = policy.act(last, deterministic=True).values  # (B, R)
        # Learning: per-term advantages, then one clipped-surrogate update.
        stacked = {k: torch.stack(v) for k, v in record.items() if k != "inputs"}  # (T, B, ...)
        advantages, returns = gae(
            stacked["rewards"],
            stacked["values"],
            next_values,
            stacked["dones"],
            ppo.gamma,
            ppo.gae_lambda,
        )
        flat = lambda x: x.reshape(-1, *x.shape[2:])  # (T, B, ...) -> (T * B, ...)
        batch = Batch(
            cat_rows(record["inputs"]),
            flat(stacked["actions"]),
            flat(stacked["log_prob"]),
            flat(advantages),
            flat(returns),
        )
        policy.train()
        stats = update(policy.evaluate, policy.parameters(), optimizer, batch, bounds, ppo)
        policy.normalizer.update(batch.inputs.observation)
        rows.append(
            {
                "iteration": iteration + 1,
                "env_transitions": transitions,
                "approx_kl": stats.approx_kl,
                "value_loss": stats.value_loss,
                "mean_reward": float(stacked["rewards"].sum(-1).mean()),
            }
        )
        print(rows[-1])
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--iterations", type=int, default=3, help="PPO updates")
    parser.add_argument("--num-envs", type=int, default=8, help="B: environments")
    parser.add_argument("--steps", type=int, default=16, help="T: steps between two updates")
    args = parser.parse_args(argv)
    train(args.iterations, args.num_envs, args.steps)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
