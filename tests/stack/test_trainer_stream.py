"""`hamnet trainer` with `hamnet rollout` workers as processes on real Zenoh: the streamed
run learns what the in-process run learns (same seeds, same weights, the same rollouts),
and two workers make one update of both workers' environments.

The first update is bit-for-bit the same; later ones differ by float rounding only: the two
processes learn from equal tensors in differently placed memory, and the CPU kernels'
summation order follows the placement (Adam then carries the last-bit differences on, by
more than 1% in some runs), so later updates are compared by what they learned from."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from hamnet.policy.registry import build
from hamnet.proto.health_pb2 import Health
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.service import HEALTH
from hamnet.runtime.transport import TransportConfig, open_session
from hamnet.trainer.collection.streamed import ROLLOUT
from hamnet.trainer.publisher import WEIGHTS, encode_weights
from tests.conftest import transport_args

B, T, ITERATIONS = 2, 2, 3
RUN = [
    "--sim.num-envs",
    str(B),
    "--sim.num-objects",
    "2",
    "--sim.nthread",
    "1",
    "--steps-per-rollout",
    str(T),
]
"""Flags the trainer and its workers share."""
COMPARED = (
    "env_transitions",
    "approx_kl",
    "clip_fraction",
    "learning_rate",
    "policy_loss",
    "value_loss",
    "log_std",
)
"""Metrics that depend only on what was collected and learned (not on timing)."""


def rows(run_dir: Path) -> list[dict]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


def finish(process: subprocess.Popen, timeout: float = 150) -> None:
    """Wait for `process` to exit with status 0; past `timeout` kill it (and the ranks it
    started) and fail with what it printed."""
    try:
        process.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        pytest.fail(f"the run did not end in {timeout:.0f} s:\n{process.stdout.read()}")
    assert process.returncode == 0, process.stdout.read()


def trainer(spawn, transport: TransportConfig, run_dir: Path, *extra: str) -> subprocess.Popen:
    return spawn("trainer", *RUN, "--max-env-transitions", str(ITERATIONS * B * T), "--eval-episodes", "0",
                 "--run-dir", str(run_dir), *extra, *transport_args(transport))  # fmt: skip


def test_a_streamed_run_equals_the_in_process_run(
    spawn, transport: TransportConfig, tmp_path
) -> None:
    workers = [spawn("rollout", "--worker", "0", *RUN, *transport_args(transport))]
    finish(trainer(spawn, transport, tmp_path / "streamed", "--workers", "1"))
    finish(trainer(spawn, transport, tmp_path / "inprocess", "--inprocess"))
    streamed, inprocess = rows(tmp_path / "streamed"), rows(tmp_path / "inprocess")
    assert len(streamed) == len(inprocess) == ITERATIONS
    assert streamed[0]["gradient_steps"] == inprocess[0]["gradient_steps"] == 0  # statistics only
    first = 1  # the first update
    assert {k: streamed[first][k] for k in COMPARED} == {k: inprocess[first][k] for k in COMPARED}
    for a, b in zip(
        streamed, inprocess, strict=True
    ):  # later updates: the same data, rounding apart
        assert a["env_transitions"] == b["env_transitions"]
        assert a["policy_lag"] == 0 and a["dropped_rollouts"] == 0
    assert workers[0].poll() is None, "the worker keeps waiting for the next trainer"


def test_two_workers_make_one_update_of_both_environments(
    spawn, transport: TransportConfig, tmp_path
) -> None:
    """The workers are not told the rollout length (on their own they would act 8192 / B
    steps): they act the T the trainer's announcements ask for."""
    own = RUN[: RUN.index("--steps-per-rollout")]
    for worker in ("0", "1"):
        spawn("rollout", "--worker", worker, *own, *transport_args(transport))
    finish(
        trainer(
            spawn,
            transport,
            tmp_path,
            "--workers",
            "2",
            "--max-env-transitions",
            str(ITERATIONS * 2 * B * T),
        )
    )
    metrics = rows(tmp_path)
    assert [row["env_transitions"] for row in metrics] == [
        2 * B * T * (i + 1) for i in range(ITERATIONS)
    ]
    assert all(row["policy_lag"] == 0 for row in metrics)


def test_a_worker_holds_its_chunk_until_a_learner_subscribes(
    spawn, transport: TransportConfig
) -> None:
    """A chunk put before any learner subscribes would reach no one, and a synchronous worker
    would then wait for new weights forever: the worker holds it (counted in its Health) and
    sends it once a subscriber appears. Here the test announces the weights and subscribes
    only after the worker reports the hold."""
    worker = spawn("rollout", "--worker", "0", *RUN, *transport_args(transport))
    ns = transport.namespace
    session = open_session(transport)
    try:
        health = Inbox(session, DropCounter())
        health.subscribe("health", HEALTH.key(ns, service="rollout", w="0"), Health)
        weights = Publisher(session, WEIGHTS.key(ns), "trainer/0")
        announcement = encode_weights(build("hamnet", seed=0), 1, 0)
        deadline = time.monotonic() + 90
        while True:
            assert worker.poll() is None, worker.stdout.read()
            assert time.monotonic() < deadline, "the worker never held a chunk"
            weights.put(announcement)
            report = health.get(timeout=0.5)
            if report is not None and report.value.events["chunks_held_for_a_learner"]:
                break
        chunks = Inbox(session, DropCounter())
        chunks.subscribe("rollout", ROLLOUT.key(ns, w="0"), RolloutChunk)
        chunk = chunks.get(timeout=30)
    finally:
        session.close()
    assert chunk is not None and chunk.value.header.policy_version == 1

