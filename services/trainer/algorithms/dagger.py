"""DAgger's pure core (issue 15): the schedule of beta, the probability that the teacher
acts, and the student's imitation update over sequences.

DAgger (Ross, Gordon and Bagnell 2011) trains on the states the mixture of teacher and
student visits, labelled by the teacher. HAMnet's paper distils its student this way but
gives no schedule, loss weights or epochs for it, and the authors released no DAgger code:
every default below is ours, and each says why. Shapes: T steps, B environments, A action
components, R reward terms.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import VELOCITY_WIDTH
from hamnet.policy.policy import Policy
from hamnet.policy.rollout_record import merge_environments
from hamnet.trainer.algorithms.recurrent_unroll import episode_starts, evaluate_sequence
from hamnet.trainer.config import DaggerConfig


def linear(start: float, end: float, span: int, env_transitions: int) -> float:
    """`start` at the counter 0, `end` from `span` on, linear in between (`end` throughout
    for a span of 0): DAgger's schedules."""
    if span == 0:
        return end
    done = min(1.0, max(0, env_transitions) / span)
    return start + (end - start) * done


def beta_at(env_transitions: int, config: DaggerConfig) -> float:
    """Probability that the teacher acts an episode that starts at the counter
    `env_transitions` (from `beta_initial` to `beta_final` over `beta_decay_transitions`)."""
    return linear(
        config.beta_initial, config.beta_final, config.beta_decay_transitions, env_transitions
    )


def lr_at(env_transitions: int, config: DaggerConfig) -> float:
    """The student's learning rate at the counter `env_transitions` (from `lr` to
    `lr_final` over `lr_decay_transitions`)."""
    return linear(config.lr, config.lr_final, config.lr_decay_transitions, env_transitions)


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
    object_velocity: Tensor
    """(T, B, 6) the object's true velocity in every visited state (linear m/s, angular
    rad/s; the teacher's privileged input, the optional velocity loss's target)."""


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
    velocity_loss: float
    """The velocity read-out's loss at the last step (`VelocityReadout.loss`; NaN without
    one)."""


def imitation_loss(mean: Tensor, labels: Tensor) -> Tensor:
    """Mean squared error between the student's action means and the teacher's, averaged
    over steps, environments and action components. The teacher's mean is a point label and
    the student is deployed with its mean, so the squared error on means is what matters;
    a Gaussian likelihood with the student's scheduled std would only rescale it."""
    return (mean - labels).square().mean()


def value_loss(values: Tensor, targets: Tensor) -> Tensor:
    """0.5 x squared error to the teacher's values, summed over reward terms, mean over steps."""
    return 0.5 * (values - targets).square().sum(-1).mean()


class VelocityReadout(torch.nn.Module):
    """A linear read-out of the object's velocity from the student's memory, for the
    velocity loss: the teacher relies on the object's velocity, which the student must infer
    from its history of pose estimates (docs/trainer.md, "What a teacher's privileged inputs
    are worth"); the loss's gradient asks the student's memory to hold it. Training only:
    the student's checkpoint does not carry it."""

    def __init__(self, memory_width: int, teacher: Policy) -> None:
        """`teacher`'s input statistics of the velocity (fixed from now on) set the loss's
        units: the velocity as the teacher reads it."""
        super().__init__()
        self.linear = torch.nn.Linear(memory_width, VELOCITY_WIDTH)
        normalizer, spec = teacher.normalizer, teacher.config.observation
        state = spec.columns("base", "object_state")
        columns = slice(state.stop - VELOCITY_WIDTH, state.stop)  # the pose, then the velocity
        self.register_buffer("mean", normalizer.base_mean[columns].clone())
        self.register_buffer("std", (normalizer.base_var[columns] + normalizer.eps).sqrt())
        self.clip = normalizer.clip

    def target(self, velocity: Tensor) -> Tensor:
        """The (..., 6) true `velocity` standardised (and clipped) as the teacher standardises
        its input: what the read-out learns to give."""
        return ((velocity - self.mean) / self.std).clamp(-self.clip, self.clip)

    def loss(self, memories: Tensor, velocity: Tensor) -> Tensor:
        """Mean squared error of the read-out of (T, B, H) `memories` against the (T, B, 6)
        true `velocity`, in the teacher's standardised units (`target`): about 1 for a
        read-out no better than the teacher's mean velocity, 0 exact."""
        return (self.linear(memories) - self.target(velocity)).square().mean()


def update_student(
    student: Policy,
    optimizer: torch.optim.Optimizer,
    batch: Demonstrations,
    config: DaggerConfig,
    readout: VelocityReadout | None = None,
    replayed: Callable[[], list[Demonstrations]] = list,
) -> ImitationStats:
    """`config.epochs` Adam steps on the whole window, each unrolling the student's GRUs over
    the T steps with their memory reset where an episode starts (`evaluate_sequence`);
    with `readout` (in `optimizer`), the velocity loss at `config.velocity_coef` too. The
    gradient is clipped over every parameter `optimizer` steps. Each step's batch is the
    window beside the windows `replayed()` gives for it (older ones, of the same T); the
    imitation losses reported are the window's own."""
    parameters = [p for group in optimizer.param_groups for p in group["params"]]
    for group in optimizer.param_groups:
        group["lr"] = config.lr
    student.train()
    width, first = batch.dones.shape[1], None
    for _ in range(config.epochs):
        older = replayed()
        merged = merge_environments([batch, *older]) if older else batch
        starts = episode_starts(merged.dones, merged.first)
        out = evaluate_sequence(student, merged.inputs, merged.labels, starts)
        own = imitation_loss(out.mean[:, :width], batch.labels).detach()
        actions = imitation_loss(out.mean, merged.labels)
        values = value_loss(out.values, merged.label_values)
        loss, velocity = actions + config.value_coef * values, math.nan
        if readout is not None:
            read = readout.loss(out.memories, merged.object_velocity)
            loss, velocity = loss + config.velocity_coef * read, read.item()
        first = own.item() if first is None else first
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        norm = torch.nn.utils.clip_grad_norm_(parameters, config.max_grad_norm)
        optimizer.step()
    return ImitationStats(first, own.item(), values.item(), float(norm), velocity)


@torch.no_grad()
def average_into(average: torch.nn.Module, latest: torch.nn.Module, decay: float) -> None:
    """One step of an exponential moving average of `latest`'s parameters into `average`'s
    (the same network): average <- decay x average + (1 - decay) x latest."""
    for mine, its in zip(average.parameters(), latest.parameters(), strict=True):
        mine.lerp_(its, 1.0 - decay)
