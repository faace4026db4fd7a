"""Zenoh clients of a secure stack's router, each under a certificate of the stack's CA:
the legitimate parties and the intruders of the attack tests."""

from __future__ import annotations

from pathlib import Path

import zenoh

from hamnet.runtime import contract
from hamnet.runtime.transport import TransportConfig, open_session


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
