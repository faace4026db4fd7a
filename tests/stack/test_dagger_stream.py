"""`hamnet trainer --algo dagger` with `hamnet rollout --algo dagger` workers as processes on
real Zenoh: the streamed run learns what the in-process DAgger run learns (same seed, same
teacher), the worker's student acts with each new version, and a worker distilling another
teacher is refused, its chunks dropped and counted.

As for PPO (tests/stack/test_trainer_stream.py), the first update is compared bit for bit;
later ones may differ in the last bits (equal tensors in differently placed memory sum in
another order, and Adam carries that on), so they are compared by what they learned from.
The teachers are freshly initialised HAMnets: the machinery is checked, not a distillation."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

from hamnet.policy.registry import build
from hamnet.policy.weights import save_checkpoint
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.transport import TransportConfig, open_session
from hamnet.trainer.algorithms.teacher import load_teacher
from hamnet.trainer.storage.demonstration_chunks import DEMONSTRATIONS
from tests.conftest import transport_args
from tests.stack.test_trainer_stream import finish, rows

B, T, ITERATIONS = 2, 2, 3
RUN = ["--algo", "dagger", "--sim.num-envs", str(B), "--sim.num-objects", "2", "--sim.nthread",
       "1", "--steps-per-rollout", str(T), "--random-encoder", "--dagger.beta-initial", "0.5",
       "--dagger.beta-final", "0.5"]  # fmt: skip
"""Flags the trainer and its workers share (but the teacher); beta 0.5, so the worker's
student acts some episodes with the announced weights and the teacher the others."""
COMPARED = ("env_transitions", "beta", "student_share", "imitation_loss", "imitation_loss_after",
            "value_loss", "gradient_norm")  # fmt: skip
"""Metrics that depend only on what was collected and learned (not on timing)."""


def wait_for_line(process: subprocess.Popen, text: str, timeout: float = 120) -> None:
    """Read `process`'s output until a line holds `text` (it keeps running)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.stdout.read()
        line = process.stdout.readline()
        if text in line:
            return
    raise AssertionError(f"no line with {text!r} within {timeout} s")


def test_a_streamed_dagger_run_equals_the_in_process_one_and_refuses_another_teacher(
    spawn, transport: TransportConfig, tmp_path: Path
) -> None:
    teacher, other = tmp_path / "teacher.safetensors", tmp_path / "other.safetensors"
    save_checkpoint(teacher, build("hamnet", seed=1), 7)
    save_checkpoint(other, build("hamnet", seed=2), 7)
    run = [*RUN, "--max-env-transitions", str(ITERATIONS * B * T), "--eval-episodes", "0"]
    net = transport_args(transport)
    inprocess = spawn("trainer", *run, "--teacher", str(teacher), "--inprocess",
                      "--run-dir", str(tmp_path / "inprocess"))  # fmt: skip
    streamed = spawn("trainer", *run, "--teacher", str(teacher), "--workers", "1",
                     "--run-dir", str(tmp_path / "streamed"), *net)  # fmt: skip
    session = open_session(transport)
    try:
        inbox = Inbox(session, DropCounter())
        inbox.subscribe("demos", DEMONSTRATIONS.pattern_in(transport.namespace), RolloutChunk,
                        finite=False)  # fmt: skip
        spawn("rollout", "--worker", "1", *RUN, "--teacher", str(other), *net)
        wait_for_line(streamed, "trainer/1/demonstrations (teacher)")  # refused, logged
        worker = spawn("rollout", "--worker", "0", *RUN, "--teacher", str(teacher), *net)
        finish(streamed)
        finish(inprocess)
        chunks: dict[str, list[RolloutChunk]] = {"0": [], "1": []}
        while (received := inbox.get(timeout=1.0)) is not None:
            chunks[received.key.split("/")[-2]].append(received.value)
    finally:
        session.close()
    got, want = rows(tmp_path / "streamed"), rows(tmp_path / "inprocess")
    assert len(got) == len(want) == ITERATIONS
    assert {k: got[0][k] for k in COMPARED} == {k: want[0][k] for k in COMPARED}
    assert 0 < got[0]["student_share"] < 1  # seeded coins: both acted
    for a, b in zip(got, want, strict=True):  # later updates: the same data, rounding apart
        assert a["env_transitions"] == b["env_transitions"] and a["beta"] == b["beta"]
        assert a["policy_lag"] == 0 and a["dropped_rollouts"] >= 1  # worker 1's, refused
    assert [c.header.policy_version for c in chunks["0"][:ITERATIONS]] == [1, 2, 3]
    assert {c.teacher_sha256 for c in chunks["0"]} == {load_teacher(teacher).sha256}
    assert chunks["1"] and {c.teacher_sha256 for c in chunks["1"]} == {load_teacher(other).sha256}
    assert worker.poll() is None, "the worker keeps waiting for the next trainer"
