"""PPO's loss terms, the KL-adaptive learning rate and the running statistics."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from hamnet.policy.observation import RobotObservation, assemble
from hamnet.policy.registry import build
from hamnet.safety.config import with_profile
from hamnet.trainer.algorithms.adaptive_lr import adapt_learning_rate
from hamnet.trainer.algorithms.normalization import ReturnScaler, RunningMeanStd
from hamnet.trainer.algorithms.ppo_losses import (
    approx_kl,
    bound_loss,
    clip_fraction,
    energy_loss,
    normalize_advantages,
    policy_loss,
    value_loss,
)
from hamnet.trainer.config import PPO_PRESETS, PPOConfig


def test_policy_loss_stops_pushing_a_ratio_beyond_the_clip() -> None:
    """With a positive advantage, raising a ratio already above 1 + clip gains nothing: the
    gradient through the clipped branch is zero, through the unclipped one it is not."""
    old = torch.zeros(2)
    new = torch.tensor([0.5, 0.1], requires_grad=True)  # ratios 1.65 (clipped) and 1.105
    policy_loss(new, old, torch.ones(2, 1), clip=0.3).backward()
    assert new.grad[0] == 0.0 and new.grad[1] < 0.0


def test_policy_loss_sums_the_terms_advantages() -> None:
    log_prob = torch.zeros(3)
    per_term = torch.tensor([[1.0, -0.5], [0.2, 0.3], [-1.0, 2.0]])
    summed = per_term.sum(dim=1, keepdim=True)
    assert policy_loss(log_prob, log_prob, per_term, 0.3) == pytest.approx(
        float(policy_loss(log_prob, log_prob, summed, 0.3))
    )
    assert policy_loss(log_prob, log_prob, per_term, 0.3) == pytest.approx(-summed.mean().item())


def test_normalized_advantages_sum_to_unit_scale_and_keep_term_ratios() -> None:
    torch.manual_seed(0)
    advantages = torch.randn(4096, 2) * torch.tensor([1.0, 3.0]) + 5.0
    normalized = normalize_advantages(advantages)
    torch.testing.assert_close(normalized.mean(dim=0), torch.zeros(2), atol=1e-5, rtol=0)
    ratio = normalized.std(dim=0)[1] / normalized.std(dim=0)[0]
    assert ratio == pytest.approx(3.0, rel=0.05)
    assert normalized.var(dim=0).sum() == pytest.approx(1.0, rel=1e-3)


def test_value_loss_is_half_the_squared_error_summed_over_heads() -> None:
    values, returns = torch.tensor([[1.0, 2.0]]), torch.tensor([[0.0, 4.0]])
    assert value_loss(values, returns).item() == pytest.approx(0.5 * (1.0 + 4.0))


def test_bound_loss_is_zero_inside_and_quadratic_outside() -> None:
    low, high = -torch.ones(2), torch.ones(2)
    assert bound_loss(torch.tensor([[0.5, -1.0]]), low, high).item() == 0.0
    assert bound_loss(torch.tensor([[3.0, -2.0]]), low, high).item() == pytest.approx(4.0 + 1.0)


def test_kl_and_clip_fraction_diagnostics() -> None:
    old = torch.zeros(4)
    assert approx_kl(old, old).item() == 0.0
    new = torch.log(torch.tensor([1.0, 1.2, 1.5, 0.5]))
    assert approx_kl(new, old).item() > 0.0
    assert clip_fraction(new, old, 0.3).item() == pytest.approx(0.5)


def test_learning_rate_adapts_to_the_kl_within_its_bounds() -> None:
    config = PPOConfig()
    assert adapt_learning_rate(3e-4, 0.001, config) == pytest.approx(4.5e-4)  # below 0.008
    assert adapt_learning_rate(3e-4, 0.05, config) == pytest.approx(2e-4)  # above 0.032
    assert adapt_learning_rate(3e-4, 0.016, config) == 3e-4
    assert adapt_learning_rate(9e-3, 0.0, config) == 1e-2
    assert adapt_learning_rate(1e-6, 1.0, config) == 1e-6


def test_presets_differ_only_in_the_loss_weights() -> None:
    code, paper = PPO_PRESETS["authors"], PPO_PRESETS["paper"]
    assert (code.policy_coef, code.value_coef) == (0.5, 2.0)
    assert (paper.policy_coef, paper.value_coef) == (2.0, 0.5)
    assert dataclasses.replace(paper, policy_coef=0.5, value_coef=2.0) == code
    assert code.early_stop_factor * code.kl_target == pytest.approx(0.024)  # the paper's ES target
    small = PPO_PRESETS["small-scale"]
    assert small == PPOConfig()
    assert (code.minibatches, code.kl_stop, code.lr_schedule, code.value_lr, code.clip_per_term) == (
        1, "before-step", "adaptive", None, True)  # fmt: skip
    with pytest.raises(ValueError, match="lr"):
        PPOConfig(lr=1.0)


def test_running_statistics_equal_the_whole_stream() -> None:
    torch.manual_seed(1)
    stream = torch.randn(1000, 3) * torch.tensor([1.0, 2.0, 0.5]) + torch.tensor([0.0, 1.0, -2.0])
    stats = RunningMeanStd((3,))
    for chunk in stream.split(37):
        stats.update(chunk)
    torch.testing.assert_close(stats.mean, stream.double().mean(0), atol=1e-6, rtol=0)
    torch.testing.assert_close(
        stats.var, stream.double().var(0, unbiased=False), atol=1e-5, rtol=1e-5
    )
    restored = RunningMeanStd((3,))
    restored.load(stats.state("obs"), "obs")
    torch.testing.assert_close(restored.normalize(stream), stats.normalize(stream))


def test_return_scaler_divides_every_term_by_one_return_scale() -> None:
    """Constant rewards (1, 3) every step with gamma 0.5: returns 4, 6, 7, ... so the scale is
    their std, the same for both terms, and the terms keep their 1:3 ratio."""
    scaler = ReturnScaler(num_envs=1, gamma=0.5)
    rewards = torch.tensor([[1.0, 3.0]])
    for _ in range(20):
        scaled = scaler.scale(rewards, torch.tensor([False]))
    assert scaled[0, 1] / scaled[0, 0] == pytest.approx(3.0)
    returns = torch.tensor([4.0 * (2 - 0.5**k) for k in range(20)], dtype=torch.float64)
    assert scaler.stats.var.item() == pytest.approx(returns.var(unbiased=False).item(), rel=1e-3)
    scaler.scale(rewards, torch.tensor([True]))
    assert scaler.returns.item() == 0.0


def test_energy_loss_is_the_power_of_the_impedance_torque() -> None:
    """A zero mean asks for no residual at mid gains (kp 105, rho 1.15): at 1 rad/s on every
    joint the torque is -rho sqrt(kp) per joint and the loss the norm of tau * v over the 7."""
    config = with_profile("training").action_magnitude
    kp = (config.kp_min + config.kp_max) / 2
    rho = (config.rho_min + config.rho_max) / 2
    loss = energy_loss(torch.zeros(2, 21), torch.ones(2, 7), config)
    assert loss.item() == pytest.approx(rho * kp**0.5 * 7**0.5, rel=1e-6)
    at_rest = energy_loss(torch.randn(2, 21), torch.zeros(2, 7), config)
    assert at_rest.item() == 0.0  # no velocity, no power


def test_the_energy_term_reads_the_joint_velocities_of_the_base_observation() -> None:
    spec = build("state-mlp").config.observation
    robot = RobotObservation(q=torch.zeros(3, 7), dq=torch.arange(21.0).reshape(3, 7),
                             ee_pos_rot6d=torch.zeros(3, 9),
                             goal_pose=torch.tensor([[0, 0, 0, 1, 0, 0, 0.0]] * 3),
                             object_pose=torch.tensor([[0, 0, 0, 1, 0, 0, 0.0]] * 3),
                             object_velocity=torch.zeros(3, 6), physics_params=torch.zeros(3, spec.physics_params))  # fmt: skip
    base = assemble(robot, torch.zeros(3, 21), spec).base
    assert torch.equal(base[:, spec.columns("base", "robot_state")][:, 7:], robot.dq)


def test_per_term_and_summed_clipping_agree_on_one_term_and_differ_when_terms_disagree() -> None:
    """One term: the same loss. Two terms of opposite sign with a ratio past the clip: per
    term, the negative term still pulls the ratio back, summed it does not."""
    log_prob, old = torch.tensor([0.5, -0.1]), torch.zeros(2)
    one = torch.tensor([[1.0], [-2.0]])
    assert policy_loss(log_prob, old, one, 0.2, per_term=True) == policy_loss(log_prob, old, one, 0.2)
    two = torch.tensor([[3.0, -1.0], [3.0, -1.0]])
    ratio = torch.tensor([0.5, -0.1], requires_grad=True)
    policy_loss(ratio, old, two, 0.2, per_term=True).backward()
    per_term = ratio.grad.clone()
    ratio.grad = None
    policy_loss(ratio, old, two, 0.2).backward()
    assert per_term[0] > 0 and ratio.grad[0] == 0  # clipped: the summed advantage stops pushing
