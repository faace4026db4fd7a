"""The four attacks of issue 16, and issue 29's, against the secure stack (real Zenoh,
loopback): one `hamnet router` with mutual TLS and the access rules of
`hamnet.security.acl`, every party a client of it under its own certificate.

Each test lets the legitimate sender and the attackers publish side by side, waits (with a
generous deadline) until the legitimate message has arrived, then checks that nothing of
the attackers' did, and that the router's log names the refusals."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pytest
import zenoh

from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafeCommand
from hamnet.proto.sim_pb2 import RobotState
from hamnet.proto.trainer_pb2 import Schedule, WeightsAnnouncement
from hamnet.runtime import contract
from hamnet.runtime.codec import encode
from hamnet.runtime.transport import TransportConfig, free_port, zenoh_config
from hamnet.security.acl import router_config_text, stack_acl
from tests.estop import ask_estop
from tests.messages import random_message
from tests.security.clients import Clients
from tests.security.conftest import STACK

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
        self.opened: dict[str, zenoh.Session] = {}
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

    def session(self, identity: str) -> zenoh.Session:
        """This stack's one client session under `identity` (opened on first use)."""
        if identity not in self.opened:
            self.opened[identity] = self.client(identity)
        return self.opened[identity]

    def wait_log(self, *texts: str) -> None:
        """Wait until the router's log holds every one of `texts`."""
        deadline = time.monotonic() + DEADLINE_S
        missing = set(texts)
        while missing:
            log = self.log.read_text()
            missing = {text for text in missing if text not in log}
            if not missing:
                return
            assert self.processes[0].poll() is None, log[-2000:]
            assert time.monotonic() < deadline, f"router log never showed: {sorted(missing)}"
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
         attacker: str | Sequence[str] = "intruder", key: str | None = None,
         eavesdroppers: Sequence[str] = ()) -> None:  # fmt: skip
    """The `attacker`s and `owner` all publish on `path` (worker 0, or `key`); `reader` must
    get only the owner's, and the `eavesdroppers` (subscribed too) nothing of anyone else's.
    Sessions are the stack's, opened once per identity."""
    attackers = [attacker] if isinstance(attacker, str) else list(attacker)
    key = key or stack.key(path)
    heard: dict[str, list[bytes]] = {name: [] for name in eavesdroppers}
    subscribers = [stack.session(name).declare_subscriber(
        key, lambda s, into=heard[name]: into.append(s.payload.to_bytes()),
        allowed_origin=zenoh.Locality.REMOTE) for name in eavesdroppers]  # fmt: skip
    received: list[bytes] = []  # through the router: the reader may be an attacker too
    subscribers.append(stack.session(reader).declare_subscriber(
        key, lambda s: received.append(s.payload.to_bytes()),
        allowed_origin=zenoh.Locality.REMOTE))  # fmt: skip
    intruders = {name: stack.session(name) for name in attackers}
    legitimate = stack.session(owner)
    attacks = {name: make(1 + index) for index, name in enumerate(attackers)}
    genuine = make(0)
    try:
        deadline = time.monotonic() + DEADLINE_S

        def both() -> None:
            for name, session in intruders.items():
                session.put(key, attacks[name])
            legitimate.put(key, genuine)  # delivered after the attacks that precede it, if any

        while genuine not in received:
            assert time.monotonic() < deadline, f"{owner}'s message on {key} never arrived"
            both()
            time.sleep(0.1)
        both()
        while received.count(genuine) < 2:
            assert time.monotonic() < deadline, f"{owner}'s second message never arrived"
            time.sleep(0.05)
    finally:
        for subscriber in subscribers:
            subscriber.undeclare()
    through = [name for name, attack in attacks.items() if attack in received]
    assert through == [], f"{through} published on {key}"
    assert {name: len(into) for name, into in heard.items() if into} == {}, f"eavesdropped {key}"
    stack.wait_log(*(refusal(name, session, "Put", key) for name, session in intruders.items()))


@pytest.fixture(scope="module")
def shared(certs: Path, tmp_path_factory) -> Iterator[Stack]:
    """One secure router for many races, and one session per identity."""
    secure = Stack(certs, tmp_path_factory.mktemp("shared"))
    yield secure
    secure.close()


PUBLISHED = [t for t in contract.TOPICS if t.message is not None]
"""The topics that carry messages (not the latches, not the liveliness tokens)."""


@pytest.mark.parametrize("topic", PUBLISHED, ids=lambda t: t.path)
def test_only_the_contracts_publishers_reach_a_reader(shared: Stack, topic: contract.Topic) -> None:
    """Issue 29: a valid certificate of the monitor or of the trainer published robot states
    (20 of 20 delivered). Now on every key of the contract the legitimate publisher and
    every other identity (each command's, the operator's, a name of no identity) publish
    side by side: a legitimate reader gets the publisher's messages only, and no identity
    that is not a reader of the key hears anything on it. Health reports: each service
    under its own name only (another's, here the sim's, is refused)."""
    owner = topic.publishers[0]
    key = (topic.key(shared.namespace, service=owner, w="0") if "service" in topic.placeholders
           else shared.key(topic.path))  # fmt: skip
    legitimate = {owner} if "service" in topic.placeholders else set(topic.publishers)
    reader = next((r for r in topic.readers if r not in contract.OBSERVERS), topic.readers[0])
    attackers = [name for name in STACK if name not in legitimate]
    eavesdroppers = [name for name in STACK if name not in topic.readers and name != owner]
    race(shared, topic.path, owner=owner, reader=reader, attacker=attackers, key=key,
         eavesdroppers=eavesdroppers, make=lambda seed: f"{key} #{seed}".encode())  # fmt: skip


def test_the_monitors_and_trainers_certificates_cannot_publish_robot_states(
    shared: Stack,
) -> None:
    """The attack of issue 29 as it was: forged states, with steps of 10^12, from the
    monitor's and the trainer's certificates; policy and safety get the sim's only."""

    def state(seed: int) -> bytes:
        message = random_message(RobotState, seed=seed)
        if seed:  # the attackers'
            message.header.step = 10**12
        return encode(message)

    for reader in ("policy", "safety"):
        race(shared, "sim/<w>/state", owner="sim", reader=reader, attacker=["monitor", "trainer"],
             make=state)  # fmt: skip


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
