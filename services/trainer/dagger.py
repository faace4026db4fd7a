"""DAgger's pure core (issue 15): the schedule of beta, the probability that the teacher
acts, and the student's imitation update over sequences.

DAgger (Ross, Gordon and Bagnell 2011) trains on the states the mixture of teacher and
student visits, labelled by the teacher. HAMnet's paper distils its student this way but
gives no schedule, loss weights or epochs for it, and the authors released no DAgger code:
every default below is ours, and each says why. Shapes: T steps, B environments, A action
components, R reward terms.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.policy import Policy
from hamnet.trainer.sequence import episode_starts, evaluate_sequence


@dataclass(frozen=True)
class DaggerConfig:
    """Beta's schedule and the student's update. Neither the paper nor the authors give
    DAgger settings; these are ours."""

    beta_initial: float = 1.0
    """Probability that the teacher acts an episode at the start: 1, DAgger's first
    iteration (the teacher alone), so the student first learns on the teacher's states."""
    beta_final: float = 0.0
    """... and once the decay is over: 0, the student alone, the deployed situation, so the
    late data are the states the student itself drifts into."""
    beta_decay_transitions: int = 200_000
    """env_transitions over which beta falls linearly from `beta_initial` to `beta_final`:
    about a third of an hour's run on this machine (roughly 150 env steps/s with two
    perceptions), so most of the run trains on the student's own states."""
    epochs: int = 4
    """Gradient steps per rollout, each on the whole (T, B) window (as PPO's one minibatch
    per epoch): a few, since the window is small and the next one comes from similar states."""
    lr: float = 3e-4
    """Adam's learning rate: PPO's base rate (paper Table tab:PPO), constant."""
    max_grad_norm: float = 1.0
    """Gradient clipping by global norm: PPO's (authors' `ppo.py:98`)."""
    value_coef: float = 0.0
    """Weight of the value loss (0.5 x squared error to the teacher's values per reward
    term); 0: off. The deployed student needs no critic; on, it gives the student a critic
    for fine-tuning by PPO later."""

    def __post_init__(self) -> None:
        for name in ("beta_initial", "beta_final"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.beta_decay_transitions < 0 or self.epochs < 1:
            raise ValueError("beta_decay_transitions must be >= 0 and epochs >= 1")
        if not (self.lr > 0 and self.max_grad_norm > 0 and self.value_coef >= 0):
            raise ValueError("lr and max_grad_norm must be > 0, value_coef >= 0")


@dataclass(frozen=True)
class AlgoConfig:
    """What a run learns by: the flags `hamnet trainer` and its `hamnet rollout` workers
    share (`--algo`, `--teacher`, `--dagger.*`; workers must be given the trainer's)."""

    algo: Literal["ppo", "dagger"] = "ppo"
    """ppo: learn by PPO. dagger: distil `--teacher` into the run's `--architecture` (default
    `student` then) by DAgger; rollout workers host the teacher beside the student."""
    teacher: Path | None = None
    """With --algo dagger: the teacher, a policy checkpoint `hamnet trainer` wrote (its
    `checkpoints/latest.safetensors`), the same file for the trainer and its workers. Give
    the run the teacher's --stage and encoder flags."""
    dagger: DaggerConfig = field(default_factory=DaggerConfig)
    """DAgger's beta schedule and student update (`--dagger.*`), with --algo dagger: workers
    draw who acts from the same schedule."""


def beta_at(env_transitions: int, config: DaggerConfig) -> float:
    """Probability that the teacher acts an episode that starts at the counter
    `env_transitions` (linear from `beta_initial` to `beta_final`, then constant)."""
    if config.beta_decay_transitions == 0:
        return config.beta_final
    done = min(1.0, max(0, env_transitions) / config.beta_decay_transitions)
    return config.beta_initial + (config.beta_final - config.beta_initial) * done


@dataclass(frozen=True)
class Demonstrations:
    """T steps of B environments: what the student saw and what the teacher would have done."""

    inputs: PolicyInputs
    """The student's inputs, every tensor (T * B, ...), time-major (`trajectory.cat_rows`)."""
    labels: Tensor
    """(T, B, A) the teacher's action mean in every visited state."""
    label_values: Tensor
    """(T, B, R) the teacher's values there (the optional value loss's targets)."""
    teacher_acted: Tensor
    """(T, B) bool: the teacher's action was executed (else the student's)."""
    first: Tensor
    """(B,) bool: step 0 begins an episode."""
    rewards: Tensor
    """(T, B, R) reward terms as the sim gave them (for the episode statistics)."""
    dones: Tensor
    """(T, B) bool: the episode ended at this step."""
    success: Tensor
    """(T, B) bool: the episode ended in success at this step."""


@dataclass(frozen=True)
class ImitationStats:
    """What one student update did."""

    imitation_loss: float
    """Mean squared error of the student's action mean before the update's first step: on
    data it has not yet fitted, the honest figure."""
    imitation_loss_after: float
    """... at the last step."""
    value_loss: float
    """The value loss at the last step (computed even when its weight is 0)."""
    gradient_norm: float
    """Global gradient norm before clipping, at the last step."""


def imitation_loss(mean: Tensor, labels: Tensor) -> Tensor:
    """Mean squared error between the student's action means and the teacher's, averaged
    over steps, environments and action components. The teacher's mean is a point label and
    the student is deployed with its mean, so the squared error on means is what matters;
    a Gaussian likelihood with the student's scheduled std would only rescale it."""
    return (mean - labels).square().mean()


def value_loss(values: Tensor, targets: Tensor) -> Tensor:
    """0.5 x squared error to the teacher's values, summed over reward terms, mean over steps."""
    return 0.5 * (values - targets).square().sum(-1).mean()


def update_student(
    student: Policy,
    optimizer: torch.optim.Optimizer,
    batch: Demonstrations,
    config: DaggerConfig,
) -> ImitationStats:
    """`config.epochs` Adam steps on the whole window, each unrolling the student's GRUs over
    the T steps with their memory reset where an episode starts (`evaluate_sequence`)."""
    starts = episode_starts(batch.dones, batch.first)
    parameters = list(student.parameters())
    for group in optimizer.param_groups:
        group["lr"] = config.lr
    student.train()
    first = None
    for _ in range(config.epochs):
        out = evaluate_sequence(student, batch.inputs, batch.labels, starts)
        actions = imitation_loss(out.mean, batch.labels)
        values = value_loss(out.values, batch.label_values)
        first = actions.item() if first is None else first
        optimizer.zero_grad(set_to_none=True)
        (actions + config.value_coef * values).backward()
        norm = torch.nn.utils.clip_grad_norm_(parameters, config.max_grad_norm)
        optimizer.step()
    return ImitationStats(first, actions.item(), values.item(), float(norm))
