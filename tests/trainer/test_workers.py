"""The streamed trainer's view of its rollout workers (`Roster`), without Zenoh: whom an
iteration waits for, who drops out and rejoins, which learner rows their chunks fill, and the
reward scaler and episode tracker on a rollout of some environments only."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from hamnet.trainer.algorithms.normalization import ReturnScaler
from hamnet.trainer.collection.worker_roster import Roster
from hamnet.trainer.runners.episodes import EpisodeTracker
from hamnet.trainer.runners.progress import workers_part

E = 2
"""Environments per worker."""


def started(workers: int = 2, **kwargs) -> Roster:
    """A roster whose first iteration took one chunk of each worker 0..workers-1."""
    roster = Roster(workers, E, **kwargs)
    ids = {str(w) for w in range(workers)}
    for worker in sorted(ids):
        roster.token(f"rollout/{worker}", True)
        roster.arrived(worker, f"rollout/{worker}")
    roster.begin(0.0)
    assert roster.takes(ids, 0.0) == sorted(ids)
    return roster


def test_the_first_iteration_waits_for_every_worker_and_slots_them_by_id() -> None:
    roster = Roster(3, E)
    roster.begin(0.0)
    assert roster.takes({"2", "0"}, 0.0) is None
    assert roster.takes({"2", "0", "1"}, 0.0) == ["0", "1", "2"]
    assert roster.rows(["0", "1", "2"]) is None  # all of them, in order


def test_a_worker_whose_token_goes_away_drops_out_and_the_others_are_learned_from() -> None:
    roster = started()
    roster.begin(1.0)
    assert roster.takes({"1"}, 1.0) is None  # worker 0 is still waited for
    roster.token("rollout/0", False)
    assert roster.takes({"1"}, 1.0) == ["1"]
    assert roster.rows(["1"]).tolist() == [2, 3]  # worker 1's environments keep their rows
    metrics = roster.metrics()
    assert metrics["dropped_partial_rollouts"] == 1 and metrics["workers_alive"] == 1
    assert metrics["workers/0/dropped_partial_rollouts"] == 1 and metrics["workers/0/alive"] == 0


def test_a_worker_that_comes_back_is_waited_for_from_the_next_iteration() -> None:
    roster = started()
    roster.token("rollout/0", False)
    roster.begin(1.0)
    assert roster.takes({"1"}, 1.0) == ["1"]  # gone at the start: not waited for, not dropped
    roster.token("rollout/0", True)
    roster.begin(2.0)
    assert roster.takes({"1"}, 2.0) is None
    assert roster.takes({"0", "1"}, 2.0) == ["0", "1"]
    assert roster.dropped_partial == 0


def test_a_chunk_queued_before_the_token_went_away_is_still_learned_from() -> None:
    roster = started()
    roster.begin(1.0)
    roster.token("rollout/0", False)
    assert roster.takes({"0", "1"}, 1.0) == ["0", "1"]
    assert roster.dropped_partial == 0


def test_a_worker_silent_past_the_timeout_drops_out_though_its_token_stays() -> None:
    roster = started(timeout_s=5.0)
    roster.begin(10.0)
    assert roster.takes({"1"}, 14.0) is None
    assert roster.takes({"1"}, 15.0) == ["1"]
    assert roster.metrics()["workers/0/dropped_partial_rollouts"] == 1


def test_without_drop_out_every_worker_is_waited_for() -> None:
    """Several learner ranks need every batch whole: a gone worker is still waited for."""
    roster = started(drop_out=False, timeout_s=1.0)
    roster.token("rollout/0", False)
    roster.begin(1.0)
    assert roster.takes({"1"}, 100.0) is None
    assert roster.takes({"0", "1"}, 100.0) == ["0", "1"]


def test_when_every_worker_dropped_out_the_iteration_waits_for_whoever_comes_back() -> None:
    roster = started()
    roster.begin(1.0)
    roster.token("rollout/0", False)
    roster.token("rollout/1", False)
    assert roster.takes(set(), 1.0) is None
    assert roster.dropped_partial == 2
    roster.token("rollout/1", True)
    assert roster.takes(set(), 2.0) is None  # now waiting for worker 1
    assert roster.waiting == {"1"}
    assert roster.takes({"1"}, 3.0) == ["1"]


def test_the_liveliness_of_a_chain_source_is_its_policy_services() -> None:
    """The service chain sends worker 0's chunks from `policy/0`: the sim's `sim/0` token
    says nothing about it."""
    roster = Roster(1, E)
    roster.token("policy/0", True)
    roster.arrived("0", "policy/0")
    roster.begin(0.0)
    assert roster.takes({"0"}, 0.0) == ["0"]
    roster.token("sim/0", False)
    assert roster.is_alive("0")
    roster.token("policy/0", False)
    assert not roster.is_alive("0")


def test_metrics_and_progress_name_each_worker() -> None:
    roster = started()
    roster.begin(1.0)
    roster.token("rollout/1", False)
    assert roster.takes({"0"}, 1.0) == ["0"]
    roster.took("0", 1, 250.0)
    row = roster.metrics()
    assert row["workers/0/env_steps_per_s"] == 250.0 and row["workers/0/policy_lag"] == 1
    assert "workers/1/env_steps_per_s" not in row and row["workers/0/chunks"] == 1
    assert workers_part(row) == " | workers 1/2 up (0:250 1:x steps/s), 1 partial dropped"
    assert workers_part({"iteration": 1}) == ""


def test_the_scaler_on_some_environments_leaves_the_others_alone() -> None:
    """Scaling rows [2, 3] of four environments is scaling those two: the others' running
    returns stay, the statistics see only the rows given."""
    rewards = torch.tensor([[1.0, 0.5], [2.0, 0.0]])  # (B, R) of environments 2 and 3
    dones = torch.tensor([False, True])
    whole, part = ReturnScaler(4, 0.9), ReturnScaler(2, 0.9)
    whole.returns[:] = torch.tensor([5.0, 6.0, 1.0, 1.0], dtype=torch.float64)
    part.returns[:] = torch.tensor([1.0, 1.0], dtype=torch.float64)
    scaled = whole.scale(rewards, dones, torch.tensor([2, 3]))
    assert torch.equal(scaled, part.scale(rewards, dones))
    assert whole.returns.tolist() == [5.0, 6.0, 2.4, 0.0]
    assert float(whole.stats.mean) == pytest.approx(float(part.stats.mean))


def test_the_tracker_on_some_environments_ends_their_own_episodes() -> None:
    tracker = EpisodeTracker(4, 1)
    tracker.returns[:] = [[10.0], [20.0], [30.0], [40.0]]
    tracker.lengths[:] = 3
    rollout = SimpleNamespace(  # what the tracker reads of a Rollout: one step of envs 3 and 1
        rewards=torch.ones(1, 2, 1), dones=torch.tensor([[True, False]]),
        success=torch.tensor([[True, False]]),
    )  # fmt: skip
    tracker.add(rollout, torch.tensor([3, 1]))
    (returns, length, success), *_ = tracker.finished
    assert returns.tolist() == [41.0] and (length, success) == (4, True)
    assert tracker.returns[:, 0].tolist() == [10.0, 21.0, 30.0, 0.0]
    assert tracker.lengths.tolist() == [3, 4, 3, 0]
