"""Asking the safety service's e-stop queryable from a test, as an operator's tool would."""

from __future__ import annotations

import json
import time

import zenoh


def ask_estop(session: zenoh.Session, key: str, command: str, deadline_s: float = 10.0) -> dict:
    """The e-stop's JSON answer to `command` (stop, reset, status), asked again until the
    safety service answers or `deadline_s` passes (its queryable appears after start-up)."""
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        for reply in session.get(f"{key}?{command}", timeout=2.0):
            assert reply.ok is not None, reply.err.payload.to_string()
            return json.loads(reply.ok.payload.to_string())
        time.sleep(0.1)
    raise AssertionError(f"no answer to e-stop {command!r}")
