"""The learner on several processes (torch.distributed): each rank learns from its own shard
of the rollout and every decision is taken on statistics of the whole one.

The PPO update sums each rank's gradient of its shard's mean loss, weighted by its share of
the rows, so every rank steps with the gradient of the whole batch's mean loss (an
all-reduce of the gradients, as DistributedDataParallel does, but weighted, so shards may
differ in size). What decides or scales the update is reduced first, so the ranks stay
identical: the advantages' mean and variance, and each minibatch's KL (early stopping, the
KL-adaptive rate), clip fraction and loss terms. The reward scaler, the episode tracker and
the policy's input statistics take in every rank's environments (`environments`: the small
per-step tensors and the observations, gathered side by side in rank order), so they equal
those of one learner of all the environments and rank 0's snapshot holds them all.

`ONE` is the single process: every method is the identity and torch.distributed is never
touched, so a one-rank run computes exactly what it did before ranks existed. Tensors are
on the CPU: the backend is gloo.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable
from dataclasses import dataclass

import torch
import torch.distributed as dist
from torch import Tensor, nn

from hamnet.policy.rollout_record import Rollout, merge_environments
from hamnet.runtime.trees import zip_trees
from hamnet.trainer.algorithms.ppo_losses import row_moments


@dataclass(frozen=True)
class Ranks:
    """This process's place among the learner's `size` processes."""

    rank: int = 0
    size: int = 1

    @property
    def main(self) -> bool:
        """Whether this rank publishes, logs and writes checkpoints and metrics (rank 0)."""
        return self.rank == 0

    def sum(self, x: Tensor) -> Tensor:
        """`x` summed over the ranks (every rank gets the same tensor)."""
        if self.size == 1:
            return x
        total = x.detach().clone()
        dist.all_reduce(total)
        return total

    def moments(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """Mean and biased variance over the rows (dim 0) of every rank's `x` together."""
        if self.size == 1:
            return row_moments(x)
        count = self.sum(torch.tensor(float(len(x)), dtype=x.dtype))
        mean = self.sum(x.sum(dim=0)) / count
        return mean, self.sum((x - mean).square().sum(dim=0)) / count

    def mean_of(self, means: Tensor, rows: int) -> Tensor:
        """(K,) means over this rank's `rows` rows -> the same means over every rank's rows."""
        if self.size == 1:
            return means
        count = torch.tensor([float(rows)], dtype=torch.float64)
        weighted = self.sum(torch.cat([means.detach().double() * rows, count]))
        return (weighted[:-1] / weighted[-1]).to(means.dtype)

    def average_gradients(self, parameters: Iterable[nn.Parameter], rows: int) -> None:
        """Turn each gradient of a mean loss over this rank's `rows` rows into the gradient of
        the mean over every rank's rows. Parameters without a gradient must be the same on
        every rank (the same network and loss terms everywhere)."""
        if self.size == 1:
            return
        grads = [p.grad for p in parameters if p.grad is not None]
        share = rows / float(self.sum(torch.tensor(float(rows), dtype=torch.float64)))
        flat = torch.cat([grad.reshape(-1) for grad in grads]) * share
        dist.all_reduce(flat)
        for grad, reduced in zip(grads, flat.split([g.numel() for g in grads]), strict=True):
            grad.copy_(reduced.view_as(grad))

    def gather(self, x: Tensor) -> list[Tensor]:
        """Every rank's `x` (the same shape on every rank), in rank order."""
        if self.size == 1:
            return [x]
        sent = x.to(torch.uint8) if x.dtype == torch.bool else x.contiguous()  # gloo: no bool
        out = [torch.empty_like(sent) for _ in range(self.size)]
        dist.all_gather(out, sent)
        return [part.to(x.dtype) for part in out]

    def environments(self, rollout: Rollout) -> Rollout:
        """The rollout of every rank's environments side by side, in rank order, as one
        learner of them all would see it; of the inputs only the observations travel (the
        tokens stay where they are learned from). Every rank needs the same T and B."""
        if self.size == 1:
            return rollout
        inputs = dataclasses.replace(
            rollout.inputs,
            **{f.name: None for f in dataclasses.fields(rollout.inputs) if f.name != "observation"},
        )
        light = dataclasses.replace(rollout, inputs=inputs)
        stacked = zip_trees([light], lambda leaves: torch.stack(self.gather(leaves[0])))
        shards = [zip_trees([stacked], lambda leaves, r=r: leaves[0][r]) for r in range(self.size)]
        return merge_environments(shards)

    def all(self, flag: bool) -> bool:
        """Whether `flag` holds on every rank (so all go on, or all stop, together)."""
        return not int(self.sum(torch.tensor(int(not flag))))

    def broadcast(self, module: nn.Module) -> None:
        """Give every rank rank 0's parameters and buffers."""
        if self.size > 1:
            for tensor in module.state_dict().values():
                dist.broadcast(tensor, 0)

    def own(self, worker: str) -> bool:
        """Whether this rank learns from rollout worker `worker` (a number): workers are
        sharded by id modulo the ranks."""
        return worker.isdigit() and int(worker) % self.size == self.rank


ONE = Ranks()
"""The single learner process."""


def from_environment() -> Ranks:
    """This process's ranks from torchrun's variables (`RANK`, `WORLD_SIZE`, `MASTER_ADDR`,
    `MASTER_PORT`), joining the process group (gloo); `ONE` without them."""
    size = int(os.environ.get("WORLD_SIZE", "1"))
    if size == 1:
        return ONE
    if not dist.is_initialized():
        dist.init_process_group("gloo", init_method="env://")
    return Ranks(dist.get_rank(), dist.get_world_size())
