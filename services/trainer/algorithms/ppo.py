"""One PPO update on a rollout: epochs of clipped-surrogate, value and bound losses, with KL
early stopping (a step past the bound undone) and the KL-adaptive learning rate (paper Table
tab:PPO, the authors' configuration where they differ: `hamnet.trainer.config`).

The update knows nothing of HAMnet: it takes the rollout's policy inputs as any tree of
tensors (tensors, dicts, dataclasses) whose leading dimension is the sample, and a function
that evaluates actions under the current parameters. Shapes: N samples, A action
components, R reward terms.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import partial
from typing import Any, Protocol

import torch
from torch import Tensor

from hamnet.runtime.trees import take_rows, zip_trees
from hamnet.trainer.algorithms.adaptive_lr import adapt_learning_rate
from hamnet.trainer.algorithms.ppo_losses import (
    approx_kl,
    bound_loss,
    clip_fraction,
    explained_variance,
    guide_loss,
    normalize_advantages,
    policy_loss,
    value_loss,
)
from hamnet.trainer.config import PPOConfig
from hamnet.trainer.runners.ranks import ONE, Ranks
from hamnet.trainer.runners.stopping import always, check


class Evaluated(Protocol):
    """What evaluating actions under the current parameters gives (`Policy.evaluate`)."""

    log_prob: Tensor
    """(N,) log-density of the given actions."""
    values: Tensor
    """(N, R) value per reward term."""
    mean: Tensor
    """(N, A) mean of the action distribution (for the bound loss)."""


Evaluate = Callable[[Any, Tensor], Evaluated]
"""(inputs of N samples, actions (N, A)) -> Evaluated, with gradients."""


class Critic(Protocol):
    """A policy whose critic reads features computed before it (`Policy.value_features`)."""

    def value_features(self, inputs: Any) -> Any:
        """What the critic reads of inputs of N samples: a tree of (N, ...) tensors."""

    def values_from(self, features: Any) -> Tensor:
        """(N, R) values of those features, with gradients for the critic's parameters."""


@dataclass(frozen=True)
class Batch:
    """A rollout flattened over time and environments."""

    inputs: Any
    """Policy inputs of N samples: a tensor, or a dict/dataclass tree of tensors (N, ...)."""
    actions: Tensor
    """(N, A) actions taken."""
    old_log_prob: Tensor
    """(N,) their log-density under the acting policy."""
    advantages: Tensor
    """(N, R) GAE per reward term."""
    returns: Tensor
    """(N, R) value targets per reward term."""
    joint_velocity: Tensor | None = None
    """(N, J) measured joint velocities, rad/s, for the energy loss (None: no energy loss)."""
    guide: Tensor | None = None
    """(N, A) the scripted pusher's raw actions, the imitation term's target (None: none)."""
    guide_weight: float = 0.0
    """The imitation term's weight in the actor's loss (`GuideConfig.weight`)."""


@dataclass(frozen=True)
class UpdateStats:
    """What one update did, for the metrics topic and the progress line."""

    policy_loss: float
    value_loss: float
    bound_loss: float
    approx_kl: float
    """KL(old || new) of the policy the update kept, on the minibatch it was measured on."""
    clip_fraction: float
    learning_rate: float
    """The actor's, after the update's adaptations."""
    gradient_steps: int
    """Steps of the actor the update kept (a step undone by `kl_stop` rollback is not one)."""
    early_stopped: bool
    energy_loss: float = 0.0
    """0 unless the energy loss is on."""
    value_steps: int = 0
    """Steps of the critic alone after the actor stopped (its own param group only)."""
    gradient_agreement: float = math.nan
    """Cosine similarity of the actor's loss gradients on the two halves of the first
    minibatch: near 0, sampling noise dominates the gradient and each step spends its KL on
    a random direction (about 0.01-0.03 at 512 samples of the easy stage, 0.1 at 2048)."""
    explained_variance: float = math.nan
    """How much of the rollout's summed return targets the acting critic predicted
    (`ppo_losses.explained_variance`): near 0, the advantages are the returns' noise."""
    guide_loss: float = math.nan
    """The imitation term (mean squared error of the mean against the scripted pusher's
    actions) of the policy the update kept; NaN in a run without a guide."""

    @classmethod
    def none(cls, learning_rate: float) -> UpdateStats:
        """An iteration that made no update (it only filled the input statistics)."""
        nan = math.nan
        return cls(nan, nan, nan, nan, nan, learning_rate, 0, False, nan, 0, nan, nan)


def optimizer_for(
    actor: Iterable[Tensor], critic: Iterable[Tensor], config: PPOConfig
) -> torch.optim.Adam:
    """Adam over a policy's parameters: param group 0 is everything the actor's loss reaches
    (its rate adapted to the KL); with `config.value_lr` the critic's own parameters are a
    second group at that rate, else they join the first (the authors' one optimizer)."""
    actor, critic = list(actor), list(critic)
    if config.value_lr is None:
        return torch.optim.Adam(actor + critic, lr=config.lr)
    return torch.optim.Adam(
        [{"params": actor, "lr": config.lr}, {"params": critic, "lr": config.value_lr}]
    )


def update(
    evaluate: Evaluate,
    parameters: Iterable[Tensor],
    optimizer: torch.optim.Optimizer,
    batch: Batch,
    action_bounds: tuple[Tensor, Tensor],
    config: PPOConfig,
    generator: torch.Generator | None = None,
    energy: Callable[[Tensor, Tensor], Tensor] | None = None,
    ranks: Ranks = ONE,
    running: Callable[[], bool] = always,
    critic: Critic | None = None,
) -> UpdateStats:
    """Run up to `config.epochs` epochs of `config.minibatches` gradient steps on `batch`.

    Every minibatch's forward pass first measures the KL of the policy the previous step
    made (on samples that step did not fit) and decides by `config.kl_stop` whether that
    step stands; the actor's rate then adapts to that KL (`config.lr_schedule`). Nothing is
    decided on the first minibatch, whose KL is zero by construction (the authors'
    `updated_policy` guard, `ppo.py:680-694`). Once the actor stops, a critic with its own
    param group (`optimizer_for`) goes on alone through the remaining minibatches.

    Args:
        evaluate: evaluates actions with gradients under the current parameters.
        parameters: what the optimizer trains (for gradient clipping).
        optimizer: from `optimizer_for`; group 0's `lr` is read and adapted in place.
        batch: the rollout.
        action_bounds: (A,) low and high of the raw action; the bound loss keeps the mean
            within `bound_scale` times them.
        config: hyperparameters.
        generator: shuffles the minibatches.
        energy: (action mean, joint velocity) -> energy loss, weighted by
            `config.energy_coef` when that is above 0 (`losses.energy_loss`).
        ranks: the learner's processes, `batch` being this one's shard: the advantages'
            statistics, every minibatch's diagnostics (so the KL's decisions) and the
            gradients are those of all shards together (`hamnet.trainer.runners.ranks`).
        running: checked before every minibatch: InterruptedError once it turns False (the
            caller goes back to the parameters from before the update).
        critic: the policy, when its critic reads features of everything before it: once
            the actor stops, those layers are frozen, so the critic-only steps compute the
            features of the whole batch once (`critic.value_features`) and run the critic
            alone on them, instead of the whole network every step (the same values).
    """
    parameters = list(parameters)
    actor: list[Tensor] = list(optimizer.param_groups[0]["params"])
    critic_alone = len(optimizer.param_groups) > 1
    advantages = (
        normalize_advantages(batch.advantages, moments=ranks.moments)
        if config.normalize_advantages
        else batch.advantages
    )
    losses = partial(_losses, evaluate, batch, advantages, action_bounds, config, energy, ranks)
    bound = config.early_stop_factor * config.kl_target
    n, lr = batch.actions.shape[0], optimizer.param_groups[0]["lr"]
    steps = value_steps = 0
    stopped, kept, before, agreement, features = False, {}, None, math.nan, None
    try:
        for _ in range(config.epochs):
            for rows in _minibatches(n, config, generator):
                check(running)
                if stopped and not critic_alone:
                    break
                if not (stopped and critic is not None):  # else no network pass is needed
                    first = steps == 0 and not stopped
                    parts, diagnostics = losses(
                        rows.chunk(2) if first and len(rows) > 1 else (rows,)
                    )
                    kl = diagnostics["kl"] if steps and not stopped else None
                    if kl is not None:
                        stopped = config.kl_stop != "off" and kl > bound
                        if stopped and critic_alone:  # the critic's steps need no actor gradient
                            _freeze(actor, True)
                        if stopped and config.kl_stop == "rollback":
                            _restore(actor, before)
                            steps -= 1
                            if critic_alone and critic is None:  # a graph of the restored actor
                                parts, _ = losses((rows,))
                        else:
                            kept = diagnostics
                        if stopped and config.lr_schedule == "adaptive":
                            lr = _adapt(optimizer, lr, kl, config)
                    elif first:
                        kept = diagnostics
                    if stopped and not critic_alone:
                        break
                if stopped and critic is not None:
                    if features is None:
                        features = _value_features(critic, batch.inputs, n, config)
                    values = critic.values_from(take_rows(features, rows))
                    parts = [(1.0, {"value": value_loss(values, batch.returns[rows])})]
                if config.kl_stop == "rollback" and not stopped:
                    before = [p.detach().clone() for p in actor]
                optimizer.zero_grad(set_to_none=True)
                gradients = []
                for weight, terms in parts:
                    loss = config.value_coef * terms["value"]
                    if not stopped:
                        loss = loss + (
                            config.policy_coef * terms["policy"]
                            + config.bound_coef * terms["bound"]
                            + config.energy_coef * terms.get("energy", 0.0)
                            + batch.guide_weight * terms.get("guide", 0.0)
                        )
                    (weight * loss).backward()
                    if len(parts) == 2:
                        gradients.append(_flat_gradient(actor))
                if len(gradients) == 2:
                    agreement = _cosine(gradients[0], gradients[1] - gradients[0])
                if stopped:
                    for p in actor:
                        p.grad = None  # the critic's group alone steps
                ranks.average_gradients(parameters, len(rows))
                for group in optimizer.param_groups:  # the critic's own: not the actor's clip
                    torch.nn.utils.clip_grad_norm_(group["params"], config.max_grad_norm)
                optimizer.step()
                if stopped:
                    value_steps += 1
                    continue
                steps += 1
                if kl is not None and config.lr_schedule == "adaptive":  # the authors' order
                    lr = _adapt(optimizer, lr, kl, config)
    finally:
        _freeze(actor, False)
    if config.kl_stop == "rollback" and steps and not stopped:
        with torch.no_grad():  # the last step's KL, on a minibatch drawn afresh
            _, diagnostics = losses((next(iter(_minibatches(n, config, generator))),))
        stopped = diagnostics["kl"] > bound
        if stopped:
            _restore(actor, before)
            steps -= 1
        else:
            kept = diagnostics
    return UpdateStats(
        kept["policy"],
        kept["value"],
        kept["bound"],
        kept["kl"],
        kept["clip"],
        lr,
        steps,
        stopped,
        kept.get("energy", 0.0),
        value_steps,
        agreement,
        explained_variance(batch.advantages, batch.returns, ranks.moments),
        kept.get("guide", math.nan),
    )


def _value_features(critic: Critic, inputs: Any, n: int, config: PPOConfig) -> Any:
    """The critic's features of all N samples, minibatch-sized chunks at a time, without
    gradients."""
    with torch.no_grad():
        chunks = [
            critic.value_features(take_rows(inputs, rows))
            for rows in torch.arange(n).chunk(config.minibatches)
        ]
    return zip_trees(chunks, torch.cat)


def _minibatches(
    n: int, config: PPOConfig, generator: torch.Generator | None
) -> tuple[Tensor, ...]:
    """One epoch's minibatches of row indices (in order when there is one)."""
    order = torch.randperm(n, generator=generator) if config.minibatches > 1 else torch.arange(n)
    return order.chunk(config.minibatches)


def _losses(
    evaluate: Evaluate,
    batch: Batch,
    advantages: Tensor,
    action_bounds: tuple[Tensor, Tensor],
    config: PPOConfig,
    energy: Callable[[Tensor, Tensor], Tensor] | None,
    ranks: Ranks,
    parts: tuple[Tensor, ...],
) -> tuple[list[tuple[float, dict[str, Tensor]]], dict[str, float]]:
    """The loss terms of each part of a minibatch (rows of `batch`), with the part's share of
    the minibatch, and the minibatch's diagnostics (means over every rank's rows)."""
    low, high = (bound * config.bound_scale for bound in action_bounds)
    total = sum(len(rows) for rows in parts)
    out, sums = [], None
    for rows in parts:
        evaluated = evaluate(take_rows(batch.inputs, rows), batch.actions[rows])
        old = batch.old_log_prob[rows]
        terms = {
            "policy": policy_loss(
                evaluated.log_prob, old, advantages[rows], config.clip, config.clip_per_term
            ),
            "value": value_loss(evaluated.values, batch.returns[rows]),
            "bound": bound_loss(evaluated.mean, low, high),
        }
        if config.energy_coef > 0 and energy is not None and batch.joint_velocity is not None:
            terms["energy"] = energy(evaluated.mean, batch.joint_velocity[rows])
        if batch.guide is not None:
            terms["guide"] = guide_loss(evaluated.mean, batch.guide[rows])
        log_prob = evaluated.log_prob.detach()
        diagnostics = {
            **terms,
            "kl": approx_kl(log_prob, old),
            "clip": clip_fraction(log_prob, old, config.clip),
        }
        weighted = torch.stack(list(diagnostics.values())).detach() * len(rows)
        sums = weighted if sums is None else sums + weighted
        out.append((len(rows) / total, terms))
    means = ranks.mean_of(sums / total, total)
    return out, dict(zip(diagnostics, means.tolist(), strict=True))


def _flat_gradient(parameters: list[Tensor]) -> Tensor:
    """The parameters' gradients as one vector (zeros where there is none)."""
    return torch.cat(
        [(p.grad if p.grad is not None else torch.zeros_like(p)).reshape(-1) for p in parameters]
    )


def _cosine(a: Tensor, b: Tensor) -> float:
    """Cosine similarity of two vectors (NaN when either is zero)."""
    norms = a.norm() * b.norm()
    return float(a @ b / norms) if norms > 0 else math.nan


def _freeze(parameters: list[Tensor], frozen: bool) -> None:
    """Keep autograd out of (or let it back into) `parameters`: once the actor stops, the
    critic's steps through the networks both share would otherwise pay for gradients that
    are thrown away."""
    for p in parameters:
        p.requires_grad_(not frozen)


def _restore(parameters: list[Tensor], values: list[Tensor] | None) -> None:
    """Put back the parameters' values from before the step being undone."""
    with torch.no_grad():
        for p, value in zip(parameters, values or [], strict=True):
            p.copy_(value)


def _adapt(optimizer: torch.optim.Optimizer, lr: float, kl: float, config: PPOConfig) -> float:
    """Set the actor's learning rate (param group 0) for the next step from this step's KL."""
    lr = adapt_learning_rate(lr, kl, config)
    optimizer.param_groups[0]["lr"] = lr
    return lr
