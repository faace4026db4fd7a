"""`hamnet router`: services that cannot meet as local peers reach each other through it."""

from __future__ import annotations

import time
from dataclasses import replace

from hamnet.runtime import contract, keys
from hamnet.runtime.codec import encode
from hamnet.runtime.transport import open_session
from tests.conftest import free_port
from tests.messages import random_message


def test_clients_exchange_messages_through_the_router(spawn, transport) -> None:
    """With no rendezvous, nothing but the router connects the test and `hamnet echo`:
    a reflected message proves the route through it."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = spawn("router", "--listen", endpoint, "--namespace", transport.namespace)
    client = ["--mode", "client", "--rendezvous", "", "--connect", endpoint]
    echo = spawn("echo", "--reflect", "--namespace", transport.namespace, *client)
    session = open_session(replace(transport, mode="client", rendezvous="", connect=(endpoint,)))
    state = contract.topic("sim/<w>/state")
    key = state.key(transport.namespace, w="0")
    payload = encode(random_message(state.message, seed=3))
    reflected: list[bytes] = []
    session.declare_subscriber(
        f"{keys.ROOT}/{transport.namespace}/echo/0/reflect/**",
        lambda sample: reflected.append(sample.payload.to_bytes()),
    )
    deadline = time.monotonic() + 20
    while not reflected and time.monotonic() < deadline:
        assert router.poll() is None and echo.poll() is None
        session.put(key, payload)
        time.sleep(0.2)
    session.close()
    assert reflected and reflected[0] == payload
