"""One PPO update on a rollout: epochs of clipped-surrogate, value and bound losses, with KL
early stopping and the KL-adaptive learning rate (paper Table tab:PPO, the authors'
configuration where they differ: `hamnet.trainer.config`).

The update knows nothing of HAMnet: it takes the rollout's policy inputs as any tree of
tensors (tensors, dicts, dataclasses) whose leading dimension is the sample, and a function
that evaluates actions under the current parameters. Shapes: N samples, A action
components, R reward terms.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol

import torch
from torch import Tensor

from hamnet.trainer.adaptive_lr import adapt_learning_rate
from hamnet.trainer.config import PPOConfig
from hamnet.trainer.losses import (
    approx_kl,
    bound_loss,
    clip_fraction,
    normalize_advantages,
    policy_loss,
    value_loss,
)
from hamnet.trainer.ranks import ONE, Ranks
from hamnet.trainer.trees import take_rows


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


@dataclass(frozen=True)
class UpdateStats:
    """What one update did, for the metrics topic and the progress line."""

    policy_loss: float
    value_loss: float
    bound_loss: float
    approx_kl: float
    """KL(old || new) at the last evaluated minibatch."""
    clip_fraction: float
    learning_rate: float
    """After the update's adaptations."""
    gradient_steps: int
    early_stopped: bool
    energy_loss: float = 0.0
    """0 unless the energy loss is on."""


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
) -> UpdateStats:
    """Run up to `config.epochs` epochs of `config.minibatches` gradient steps on `batch`.

    An epoch's step is skipped and the update ends once a minibatch's KL exceeds
    `early_stop_factor * kl_target`; after every evaluated minibatch the learning rate of
    `optimizer` adapts to its KL (the authors' `_train_batch`, `ppo.py:567-596`). Neither
    happens on the first minibatch, whose KL is zero by construction: it would raise the
    rate every update (the authors' `updated_policy` guard, `ppo.py:680-694`).

    Args:
        evaluate: evaluates actions with gradients under the current parameters.
        parameters: what the optimizer trains (for gradient clipping).
        optimizer: its param groups' `lr` is read and adapted in place.
        batch: the rollout.
        action_bounds: (A,) low and high of the raw action; the bound loss keeps the mean
            within `bound_scale` times them.
        config: hyperparameters.
        generator: shuffles the minibatches.
        energy: (action mean, joint velocity) -> energy loss, weighted by
            `config.energy_coef` when that is above 0 (`losses.energy_loss`).
        ranks: the learner's processes, `batch` being this one's shard: the advantages'
            statistics, every minibatch's diagnostics (so the KL's decisions) and the
            gradients are those of all shards together (`hamnet.trainer.ranks`).
    """
    parameters = list(parameters)
    advantages = (
        normalize_advantages(batch.advantages, moments=ranks.moments)
        if config.normalize_advantages
        else batch.advantages
    )
    low, high = (bound * config.bound_scale for bound in action_bounds)
    n = batch.actions.shape[0]
    lr = optimizer.param_groups[0]["lr"]
    steps, stopped, last = 0, False, {}
    for _ in range(config.epochs):
        order = (
            torch.randperm(n, generator=generator) if config.minibatches > 1 else torch.arange(n)
        )
        for rows in order.chunk(config.minibatches):
            out = evaluate(take_rows(batch.inputs, rows), batch.actions[rows])
            old = batch.old_log_prob[rows]
            terms = {
                "policy": policy_loss(out.log_prob, old, advantages[rows], config.clip),
                "value": value_loss(out.values, batch.returns[rows]),
                "bound": bound_loss(out.mean, low, high),
            }
            if config.energy_coef > 0 and energy is not None and batch.joint_velocity is not None:
                terms["energy"] = energy(out.mean, batch.joint_velocity[rows])
            diagnostics = {**terms, "kl": approx_kl(out.log_prob.detach(), old),
                           "clip": clip_fraction(out.log_prob.detach(), old, config.clip)}  # fmt: skip
            means = ranks.mean_of(torch.stack(list(diagnostics.values())).detach(), len(rows))
            last = dict(zip(diagnostics, means.tolist(), strict=True))
            kl = last["kl"]
            if steps and kl > config.early_stop_factor * config.kl_target:
                lr = _adapt(optimizer, lr, kl, config)
                stopped = True
                break
            loss = (config.policy_coef * terms["policy"] + config.value_coef * terms["value"]
                    + config.bound_coef * terms["bound"]
                    + config.energy_coef * terms.get("energy", 0.0))  # fmt: skip
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            ranks.average_gradients(parameters, len(rows))
            torch.nn.utils.clip_grad_norm_(parameters, config.max_grad_norm)
            optimizer.step()
            if steps:
                lr = _adapt(optimizer, lr, kl, config)
            steps += 1
        if stopped:
            break
    return UpdateStats(last["policy"], last["value"], last["bound"], last["kl"], last["clip"], lr, steps, stopped,
                       last.get("energy", 0.0))  # fmt: skip


def _adapt(optimizer: torch.optim.Optimizer, lr: float, kl: float, config: PPOConfig) -> float:
    """Set the optimizer's learning rate for the next step from this step's KL."""
    lr = adapt_learning_rate(lr, kl, config)
    for group in optimizer.param_groups:
        group["lr"] = lr
    return lr
