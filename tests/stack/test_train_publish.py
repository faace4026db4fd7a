"""`hamnet trainer --inprocess --publish` as a process on real Zenoh: what a monitor and a policy service
of the same namespace receive from an in-process run (weights they can load, the schedule
counter, each iteration's metrics)."""

from __future__ import annotations

import time

from hamnet.policy.weights import from_bytes, sha256
from hamnet.proto.trainer_pb2 import Metrics, Schedule, WeightsAnnouncement
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.transport import TransportConfig, open_session
from hamnet.trainer.publisher import METRICS, SCHEDULE, WEIGHTS
from tests.conftest import transport_args

ITERATIONS = 6
B, T = 2, 2


def test_an_in_process_run_publishes_weights_counter_and_metrics(spawn, transport: TransportConfig, tmp_path) -> None:
    ns = transport.namespace
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("weights", WEIGHTS.key(ns), WeightsAnnouncement)
    inbox.subscribe("schedule", SCHEDULE.key(ns), Schedule)
    inbox.subscribe("metrics", METRICS.key(ns), Metrics)
    train = spawn(
        "trainer", "--inprocess", "--publish", "--sim.num-envs", str(B), "--sim.num-objects", "2", "--sim.nthread", "1",
        "--steps-per-rollout", str(T), "--max-env-transitions", str(ITERATIONS * B * T),
        "--eval-episodes", "0", "--run-dir", str(tmp_path), *transport_args(transport),
    )  # fmt: skip
    received: dict[str, list] = {"weights": [], "schedule": [], "metrics": []}
    deadline = time.monotonic() + 120
    try:
        while True:  # until the run has ended and nothing more arrives
            item = inbox.get(timeout=0.5)
            if item is not None:
                received[item.name].append(item.value)
            elif train.poll() is not None:
                break
            assert time.monotonic() < deadline, "the run did not end in time"
    finally:
        session.close()
    assert train.returncode == 0, train.stdout.read()
    counters = [message.env_transitions for message in received["schedule"]]
    assert counters and counters == sorted(counters) and counters[-1] == ITERATIONS * B * T
    last = received["metrics"][-1]
    assert last.iteration == ITERATIONS and {"approx_kl", "env_steps_per_s"} <= set(last.scalars)
    final = received["weights"][-1]
    assert final.version == ITERATIONS + 1 and final.sha256 == sha256(final.safetensors)
    weights = from_bytes(final.safetensors)
    assert weights.architecture == "hamnet" and weights.version == ITERATIONS + 1
