"""Zenoh clients of a secure stack's router, each under a certificate of the stack's CA:
the legitimate parties and the intruders of the attack tests."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import zenoh

from hamnet.runtime import contract
from hamnet.runtime.codec import decode
from hamnet.runtime.transport import TransportConfig, open_session
from tests.stack.up import Up


class Clients:
    """Sessions opened as clients of the router at `endpoint`, in `namespace`."""

    def __init__(self, certs: Path, namespace: str, endpoint: str) -> None:
        self.certs = certs
        self.namespace = namespace
        self.endpoint = endpoint
        self.sessions: list[zenoh.Session] = []

    def client(self, identity: str, directory: Path | None = None) -> zenoh.Session:
        """A Zenoh client of the router presenting `identity`'s certificate."""
        transport = TransportConfig(namespace=self.namespace, mode="client", rendezvous="",
                                    connect=(self.endpoint,), identity=identity,
                                    tls_dir=directory or self.certs)  # fmt: skip
        session = open_session(transport)
        self.sessions.append(session)
        return session

    def key(self, path: str) -> str:
        """The key of contract topic `path` in the namespace (worker 0)."""
        return contract.topic(path).key(self.namespace, w="0") if "<w>" in path else (
            contract.topic(path).key(self.namespace))  # fmt: skip

    def close(self) -> None:
        for session in self.sessions:
            session.close()


class Running(Clients):
    """A secure stack under `hamnet up`, and clients of its router."""

    def __init__(
        self, run: Up, certs: Path, namespace: str, endpoint: str, deadline_s: float = 60.0
    ) -> None:
        super().__init__(certs, namespace, endpoint)
        self.run = run
        self.deadline_s = deadline_s
        """Generous bound for anything to happen (the machine is shared with training runs)."""

    def collect(self, path: str, kind: type, identity: str = "monitor") -> list:
        """Every message published on topic `path` from now on, decoded, as it arrives."""
        received: list = []
        session = self.client(identity)
        session.declare_subscriber(self.key(path),
                                   lambda s: received.append(decode(kind, s.payload.to_bytes())))  # fmt: skip
        return received

    def wait(self, condition: Callable[[], bool], what: str) -> None:
        """Wait until `condition()` holds, while the stack runs."""
        deadline = time.monotonic() + self.deadline_s
        while not condition():
            assert self.run.process.poll() is None, f"hamnet up ended:\n{self.run.output[-3000:]}"
            assert time.monotonic() < deadline, f"never: {what}\n{self.run.output[-3000:]}"
            time.sleep(0.1)
