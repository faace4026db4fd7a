"""`hamnet policy` as a process on real Zenoh, with this test as sim, perception and trainer.

States and tokens stream with several steps in flight while the trainer's weights arrive
(three good versions and one corrupt announcement). Every step must be answered at most
once, versions must never go back, the corrupt version must never be served, and each
action must equal, to 1e-5, the core's action under the weights of the version it is
stamped with: a batch computed with mixed or other weights would not.

States and tokens travel on two topics, and Zenoh orders messages per publisher only: while
the peers' links settle, a step's tokens can arrive after the next step is complete, and the
policy then rightly serves the newer step and drops the older half (counted as superseded).
So a few steps may go unanswered; a policy that loses steps under load would miss many.
"""

from __future__ import annotations

import time

import numpy as np
import torch

from hamnet.policy.registry import build
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox, Publisher
from hamnet.runtime.transport import open_session
from tests.conftest import transport_args
from tests.policy.test_shell import B, expected
from tests.policy.wire import announcement, state_message, tokens_message

STEPS = 60
IN_FLIGHT = 4
RELOADS = {12: 1, 28: 2, 44: 3}
"""Step after which a weights version is announced."""
CORRUPT_AT, CORRUPT_VERSION = 20, 10
MAY_SKIP = 3
"""Steps that may be superseded (see the module docstring)."""


def test_hot_reload_under_load_serves_every_step_from_one_version(spawn, transport) -> None:
    process = spawn("policy", "--random-init", "hamnet", "--deterministic",
                    *transport_args(transport))  # fmt: skip
    ns, w = transport.namespace, "0"
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("action", contract.topic("policy/<w>/action").key(ns, w=w), PolicyAction, finite=False)
    state = Publisher(session, contract.topic("sim/<w>/state").key(ns, w=w), "sim/0")
    tokens = Publisher(session, contract.topic("perception/<w>/tokens").key(ns, w=w), "perception/0")
    weights = Publisher(session, contract.topic("trainer/weights").key(ns), "trainer/0")
    models = {0: build("hamnet", seed=0), **{v: build("hamnet", seed=v) for v in RELOADS.values()}}
    answers: dict[int, list[PolicyAction]] = {}

    def send(step: int) -> None:
        state.put(state_message(step, B))
        tokens.put(tokens_message(step, B))

    def collect(timeout: float) -> None:
        received = inbox.get(timeout=timeout)
        if received is not None:
            answers.setdefault(received.value.header.step, []).append(received.value)

    try:
        deadline = time.monotonic() + 30
        while 0 not in answers:  # until the policy is up and subscribed
            assert process.poll() is None and time.monotonic() < deadline, process.stdout.read()
            send(0)
            collect(0.5)
        sent = 0
        while max(answers) < STEPS:
            assert time.monotonic() < deadline + 30, f"answered {sorted(answers)}"
            while sent < STEPS and sent - max(answers) < IN_FLIGHT:
                sent += 1
                send(sent)
                if sent in RELOADS:
                    weights.put(announcement(models[RELOADS[sent]], RELOADS[sent]))
                if sent == CORRUPT_AT:
                    corrupt = announcement(models[1], CORRUPT_VERSION)
                    corrupt.safetensors = corrupt.safetensors[:-8] + b"\x00" * 8
                    weights.put(corrupt)
            collect(1.0)
    finally:
        inbox.close()
        session.close()
    served = sorted(answers)
    assert len(served) >= STEPS + 1 - MAY_SKIP, f"answered {served}"
    assert all(len(copies) == 1 for step, copies in answers.items() if step)
    versions = [answers[step][0].header.policy_version for step in served]
    assert versions == sorted(versions) and versions[-1] == 3 and CORRUPT_VERSION not in versions
    previous = None  # every step continues the episode of step 0: it follows the last served
    for step in served:
        message = answers[step][0]
        got = torch.from_numpy(np.frombuffer(message.action.data, np.float32).reshape(B, 21).copy())
        want = expected(models[message.header.policy_version], step, previous=previous)
        torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)
        previous = got
