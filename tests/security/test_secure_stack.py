"""The four attacks of issue 16 against the secure stack (real Zenoh, loopback): one
`hamnet router` with mutual TLS and the access rules of `hamnet.security.acl`, every
party a client of it under its own certificate.

Each test lets the legitimate sender and the attacker publish side by side, waits (with a
generous deadline) until the legitimate message has arrived, then checks that nothing of
the attacker's did, and that the router's log names the refusal."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafeCommand
from hamnet.proto.trainer_pb2 import Schedule, WeightsAnnouncement
from hamnet.runtime.codec import encode
from hamnet.runtime.transport import TransportConfig, free_port, zenoh_config
from hamnet.security.acl import router_config_text, stack_acl
from tests.estop import ask_estop
from tests.messages import random_message
from tests.security.clients import Clients

DEADLINE_S = 40.0
"""Generous bound for anything to arrive (the machine is shared with training runs)."""

DENIED = "CertCommonName({who})+Transport(Tls)+{zid} is unauthorized to {what} (ingress) on {key}"
"""How Zenoh's access control logs a refused message of an identity of the stack (trace)."""

STRANGER = "{zid} did not match any configured ACL subject"
"""How it logs a link whose certificate names no identity of the stack (info, once): all
its messages are refused."""


def refusal(who: str, session: zenoh.Session, what: str, key: str) -> str:
    """The router's log line that shows `who`'s message refused."""
    if any(who in subject["cert_common_names"] for subject in stack_acl()["subjects"]):
        return DENIED.format(who=who, zid=session.info.zid(), what=what, key=key)
    return STRANGER.format(zid=session.info.zid())


class Stack(Clients):
    """A secure router on a free tls/ port, and clients of it under given identities."""

    def __init__(self, certs: Path, tmp_path: Path) -> None:
        super().__init__(certs, f"secure{uuid.uuid4().hex[:8]}", f"tls/127.0.0.1:{free_port()}")
        config = tmp_path / "router.json5"
        config.write_text(router_config_text())
        self.log = tmp_path / "router.log"
        self.processes: list[subprocess.Popen] = []
        self.spawn("router", "--tls-dir", str(certs), "--listen", self.endpoint,
                   "--zenoh-config", str(config),
                   "--zenoh-log", "warn,zenoh::net::routing::interceptor::access_control=trace")  # fmt: skip

    def spawn(self, command: str, *args: str) -> subprocess.Popen:
        """Start `hamnet <command>`; the router's output goes to `self.log` (a file: its
        trace log would fill a pipe), a service's to a file next to it."""
        log = self.log if command == "router" else self.log.with_name(f"{command}.log")
        client = () if command == "router" else ("--mode", "client", "--rendezvous", "",
                                                 "--connect", self.endpoint,
                                                 "--tls-dir", str(self.certs))  # fmt: skip
        with log.open("w") as out:
            process = subprocess.Popen(
                [sys.executable, "-m", "hamnet", command, "--namespace", self.namespace,
                 *client, *args], stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                env={**os.environ, "PYTHONUNBUFFERED": "1"})  # fmt: skip
        self.processes.append(process)
        return process

    def wait_log(self, text: str) -> None:
        """Wait until the router's log holds `text`."""
        deadline = time.monotonic() + DEADLINE_S
        while text not in self.log.read_text():
            assert self.processes[0].poll() is None, self.log.read_text()[-2000:]
            assert time.monotonic() < deadline, f"router log never showed: {text}"
            time.sleep(0.2)

    def close(self) -> None:
        super().close()
        for process in self.processes:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in self.processes:
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()


@pytest.fixture
def stack(certs: Path, tmp_path: Path) -> Iterator[Stack]:
    secure = Stack(certs, tmp_path)
    yield secure
    secure.close()


def race(stack: Stack, path: str, owner: str, reader: str, make: Callable[[int], bytes],
         attacker: str = "intruder") -> None:  # fmt: skip
    """`attacker` and `owner` both publish on `path`; `reader` must get only the owner's."""
    key = stack.key(path)
    received: list[bytes] = []
    stack.client(reader).declare_subscriber(key, lambda s: received.append(s.payload.to_bytes()))
    intruder, legitimate = stack.client(attacker), stack.client(owner)
    attack, genuine = make(1), make(2)
    deadline = time.monotonic() + DEADLINE_S
    while genuine not in received:
        assert time.monotonic() < deadline, f"{owner}'s message on {key} never arrived"
        intruder.put(key, attack)
        legitimate.put(key, genuine)
        time.sleep(0.1)
    intruder.put(key, attack)
    legitimate.put(key, genuine)  # delivered after the attack that precedes it, if any
    while received.count(genuine) < 2:
        assert time.monotonic() < deadline, f"{owner}'s second message never arrived"
        time.sleep(0.05)
    assert attack not in received
    stack.wait_log(refusal(attacker, intruder, "Put", key))


@pytest.mark.parametrize("attacker", ["intruder", "rollout"])
def test_only_the_safety_identity_can_command_the_robot(stack: Stack, attacker: str) -> None:
    """Before: any peer's SafeCommand reached the sim, which drove joint 1 past its limit.
    Now the router drops the commands of a certificate under another name (`intruder`,
    which gets nothing at all) or of another service of the stack (`rollout`, compromised);
    the sim's session gets safety's only."""
    race(stack, "safety/<w>/command", owner="safety", reader="sim", attacker=attacker,
         make=lambda seed: encode(random_message(SafeCommand, seed=seed)))  # fmt: skip


def test_only_the_trainer_can_publish_weights_and_the_step_counter(stack: Stack) -> None:
    """Before: weights with version 10^18 from any peer were served by the policy, which
    then refused the trainer's next version. Now only the trainer's reach the policy."""
    race(stack, "trainer/weights", owner="trainer", reader="policy",
         make=lambda seed: encode(random_message(WeightsAnnouncement, seed=seed)))  # fmt: skip


def test_only_the_operator_can_release_a_latched_estop(stack: Stack) -> None:
    """Before: any peer released an operator's latched e-stop with `reset`. Against a real
    `hamnet safety`, the operator's stop latches, the intruder's reset gets no answer (the
    router drops the query) and the latch holds; the operator can still release it."""
    stack.spawn("safety", "--num-envs", "2")
    key = stack.key("safety/<w>/estop")
    operator, intruder = stack.client("operator"), stack.client("intruder")
    assert ask_estop(operator, key, "stop", DEADLINE_S)["latched"] is True
    assert list(intruder.get(f"{key}?reset", timeout=2.0)) == []
    stack.wait_log(refusal("intruder", intruder, "Query", key))
    assert ask_estop(operator, key, "status")["latched"] is True
    assert ask_estop(operator, key, "reset")["latched"] is False


def test_a_peer_without_a_valid_certificate_cannot_connect(stack: Stack, stranger: Path) -> None:
    """A certificate from another CA (its holder even trusts ours) gets no link: a client,
    which cannot start without its router, fails to open; the router logs the refused
    handshake, and the stack still runs, its rules still held."""
    transport = TransportConfig(namespace=stack.namespace, mode="client", rendezvous="",
                                connect=(stack.endpoint,), tls_dir=stranger,
                                identity="stranger")  # fmt: skip
    config = zenoh_config(transport)
    config.insert_json5("connect/timeout_ms", "3000")  # give up instead of waiting forever
    with pytest.raises(zenoh.ZError):
        zenoh.open(config)
    stack.wait_log("invalid peer certificate")
    race(stack, "trainer/schedule", owner="trainer", reader="policy",
         make=lambda seed: encode(random_message(Schedule, seed=seed)))  # fmt: skip


def test_the_bridge_publishes_the_robot_only_and_hears_only_safetys_commands(stack: Stack) -> None:
    """The real robot's bridge (issue 17) holds a valid certificate like every member, but may
    publish only the robot's topics and subscribe only to safety's commands: its actions
    never reach safety; its states reach the policy; it hears safety's commands, never the
    perception tokens another member hears."""
    race(stack, "policy/<w>/action", owner="policy", reader="safety", attacker="bridge",
         make=lambda seed: encode(random_message(PolicyAction, seed=seed)))  # fmt: skip
    bridge, policy = stack.client("bridge"), stack.client("policy")
    heard: dict[str, list[bytes]] = {"tokens": [], "command": []}
    for name, path in (("tokens", "perception/<w>/tokens"), ("command", "safety/<w>/command")):
        bridge.declare_subscriber(stack.key(path), lambda s, into=heard[name]: into.append(b""))
    states: list[bytes] = []
    tokens: list[bytes] = []
    policy.declare_subscriber(stack.key("sim/<w>/state"), lambda s: states.append(b""))
    policy.declare_subscriber(stack.key("perception/<w>/tokens"), lambda s: tokens.append(b""))
    safety, perception = stack.client("safety"), stack.client("perception")
    deadline = time.monotonic() + DEADLINE_S
    # Its subscriptions are declared in order: once commands arrive, tokens would too.
    while not (heard["command"] and states and len(tokens) >= 3):
        assert time.monotonic() < deadline, (len(heard["command"]), len(states), len(tokens))
        if heard["command"]:
            perception.put(stack.key("perception/<w>/tokens"), b"tokens")
        safety.put(stack.key("safety/<w>/command"), b"command")
        bridge.put(stack.key("sim/<w>/state"), b"state")
        time.sleep(0.1)
    assert heard["tokens"] == []
