"""The learner on two gloo ranks (two CPU processes on loopback) gives the update and the
running statistics of one learner of the whole batch."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
import torch
import torch.distributed as dist
import torch.multiprocessing as mp

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import NetworkInputs
from hamnet.policy.rollout_record import Rollout, merge_environments
from hamnet.trainer import cli
from hamnet.trainer.algorithms.ppo import Batch, UpdateStats, update
from hamnet.trainer.config import AUTHORS
from hamnet.trainer.runners.ranks import ONE, Ranks
from tests.trainer.test_ppo import TinyActorCritic

N, SIZE = 256, 2
"""Samples of the batch; ranks."""
CONFIG = dataclasses.replace(AUTHORS, lr=4e-3, kl_stop="rollback")
"""The authors' update with a rate at which the policy moves enough to raise the rate and
stop early (one minibatch: a single learner's permutation is not the ranks' union of
theirs), its step past the bound undone."""


def fixed_batch() -> Batch:
    """N samples of the tiny bandit, the old log-probs a little off the model's."""
    generator = torch.Generator().manual_seed(3)
    states, actions = torch.rand(N, 2, generator=generator), torch.rand(N, 2, generator=generator)
    advantages = torch.randn(N, 2, generator=generator) + torch.tensor([0.5, -0.2])
    returns = torch.randn(N, 2, generator=generator)
    with torch.no_grad():
        old = fresh_model().evaluate(states, actions).log_prob
    return Batch(states, actions, old + 0.05 * torch.randn(N, generator=generator),
                 advantages, returns)  # fmt: skip


def fresh_model() -> TinyActorCritic:
    torch.manual_seed(0)
    return TinyActorCritic()


def learn(batch: Batch, ranks: Ranks) -> tuple[list[torch.Tensor], UpdateStats]:
    """One full update (every epoch) of a fresh model on `batch`; its parameters and stats."""
    model = fresh_model()
    optimizer = torch.optim.Adam(model.parameters(), lr=CONFIG.lr)
    bounds = (-torch.full((2,), 0.6), torch.full((2,), 0.6))  # the bound loss is active too
    stats = update(model.evaluate, model.parameters(), optimizer, batch, bounds, CONFIG,
                   ranks=ranks)  # fmt: skip
    return [p.detach().clone() for p in model.parameters()], stats


def shard(batch: Batch, rank: int) -> Batch:
    """Rank `rank`'s rows: its half of the batch, unequal halves (the weighting counts)."""
    cut = N // 2 + 16
    rows = slice(0, cut) if rank == 0 else slice(cut, N)
    tensors = {f.name: getattr(batch, f.name) for f in dataclasses.fields(Batch)}
    return dataclasses.replace(batch, **{name: value[rows] for name, value in tensors.items()
                                         if isinstance(value, torch.Tensor)})  # fmt: skip


def tiny_rollout(rank: int, steps: int = 3, envs: int = 2) -> Rollout:
    """A rollout of `envs` environments whose every number says its rank, step and env (a
    guided run's: the scripted pusher's actions travel too)."""
    generator = torch.Generator().manual_seed(rank)
    field = lambda *shape: torch.randn(*shape, generator=generator)
    observation = NetworkInputs(
        *(field(steps * envs, 3) for _ in dataclasses.fields(NetworkInputs))
    )
    return Rollout(
        PolicyInputs(observation, field(steps * envs, 4, 5)), field(steps, envs, 2),
        field(steps, envs), field(steps, envs, 2), field(steps, envs, 2), field(steps, envs, 2),
        field(steps, envs) > 0, field(envs, 2), field(steps, envs) > 1, field(steps, envs, 2),
    )  # fmt: skip


def rank_main(rank: int, init: str, out: Path) -> None:
    """One rank: its shard's update and the environments of every rank, saved to `out`."""
    dist.init_process_group("gloo", init_method=init, rank=rank, world_size=SIZE)
    try:
        ranks = Ranks(rank, SIZE)
        parameters, stats = learn(shard(fixed_batch(), rank), ranks)
        joined = ranks.environments(tiny_rollout(rank))
        result = {"parameters": parameters, "stats": dataclasses.asdict(stats), "joined": joined}
        torch.save(result, out / f"rank{rank}.pt")
    finally:
        dist.destroy_process_group()


@pytest.fixture(scope="module")
def two_ranks(tmp_path_factory: pytest.TempPathFactory) -> list[dict]:
    """What each of two spawned gloo ranks computed."""
    out = tmp_path_factory.mktemp("ranks")
    mp.spawn(rank_main, args=(f"file://{out / 'rendezvous'}", out), nprocs=SIZE)
    return [torch.load(out / f"rank{rank}.pt", weights_only=False) for rank in range(SIZE)]


def test_two_ranks_make_the_update_of_one_on_the_whole_batch(two_ranks: list[dict]) -> None:
    """Same parameters after all epochs (within float rounding) on both ranks, and the same
    decisions: gradient steps, early stop, the adapted rate, the KL they rest on."""
    parameters, stats = learn(fixed_batch(), ONE)
    assert stats.early_stopped and 1 < stats.gradient_steps < CONFIG.epochs  # decisions matter
    assert stats.learning_rate != CONFIG.lr
    for result in two_ranks:
        for alone, ranked in zip(parameters, result["parameters"], strict=True):
            torch.testing.assert_close(ranked, alone, rtol=1e-5, atol=1e-6)
        ranked = result["stats"]
        assert ranked["gradient_steps"] == stats.gradient_steps
        assert ranked["early_stopped"] == stats.early_stopped
        assert ranked["learning_rate"] == pytest.approx(stats.learning_rate, rel=1e-9)
        for name in ("approx_kl", "clip_fraction", "policy_loss", "value_loss", "bound_loss"):
            assert ranked[name] == pytest.approx(getattr(stats, name), rel=1e-4, abs=1e-7)
    for first, second in zip(*(r["parameters"] for r in two_ranks), strict=True):
        assert torch.equal(first, second)  # the ranks never drift apart


def test_every_rank_sees_every_environment_side_by_side(two_ranks: list[dict]) -> None:
    """The scaler, tracker and input statistics see what one learner of all the environments
    would: the ranks' rollouts merged in rank order (observations only of the inputs)."""
    whole = merge_environments([tiny_rollout(rank) for rank in range(SIZE)])
    for result in two_ranks:
        joined = result["joined"]
        for f in dataclasses.fields(Rollout):
            if f.name != "inputs":
                assert torch.equal(getattr(joined, f.name), getattr(whole, f.name)), f.name
        for f in dataclasses.fields(NetworkInputs):
            expected = getattr(whole.inputs.observation, f.name)
            assert torch.equal(getattr(joined.inputs.observation, f.name), expected)
        assert joined.inputs.object_tokens is None


def test_one_rank_is_the_plain_update() -> None:
    """`ONE` changes nothing: the same update bit for bit as without ranks."""
    batch, model = fixed_batch(), fresh_model()
    optimizer = torch.optim.Adam(model.parameters(), lr=CONFIG.lr)
    bounds = (-torch.full((2,), 0.6), torch.full((2,), 0.6))
    stats = update(model.evaluate, model.parameters(), optimizer, batch, bounds, CONFIG)
    parameters, ranked = learn(batch, ONE)
    assert all(torch.equal(a, b) for a, b in zip(model.parameters(), parameters, strict=True))
    assert stats == ranked and not math.isnan(stats.approx_kl)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--ranks", "2", "--inprocess"], "needs PPO without --inprocess"),
        (["--ranks", "2", "--workers", "3"], "must be a multiple of --ranks 2"),
        (["--ranks", "0"], "--ranks must be >= 1"),
    ],
)
def test_ranks_that_cannot_shard_the_workers_are_one_line(
    args: list[str], says: str, capsys
) -> None:
    with pytest.raises(SystemExit) as stopped:
        cli.main(args)
    err = capsys.readouterr().err
    assert stopped.value.code == 2 and says in err and len(err.strip().splitlines()) == 1
