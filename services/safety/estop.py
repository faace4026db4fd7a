"""The e-stop latch behind the queryable `hamnet/<ns>/safety/<w>/estop`: `stop` latches a
stop, `reset` releases it, `status` reports; each answer is a JSON object."""

from __future__ import annotations

import json
import threading
from collections import deque


class EStop:
    """The latch behind the e-stop queryable. Zenoh threads call `request`; the service
    thread applies the queued requests to the filter (`take`), so the filter is only ever
    touched by one thread. The latch itself takes effect at once: actions are ignored from
    the moment `stop` is answered."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._requests: deque[str] = deque()
        self.latched = False
        """A stop is latched: actions are ignored, every state gets the brake."""
        self.status: dict[str, object] = {}
        """What the service thread last reported (step, watchdog), for `status` answers."""

    def request(self, command: str) -> tuple[bool, str]:
        """Handle `stop`, `reset` or `status`; returns (ok, JSON answer or error text)."""
        command = command.strip().lower()
        if command not in ("stop", "reset", "status"):
            return False, f"unknown e-stop command {command!r}: use stop, reset or status"
        with self._lock:
            if command != "status":
                self.latched = command == "stop"
                self._requests.append(command)
            answer = {"latched": self.latched, **self.status}
        return True, json.dumps(answer)

    def take(self) -> list[str]:
        """Requests not applied yet, oldest first."""
        with self._lock:
            requests = list(self._requests)
            self._requests.clear()
        return requests


def on_query(estop: EStop, query) -> None:
    """Zenoh callback of the queryable: the command is the payload, else the parameters
    (`hamnet/<ns>/safety/<w>/estop?stop`)."""
    payload = query.payload
    text = payload.to_string() if payload is not None else str(query.parameters)
    ok, answer = estop.request(text)
    if ok:
        query.reply(query.key_expr, answer)
    else:
        query.reply_err(answer)
