"""PPO's guide (`GuideConfig`): the weight's schedule, the scripted pusher's actions as rollout
workers record them (in either action space, the same arm motion), the imitation term that
pulls the policy's mean to them, and a guided run in process on the real cores."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from hamnet.policy.registry import architecture, build
from hamnet.safety.config import in_action_space, with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.sim.env import VectorEnv
from hamnet.trainer.algorithms.ppo import Batch, update
from hamnet.trainer.collection.scripted_pusher import ScriptedPusher
from hamnet.trainer.collection.sources import build_workers
from hamnet.trainer.config import GuideConfig, PPOConfig
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner
from tests.trainer.test_runner import tiny_sim

GUIDED = GuideConfig(coef=1.0, hold=100, until=300)
A = 21


def test_the_weight_holds_then_falls_linearly_to_zero() -> None:
    weights = [GUIDED.weight(t) for t in (0, 100, 200, 300, 10_000)]
    assert weights == pytest.approx([1.0, 1.0, 0.5, 0.0, 0.0])
    assert GuideConfig().weight(0) == 0.0  # off by default: the paper's PPO


@pytest.mark.parametrize("bad", [{"coef": -1.0}, {"coef": 1.0, "hold": 5, "until": 4}])
def test_a_guide_with_a_negative_weight_or_a_fall_before_its_hold_is_refused(bad) -> None:
    with pytest.raises(ValueError, match="guide"):
        GuideConfig(**bad)


def test_the_pusher_asks_the_same_arm_motion_in_either_action_space() -> None:
    """The paddle space's twist, through its filter, commands the joint targets the joint
    space's residual commands through its own: the labels mean one motion, whichever space
    the policy learns in."""
    env = VectorEnv(dataclasses.replace(tiny_sim(), num_envs=4, num_objects=4))
    observation = env.reset(seed=3)
    q, dq = observation.q.astype(np.float64), observation.dq.astype(np.float64)
    targets = {}
    for space in ("paddle", "joint"):
        safety = in_action_space(with_profile("training"), space)
        action = ScriptedPusher(env, safety.action_magnitude).actions(observation, 0)
        assert action.shape == (4, A) and action.dtype == torch.float32
        safe_filter = SafetyFilter(np.zeros((4, 7)), safety)
        safe_filter.start_episodes(np.arange(4), q)
        targets[space] = safe_filter.command(action.numpy().astype(np.float64), q, dq, 0).q_ref
    paddle, joint = targets["paddle"][:, -1] - q, targets["joint"][:, -1] - q
    assert np.abs(paddle).max() > 0.03  # the pusher moves the arm, rad
    # within 10% of the motion: the two mappings solve the same least squares, damped by
    # 1e-3 (the script) and 1e-6 (the filter) (measured: 3-5% apart); a wrong scale, sign
    # or row is not
    np.testing.assert_allclose(paddle, joint, atol=0.1 * np.abs(joint).max())


def guided_run(**changes) -> RunConfig:
    return RunConfig(architecture="state-mlp", action_space="paddle", sim=tiny_sim(),
                     steps_per_rollout=3, guide=GUIDED, **changes)  # fmt: skip


def test_a_guided_worker_records_the_pushers_action_in_every_state_it_samples_in() -> None:
    (worker,), _ = build_workers(guided_run(), groups=1)
    entry = architecture("state-mlp")
    paddle = dataclasses.replace(entry.config, action_space="paddle")
    policy = build("state-mlp", paddle, seed=0)
    script = ScriptedPusher(worker.env, worker.safety.config.action_magnitude)
    first = script.actions(worker.observation, 0)
    rollout = worker.collect(policy, steps=3, env_transitions=0)
    assert rollout.guide.shape == rollout.actions.shape
    torch.testing.assert_close(rollout.guide[0], first)
    assert torch.isfinite(rollout.guide).all()
    (plain,), _ = build_workers(dataclasses.replace(guided_run(), guide=GuideConfig()), groups=1)
    assert plain.collect(policy, steps=3, env_transitions=0).guide is None


class Linear(torch.nn.Module):
    """A Gaussian policy whose mean is linear in its inputs, and a value of its own."""

    def __init__(self) -> None:
        super().__init__()
        self.mean = torch.nn.Linear(4, A)
        self.value = torch.nn.Parameter(torch.zeros(1))

    def evaluate(self, inputs: torch.Tensor, actions: torch.Tensor):
        mean = self.mean(inputs)
        log_prob = torch.distributions.Normal(mean, 1.0).log_prob(actions).sum(-1)
        values = self.value.expand(len(inputs), 1)
        return type("Out", (), {"mean": mean, "log_prob": log_prob, "values": values})()


@pytest.mark.parametrize("weight", [0.0, 1.0])
def test_the_imitation_term_pulls_the_mean_to_the_guides_actions_by_its_weight(weight) -> None:
    """Zero advantages leave PPO's surrogate without a gradient: only the guide's term moves
    the mean, and only while it weighs something."""
    torch.manual_seed(0)
    policy, n = Linear(), 256
    inputs = torch.randn(n, 4)
    target = torch.full((n, A), 0.5)
    with torch.no_grad():
        actions = policy.mean(inputs) + torch.randn(n, A)
        old = policy.evaluate(inputs, actions).log_prob
        before = (policy.mean(inputs) - target).square().mean()
    zeros = torch.zeros(n, 1)
    batch = Batch(inputs, actions, old, zeros, zeros, guide=target, guide_weight=weight)
    config = PPOConfig(kl_stop="off", bound_coef=0.0)
    optimizer = torch.optim.Adam(policy.parameters(), lr=1e-2)
    bounds = (-torch.ones(A), torch.ones(A))
    stats = update(policy.evaluate, policy.parameters(), optimizer, batch, bounds, config)
    with torch.no_grad():
        after = (policy.mean(inputs) - target).square().mean()
    assert np.isfinite(stats.guide_loss)
    if weight:
        assert after < 0.5 * before
    else:
        assert after == pytest.approx(float(before), rel=1e-6)


def test_a_guided_run_learns_with_the_imitation_term_and_refuses_rollouts_without_labels(
    tmp_path: Path,
) -> None:
    config = guided_run(run_dir=tmp_path, max_env_transitions=18)
    runner = Runner(config)
    metrics = runner.run()
    rows = [json.loads(line) for line in metrics.read_text().splitlines()]
    learned = [row for row in rows if row["gradient_steps"]]
    assert learned and all(np.isfinite(row["guide_loss"]) for row in learned)
    rollout = runner.source.collect(runner.policy, 3, 18, 1).rollout
    assert runner.algorithm.batch(rollout, guide_weight=1.0).guide is not None
    with pytest.raises(ValueError, match="scripted pusher"):
        runner.algorithm.batch(dataclasses.replace(rollout, guide=None), guide_weight=1.0)
