"""The Gymnasium adapter's bookkeeping (`hamnet.trainer.gym_adapter`) on a scripted vector
env: no gymnasium needed, so it runs in the default suite."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
import torch
from torch import nn

from hamnet.trainer.algorithms.gae import gae
from hamnet.trainer.algorithms.normalization import ReturnScaler
from hamnet.trainer.config import PPOConfig
from hamnet.trainer.gym_adapter import GymPPO, GymPPOConfig


class BoxSpace:
    """The part of a `gymnasium.spaces.Box` the adapter reads."""

    def __init__(self, low: float, high: float, shape: tuple[int, ...]) -> None:
        self.low, self.high, self.shape = np.full(shape, low), np.full(shape, high), shape


class ScriptedEnv:
    """Two environments in SAME_STEP autoreset mode whose observation is the step count t.
    At t = 2 environment 0 is truncated and environment 1 terminated: their final
    observations are 10 and 20, and both restart at 100. Rewards are 1 and 2 per step."""

    num_envs = 2
    single_observation_space = SimpleNamespace(shape=(1,))

    def __init__(self) -> None:
        self.single_action_space = BoxSpace(-1.0, 1.0, (1,))
        self.t = 0
        self.sent: list[np.ndarray] = []

    def reset(self, *, seed: int | None = None) -> tuple[np.ndarray, dict]:
        return np.zeros((2, 1)), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        self.sent.append(actions.copy())
        self.t += 1
        obs = np.full((2, 1), float(self.t))
        ended = self.t == 2
        info: dict = {}
        if ended:
            info["final_obs"] = np.empty(2, dtype=object)
            info["final_obs"][0], info["final_obs"][1] = np.array([10.0]), np.array([20.0])
            obs = np.full((2, 1), 100.0)
        return obs, np.array([1.0, 2.0]), np.array([False, ended]), np.array([ended, False]), info


def learner(log_std: float = 0.0) -> GymPPO:
    """A learner whose critic is V(s) = s / 10 within the clip: statistics of mean 0 and
    variance 100 (as if a first rollout had filled them) and a linear critic of weight 1."""
    config = GymPPOConfig(
        steps_per_rollout=3, log_std_init=log_std, ppo=PPOConfig(gamma=0.5, gae_lambda=0.5)
    )
    ppo = GymPPO(ScriptedEnv(), config, seed=0)
    ppo.model.observations.update(torch.tensor([[-10.0], [10.0]]))
    critic = nn.Linear(1, 1)
    with torch.no_grad():
        critic.weight.fill_(1.0)
        critic.bias.zero_()
    ppo.model.critic = critic
    return ppo


def test_truncation_bootstraps_the_final_observation_and_termination_does_not() -> None:
    """A truncated episode's step must carry V(final observation 10) = 1, not V of the next
    episode's first observation (100, clipped to 5); a terminated one carries nothing. Both
    end there."""
    rollout = learner().collect()
    torch.testing.assert_close(
        rollout.final_values[:, :, 0],
        torch.tensor([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]]),
        atol=1e-4,
        rtol=0,
    )
    assert rollout.dones.tolist() == [[False, False], [True, True], [False, False]]
    assert rollout.observations[:, :, 0].tolist() == [[0, 0], [1, 1], [100, 100]]
    torch.testing.assert_close(
        rollout.next_values[:, 0], torch.tensor([0.3, 0.3]), atol=1e-4, rtol=0
    )


def test_targets_add_the_discounted_bootstrap_to_the_scaled_reward() -> None:
    """The trainer's order (`Runner.learn`): rewards scaled first, then + gamma V(final);
    a bootstrap added before scaling, or not at all, changes the truncated step's target."""
    ppo = learner()
    rollout = ppo.collect()
    advantages, returns = ppo.targets(rollout)
    scaler = ReturnScaler(2, gamma=0.5)
    scaled = torch.stack([scaler.scale(r, d) for r, d in zip(rollout.rewards, rollout.dones)])
    expected = gae(
        scaled + 0.5 * rollout.final_values,
        rollout.values,
        rollout.next_values,
        rollout.dones,
        0.5,
        0.5,
    )
    torch.testing.assert_close(advantages, expected[0])
    torch.testing.assert_close(returns, expected[1])


def test_actions_are_clipped_for_the_env_and_kept_raw_for_the_update() -> None:
    """The env gets actions within its bounds, as SB3 sends them; the log-probabilities
    belong to the raw samples, so the rollout keeps those (std e^2 ~ 7 leaves [-1, 1])."""
    ppo = learner(log_std=2.0)
    rollout = ppo.collect()
    sent = np.concatenate(ppo.env.sent)
    assert np.abs(sent).max() <= 1.0
    assert rollout.actions.abs().max() > 1.0
    np.testing.assert_allclose(sent, rollout.actions.reshape(-1, 1).clamp(-1, 1).numpy(), rtol=1e-6)


def test_finished_episodes_are_recorded_with_their_return() -> None:
    ppo = learner()
    ppo.collect()
    assert ppo.episodes == [(4, 2.0), (4, 4.0)]
    assert ppo.env_steps == 6


def test_the_first_rollout_only_fills_the_statistics_then_updates_learn() -> None:
    """As the trainer's `Runner.iterate`: the first rollout acts on zeroed inputs and is not
    learned from (its advantages would rest on unstandardised values); it fills the
    observation statistics and the return scaler, and the next iteration updates."""
    config = GymPPOConfig(steps_per_rollout=3, ppo=PPOConfig(minibatches=1, kl_stop="off"))
    ppo = GymPPO(ScriptedEnv(), config, seed=0)
    assert ppo.model.standardise(torch.tensor([[7.0]])).item() == 0.0
    assert ppo.iterate() == {}
    assert float(ppo.model.observations.count) == pytest.approx(6.0)
    assert float(ppo.scaler.stats.count) == pytest.approx(6.0)
    row = ppo.iterate()
    assert row["gradient_steps"] == config.ppo.epochs and np.isfinite(row["value_loss"])
    assert float(ppo.model.observations.count) == pytest.approx(12.0)


def test_the_adapter_does_not_import_gymnasium() -> None:
    """gymnasium is the `reference` extra, not a dependency: importing the adapter (and with
    it hamnet) must not need it, in a fresh interpreter where no test imported it first."""
    code = "import sys, hamnet.trainer.gym_adapter; print('gymnasium' in sys.modules)"
    result = subprocess.run(
        [sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == "False"
