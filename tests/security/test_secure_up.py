"""The secure stack end to end under `hamnet up`, and the attacks of issue 16 against its
running services.

compose/secure/stack.yaml, made small (the control loop: sim, perception, policy on random
weights, safety) and put on a free port: `hamnet certs stack` makes its certificates,
`hamnet up` starts its router (mutual TLS, the access rules) and every service as a client
under its own certificate. While it runs, an `intruder` (a certificate of the same CA, the
wrong name) tries to drive joint 1 past its limit and announces weights of version 10^18;
the test plays the trainer's identity for the legitimate next version. Without the access
rules (an empty router config) both attacks succeed: joint 1 reached 2.912 rad and the
trainer's version was refused. Once the loop turned, the stack is stopped and its summary
read. Every wait is on a condition, with generous deadlines."""

from __future__ import annotations

import os
import signal
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml
import zenoh

from hamnet.fr3.limits import FR3
from hamnet.launcher.certs_cli import main as certs
from hamnet.policy.registry import build
from hamnet.proto.common_pb2 import Header
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafeCommand
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.codec import decode, encode
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.runtime.transport import TransportConfig, free_port
from hamnet.security.certs import issue
from hamnet.sim.config import SimConfig
from tests.policy.wire import announcement
from tests.security.clients import Running
from tests.stack.up import up

SECURE = Path(__file__).resolve().parents[2] / "compose" / "secure"
NUM_ENVS = 2
SERVICES = {
    "sim": {"args": {"num-envs": NUM_ENVS, "report-period-s": 5}},
    "perception": {"args": {"report-period-s": 5}},
    "policy": {"args": {"random-init": "hamnet"}},
    "safety": {},
}
"""The control loop of compose/secure/stack.yaml (its trainer, rollout worker and monitor
are left out: the test plays the trainer)."""

FORGED_VERSION = 10**18


@pytest.fixture(scope="module")
def stack(tmp_path_factory) -> Iterator[Running]:
    folder = tmp_path_factory.mktemp("secure-up")
    endpoint = f"tls/127.0.0.1:{free_port()}"
    document = yaml.safe_load((SECURE / "stack.yaml").read_text())
    document["secure"].update(tls_dir=str(folder / "certs"), access=str(SECURE / "router.json5"),
                              listen=endpoint)  # fmt: skip
    document.update(services=SERVICES, duration_s=300)  # a bound; the last test stops it
    path = folder / "stack.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    assert certs(["stack", str(path)]) == 0
    for name in ("intruder", "monitor", "trainer"):  # the test reads as monitor, plays the trainer
        issue(folder / "certs", name, days=1)
    namespace = f"secure{uuid.uuid4().hex[:8]}"
    with up(path, TransportConfig(namespace=namespace), cwd=folder) as run:
        running = Running(run, folder / "certs", namespace, endpoint)
        try:
            yield running
        finally:
            running.close()


def test_an_intruder_cannot_drive_joint_1_past_its_limit(stack: Running) -> None:
    """Before: an intruder's SafeCommands for the sim's current step were executed; joint
    1 reached 2.927 rad (limit 2.9007). Now, for every state it sees, the intruder answers
    at once with a command towards 3.5 rad at full stiffness; the router drops them, the
    sim keeps stepping on safety's commands and joint 1 stays within its limits."""
    states = stack.collect("sim/<w>/state", RobotState)
    intruder = stack.client("intruder")
    samples = SimConfig().control_samples
    forged = 0

    def attack(sample) -> None:
        nonlocal forged
        state = decode(RobotState, sample.payload.to_bytes())
        q = from_tensor(state.q, np.float32, (NUM_ENVS, 7))
        q_ref = np.repeat(q[:, None, :], samples, axis=1)
        q_ref[:, :, 0] = 3.5
        command = SafeCommand(header=Header(step=state.header.step, run=state.header.run))
        to_tensor(q_ref.astype(np.float32), command.q_ref)
        to_tensor(np.full((NUM_ENVS, 7), 600.0, np.float32), command.kp)
        to_tensor(np.full((NUM_ENVS, 7), 50.0, np.float32), command.kd)
        to_tensor(np.tile(FR3.tau_max, (NUM_ENVS, 1)).astype(np.float32), command.tau_limit)
        intruder.put(stack.key("safety/<w>/command"), encode(command))
        forged += 1

    # The intruder may not even subscribe: a member's session shows it the states.
    stack.client("monitor").declare_subscriber(stack.key("sim/<w>/state"), attack)
    stack.wait(lambda: forged >= 200, "200 forged commands sent")
    first = min(s.header.step for s in states)
    stack.wait(lambda: max(s.header.step for s in states) >= first + 150, "150 sim steps")
    joint_1 = np.concatenate([from_tensor(s.q, np.float32, (NUM_ENVS, 7))[:, 0] for s in states])
    assert np.abs(joint_1).max() <= FR3.q_max[0], joint_1.max()


def test_forged_weights_are_never_served_and_the_trainer_is_still_heard(stack: Running) -> None:
    """Before: weights of version 10^18 from any peer were served, and the trainer's next
    version was refused as not newer. Now the intruder's announcement never reaches the
    policy (only the trainer's certificate may publish weights): it keeps serving version
    0, then serves the trainer's version 1."""
    actions = stack.collect("policy/<w>/action", PolicyAction)
    stack.wait(lambda: len(actions) >= 10, "the policy acts")
    forged = encode(announcement(build("hamnet", seed=1), FORGED_VERSION))
    genuine = encode(announcement(build("hamnet", seed=2), 1))
    intruder, trainer = stack.client("intruder"), stack.client("trainer")
    weights = stack.key("trainer/weights")
    stop = threading.Event()

    def keep_forging() -> None:
        while not stop.wait(0.5):
            intruder.put(weights, forged)

    forging = threading.Thread(target=keep_forging, daemon=True)
    forging.start()
    try:
        intruder.put(weights, forged)
        seen = len(actions)
        stack.wait(lambda: len(actions) >= seen + 100, "100 actions while the intruder forges")
        # blocking, as the trainer's publisher of this lossless topic does (contract.Topic)
        trainer.put(weights, genuine, congestion_control=zenoh.CongestionControl.BLOCK)
        stack.wait(lambda: actions[-1].header.policy_version == 1, "the trainer's version served")
        seen = len(actions)
        stack.wait(lambda: len(actions) >= seen + 20, "20 actions more")
    finally:
        stop.set()
        forging.join()
    versions = [a.header.policy_version for a in actions]
    assert FORGED_VERSION not in versions
    assert versions == sorted(versions) and set(versions) == {0, 1}


def test_the_secure_stack_closes_the_loop_and_says_it_is_secure(stack: Running) -> None:
    """Every service joined the router over TLS with its own certificate, the loop turned
    (the sim stepped on safety's commands), and the summary names TLS and the rules."""
    states = stack.collect("sim/<w>/state", RobotState)
    stack.wait(lambda: len({s.header.step for s in states}) >= 50, "50 sim steps")
    os.killpg(stack.run.process.pid, signal.SIGTERM)
    assert stack.run.wait(timeout=60) == 0, stack.run.output[-3000:]
    summary = stack.run.summary()
    assert summary["security"] == {"tls_dir": str(stack.certs),
                                   "access": str(SECURE / "router.json5"),
                                   "router": stack.endpoint}  # fmt: skip
    processes = {p["service"]: p for p in summary["processes"]}
    assert list(processes) == ["router", *SERVICES]
    assert all(p["announced"] >= 1 and p["restarts"] == 0 for p in processes.values()), processes
    sim = processes["sim"]
    steps = sim["published"][stack.key("sim/<w>/transition")]
    assert steps >= 50 and sim["received"]["command"] >= steps, sim
    assert processes["safety"]["published"][stack.key("safety/<w>/command")] >= steps
    said = [line for line in stack.run.lines if "secure: mutual TLS (certificates in" in line]
    assert len(said) == 2, said  # when it starts (log) and in the summary
