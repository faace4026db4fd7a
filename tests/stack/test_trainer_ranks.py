"""`hamnet trainer --ranks 2` on real Zenoh with two `hamnet rollout` workers: each learner
rank takes one worker's chunks, and the run learns what one learner of both workers learns
from the same rollouts (the first update to float rounding; the data of later ones follows
weights that differ by rounding). Only rank 0 writes metrics and checkpoints."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest

from hamnet.runtime.transport import TransportConfig
from tests.conftest import transport_args
from tests.stack.test_trainer_stream import COMPARED, ITERATIONS, RUN, B, T, finish, rows, trainer


def run_with_fresh_workers(spawn, transport: TransportConfig, run_dir: Path, *extra: str) -> None:
    """Workers 0 and 1 from their first step, a trainer of both until it ends, workers gone."""
    workers = [spawn("rollout", "--worker", w, *RUN, *transport_args(transport)) for w in "01"]
    finish(trainer(spawn, transport, run_dir, "--workers", "2",
                   "--max-env-transitions", str(ITERATIONS * 2 * B * T), *extra))  # fmt: skip
    for worker in workers:
        worker.send_signal(signal.SIGTERM)
        try:
            worker.wait(timeout=30)
        except subprocess.TimeoutExpired:
            worker.kill()


def test_two_learner_ranks_learn_what_one_learner_does(
    spawn, transport: TransportConfig, tmp_path
) -> None:
    # One minibatch: with several, each rank shuffles its own shard (docs/trainer.md). In
    # float32: under bfloat16 (the default update where the CPU has it) a shard's pass and
    # the whole batch's round differently at 8 bits, and the first update's KL differed by
    # 7e-4 of itself, where this test checks the ranks' arithmetic to float rounding.
    same = ("--ppo.minibatches", "1", "--ppo.precision", "float32")
    run_with_fresh_workers(spawn, transport, tmp_path / "ranks", "--ranks", "2", *same)
    run_with_fresh_workers(spawn, transport, tmp_path / "one", *same)
    ranked, one = rows(tmp_path / "ranks"), rows(tmp_path / "one")
    assert [r["env_transitions"] for r in ranked] == [
        2 * B * T * (i + 1) for i in range(ITERATIONS)
    ]
    assert [r["env_transitions"] for r in one] == [r["env_transitions"] for r in ranked]
    for name in COMPARED:  # the first update (the first iteration only fills the statistics)
        assert ranked[1][name] == pytest.approx(one[1][name], rel=1e-4, abs=1e-7), name
    assert all(row["policy_lag"] == 0 for row in ranked)
    assert (tmp_path / "ranks" / "checkpoints" / "latest.safetensors").exists()
