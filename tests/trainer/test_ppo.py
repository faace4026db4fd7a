"""A PPO update on a tiny batched task whose optimum is known in closed form."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import pytest
import torch
from torch import Tensor, nn

from hamnet.runtime.trees import take_rows
from hamnet.trainer.algorithms.gae import gae
from hamnet.trainer.algorithms.ppo import Batch, UpdateStats, optimizer_for, update
from hamnet.trainer.algorithms.ppo_learner import PPO
from hamnet.trainer.algorithms.ppo_losses import approx_kl, explained_variance
from hamnet.trainer.config import AUTHORS, PPOConfig
from hamnet.trainer.runners.run_config import RunConfig

B, T, LOG_STD = 64, 4, math.log(0.3)


@dataclass(frozen=True)
class Evaluation:
    log_prob: Tensor
    values: Tensor
    mean: Tensor


class TinyActorCritic(nn.Module):
    """Linear Gaussian actor with a fixed std and a two-headed linear critic."""

    def __init__(self) -> None:
        super().__init__()
        self.actor, self.critic = nn.Linear(2, 2), nn.Linear(2, 2)

    def evaluate(self, states: Tensor, actions: Tensor) -> Evaluation:
        mean = self.actor(states)
        log_prob = (-0.5 * ((actions - mean) / math.exp(LOG_STD)).square() - LOG_STD
                    - 0.5 * math.log(2 * math.pi)).sum(-1)  # fmt: skip
        return Evaluation(log_prob, self.critic(states), mean)


def rewards_of(states: Tensor, actions: Tensor) -> Tensor:
    """(.., 2) terms: reach the state, and keep the action small; the sum
    -|a - s|^2 - 0.5 |a|^2 is maximal at a = s / 1.5."""
    return torch.stack([-(actions - states).square().sum(-1), -0.5 * actions.square().sum(-1)], -1)


def update_tiny(
    model: TinyActorCritic, optimizer: torch.optim.Optimizer, batch: Batch, **kwargs
) -> object:
    """One PPO update of the tiny model with actions bounded to [-1, 1]."""
    config = kwargs.pop("config", PPOConfig())
    return update(
        model.evaluate,
        model.parameters(),
        optimizer,
        batch,
        (-torch.ones(2), torch.ones(2)),
        config,
        **kwargs,
    )


def test_ppo_converges_to_the_known_optimum_of_a_two_term_bandit() -> None:
    """One-step episodes with two reward terms: per-term GAE, the summed advantage and the
    update must drive the mean action to s / 1.5 and each value head to its term."""
    torch.manual_seed(0)
    model = TinyActorCritic()
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-4)
    config = PPOConfig()
    bounds = (-torch.full((2,), 2.0), torch.full((2,), 2.0))
    for _ in range(300):
        states = torch.rand(T, B, 2) * 2 - 1  # (T, B, 2)
        with torch.no_grad():
            out = model.evaluate(states, torch.zeros(T, B, 2))
            actions = out.mean + math.exp(LOG_STD) * torch.randn(T, B, 2)
            old = model.evaluate(states, actions)
        rewards = rewards_of(states, actions)  # (T, B, 2)
        dones = torch.ones(T, B, dtype=torch.bool)
        advantages, returns = gae(rewards, old.values, torch.zeros(B, 2), dones, 0.99, 0.95)
        flat = lambda x: x.reshape(T * B, *x.shape[2:])
        batch = Batch(
            flat(states), flat(actions), flat(old.log_prob), flat(advantages), flat(returns)
        )
        stats = update(model.evaluate, model.parameters(), optimizer, batch, bounds, config)
    probe = torch.rand(256, 2) * 2 - 1
    with torch.no_grad():
        out = model.evaluate(probe, torch.zeros(256, 2))
    error = (out.mean - probe / 1.5).abs()  # (256, 2); it starts near 0.5
    assert error.max() < 0.1 and error.mean() < 0.03
    expected = rewards_of(probe, out.mean) - torch.tensor([2, 1]) * 0.09  # E over the noise
    assert (out.values - expected).abs().mean() < 0.1
    assert stats.gradient_steps >= 1 and 1e-6 <= stats.learning_rate <= 1e-2


def test_the_first_minibatch_neither_stops_nor_moves_the_learning_rate() -> None:
    """Its KL is zero when the old log-probs are the policy's own: counting it would raise the
    rate on every update. Here the old log-probs are far off (KL above 0.024 at once): the
    first step still happens, the second epoch stops, and only that KL lowers the rate."""
    torch.manual_seed(1)
    model = TinyActorCritic()
    before = [p.detach().clone() for p in model.parameters()]
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-4)
    states, actions = torch.rand(32, 2), torch.rand(32, 2)
    with torch.no_grad():
        old_log_prob = model.evaluate(states, actions).log_prob - 1.0
    batch = Batch(states, actions, old_log_prob, torch.randn(32, 2), torch.randn(32, 2))
    stats = update_tiny(model, optimizer, batch, config=AUTHORS)
    assert stats.early_stopped and stats.gradient_steps == 1
    assert not all(torch.equal(a, b) for a, b in zip(before, model.parameters(), strict=True))
    assert stats.learning_rate == pytest.approx(2e-4)


def test_a_policy_that_stays_close_keeps_raising_the_rate_from_the_second_step() -> None:
    """Zero advantages leave the policy where it is (KL stays ~0): 7 adaptations after the
    first step, each x1.5, none on the first."""
    model = TinyActorCritic()
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-5)
    states, actions = torch.rand(16, 2), torch.rand(16, 2)
    with torch.no_grad():
        out = model.evaluate(states, actions)
    batch = Batch(states, actions, out.log_prob, torch.zeros(16, 2), out.values)
    stats = update_tiny(model, optimizer, batch, config=AUTHORS)
    assert stats.gradient_steps == 8 and not stats.early_stopped
    assert stats.learning_rate == pytest.approx(1e-5 * 1.5**7)


def test_take_rows_walks_tensors_dicts_and_dataclasses() -> None:
    tree = {
        "a": torch.arange(4),
        "b": Evaluation(torch.arange(4), torch.zeros(4, 2), torch.ones(4, 3)),
        "c": None,
    }
    rows = take_rows(tree, torch.tensor([3, 1]))
    assert rows["a"].tolist() == [3, 1] and rows["b"].log_prob.tolist() == [3, 1]
    assert rows["b"].mean.shape == (2, 3) and rows["c"] is None


def test_the_energy_term_enters_the_update_only_when_weighted() -> None:
    """With every other weight 0, an update with energy_coef > 0 lowers the energy of the
    mean action; with energy_coef 0 (the authors' training) it changes nothing."""
    torch.manual_seed(0)
    states, velocity = torch.randn(B, 2), torch.ones(B, 7)
    energy = lambda mean, v: (
        mean.square().sum(-1) * v.sum(-1)
    ).mean()  # a stand-in of losses.energy_loss
    for coef in (0.0, 1.0):
        model = TinyActorCritic()
        before = energy(model.actor(states), velocity).item()
        with torch.no_grad():
            actions = model.actor(states)
            old = model.evaluate(states, actions)
        batch = Batch(
            states, actions, old.log_prob, torch.zeros(B, 2), old.values, joint_velocity=velocity
        )
        config = PPOConfig(
            policy_coef=0.0, value_coef=0.0, bound_coef=0.0, energy_coef=coef, epochs=4
        )
        optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
        stats = update_tiny(model, optimizer, batch, config=config, energy=energy)
        after = energy(model.actor(states), velocity).item()
        assert (
            (after < before and stats.energy_loss > 0)
            if coef
            else (after == before and stats.energy_loss == 0)
        )


def overshooting_batch(model: TinyActorCritic) -> Batch:
    """256 samples whose large advantages, at a rate of 0.03, move the policy past the KL
    bound within an update."""
    torch.manual_seed(3)
    states = torch.rand(256, 2) * 2 - 1
    with torch.no_grad():
        mean = model.evaluate(states, torch.zeros(256, 2)).mean
        actions = mean + math.exp(LOG_STD) * torch.randn(256, 2)
        old = model.evaluate(states, actions).log_prob
    advantages = rewards_of(states, actions)
    return Batch(states, actions, old, advantages, torch.zeros(256, 2))


def kl_after(model: TinyActorCritic, batch: Batch) -> float:
    with torch.no_grad():
        return float(approx_kl(model.evaluate(batch.inputs, batch.actions).log_prob,
                               batch.old_log_prob))  # fmt: skip


@pytest.mark.parametrize("kl_stop", ["rollback", "before-step"])
def test_the_update_ends_within_the_kl_bound_only_when_it_undoes_the_step_past_it(
    kl_stop: str,
) -> None:
    """The authors' check before each step keeps the step that overshoots (their updates
    ended at 2-4x the bound); rollback measures each step's KL and undoes one past it."""
    model = TinyActorCritic()
    config = PPOConfig(minibatches=1, lr=0.03, lr_bounds=(1e-6, 0.1), kl_stop=kl_stop)
    batch = overshooting_batch(model)
    stats = update_tiny(model, torch.optim.Adam(model.parameters(), lr=0.03), batch, config=config)
    bound = config.early_stop_factor * config.kl_target
    assert stats.early_stopped and stats.gradient_steps >= 1
    if kl_stop == "rollback":
        assert kl_after(model, batch) <= bound
        assert stats.approx_kl == pytest.approx(kl_after(model, batch), rel=1e-5)
    else:
        assert kl_after(model, batch) > bound


def test_the_critic_goes_on_alone_at_its_own_rate_once_the_actor_stops() -> None:
    """With its own param group the critic takes every remaining minibatch's step after the
    actor stopped; the actor's parameters stay where the update left them."""
    model = TinyActorCritic()
    config = PPOConfig(minibatches=1, lr=0.03, lr_bounds=(1e-6, 0.1), value_lr=1e-3)
    optimizer = optimizer_for(model.actor.parameters(), model.critic.parameters(), config)
    batch = overshooting_batch(model)
    stats = update_tiny(model, optimizer, batch, config=config)
    assert stats.early_stopped
    assert stats.gradient_steps + stats.value_steps + 1 == config.epochs  # one step undone
    assert optimizer.param_groups[1]["lr"] == 1e-3  # not adapted to the actor's KL


def test_gradient_agreement_is_one_when_the_two_halves_are_the_same_samples() -> None:
    """The diagnostic compares the actor's gradients on the two halves of the first
    minibatch: identical halves agree exactly, independent ones much less."""
    model = TinyActorCritic()
    half = overshooting_batch(model)
    twice = Batch(*(torch.cat([x, x]) for x in (half.inputs, half.actions, half.old_log_prob,
                                                 half.advantages, half.returns)))  # fmt: skip
    config = PPOConfig(minibatches=1, epochs=1, normalize_advantages=False)
    same = update_tiny(model, torch.optim.Adam(model.parameters()), twice, config=config)
    assert same.gradient_agreement == pytest.approx(1.0, abs=1e-5)
    fresh = TinyActorCritic()
    other = update_tiny(fresh, torch.optim.Adam(fresh.parameters()), half, config=config)
    assert -1.0 <= other.gradient_agreement < 0.999


class SharedTrunk(TinyActorCritic):
    """A trunk the actor trains and the critic reads with its gradient stopped (HAMnet's
    default), counting the passes through it."""

    def __init__(self) -> None:
        super().__init__()
        self.trunk, self.actor, self.critic = nn.Linear(2, 4), nn.Linear(4, 2), nn.Linear(4, 2)
        self.passes = 0

    def value_features(self, states: Tensor) -> Tensor:
        self.passes += 1
        return torch.tanh(self.trunk(states))

    def values_from(self, features: Tensor) -> Tensor:
        return self.critic(features)

    def evaluate(self, states: Tensor, actions: Tensor) -> Evaluation:
        features = self.value_features(states)
        mean = self.actor(features)
        log_prob = (-0.5 * ((actions - mean) / math.exp(LOG_STD)).square() - LOG_STD
                    - 0.5 * math.log(2 * math.pi)).sum(-1)  # fmt: skip
        return Evaluation(log_prob, self.values_from(features.detach()), mean)


@pytest.mark.parametrize("kl_stop", ["rollback", "before-step"])
def test_the_critic_alone_on_features_computed_once_steps_as_on_the_whole_network(
    kl_stop: str,
) -> None:
    """Once the actor stops, the critic-only steps read the trunk's features of the whole
    batch, computed once: the same parameters as running the whole network every step, with
    one trunk pass per minibatch chunk instead of one per step."""
    config = PPOConfig(
        minibatches=4, lr=0.01, lr_bounds=(1e-6, 0.1), value_lr=1e-3, kl_stop=kl_stop
    )
    results = []
    for critic in (False, True):
        torch.manual_seed(0)
        model = SharedTrunk()
        optimizer = optimizer_for([*model.trunk.parameters(), *model.actor.parameters()],
                                  model.critic.parameters(), config)  # fmt: skip
        batch = overshooting_batch(model)
        model.passes = 0
        stats = update_tiny(model, optimizer, batch, config=config,
                            generator=torch.Generator().manual_seed(1),
                            critic=model if critic else None)  # fmt: skip
        results.append((stats, model.passes, [p.detach().clone() for p in model.parameters()]))
    (whole, whole_passes, whole_params), (alone, alone_passes, alone_params) = results
    assert whole.early_stopped and whole.value_steps >= 8
    assert (alone.gradient_steps, alone.value_steps) == (whole.gradient_steps, whole.value_steps)
    for a, b in zip(alone_params, whole_params, strict=True):
        torch.testing.assert_close(a, b)
    # Until the stop both run the network on each minibatch; then one pass per chunk.
    assert alone_passes <= whole_passes - whole.value_steps + 1 + config.minibatches


def test_explained_variance_says_how_much_of_the_return_targets_the_critic_predicted() -> None:
    """Advantages are returns - values: zero advantages mean the critic predicted every
    target (1); advantages equal to the centred targets mean it predicted only their mean
    (0); twice that, worse than the mean (-3). Terms are summed first; constant targets say
    nothing (NaN)."""
    returns = torch.tensor([[1.0, 0.0], [3.0, 0.5], [0.0, -0.5], [2.0, 1.0]])  # (N, R)
    centred = returns - returns.mean(dim=0)
    assert explained_variance(torch.zeros_like(returns), returns) == pytest.approx(1.0)
    assert explained_variance(centred, returns) == pytest.approx(0.0, abs=1e-6)
    assert explained_variance(2 * centred, returns) == pytest.approx(-3.0)
    assert math.isnan(explained_variance(torch.zeros(4, 2), torch.ones(4, 2)))


def test_every_update_reports_its_critics_explained_variance() -> None:
    """The figure of the update's own batch, in the stats the metrics rows carry."""
    model = TinyActorCritic()
    batch = dataclasses.replace(
        overshooting_batch(model),
        returns=torch.randn(
            overshooting_batch(model).returns.shape, generator=torch.Generator().manual_seed(0)
        ),
    )
    stats = update_tiny(
        model, torch.optim.Adam(model.parameters()), batch, config=PPOConfig(epochs=1)
    )
    assert math.isfinite(stats.explained_variance)
    assert stats.explained_variance == pytest.approx(
        explained_variance(batch.advantages, batch.returns)
    )
    assert math.isnan(UpdateStats.none(3e-4).explained_variance)


def test_the_energy_loss_is_refused_in_the_paddle_action_space() -> None:
    """The energy loss reads the action's first components as joint residuals: a paddle
    twist run that asks for it is refused before anything is built."""
    energetic = RunConfig(action_space="paddle", ppo=PPOConfig(energy_coef=0.1))
    with pytest.raises(ValueError, match="--action-space joint"):
        PPO(energetic).prepare(energetic)
    plain = dataclasses.replace(energetic, ppo=PPOConfig())
    assert PPO(plain).prepare(plain) == plain
