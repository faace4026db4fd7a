"""The latest replayed scene of every environment, so that a replay answers the scene
queries of services started after the scenes went by (`Inbox.catch_up`), as the live sim
does: a monitor or perception service joining a replay halfway gets going at once.

Consumes the Scene payloads replay publishes (key, bytes); answers with the fewest recorded
payloads that hold every environment's latest scene, in their recorded order, unchanged.
"""

from __future__ import annotations

import numpy as np
import zenoh

from hamnet.proto.sim_pb2 import Scene
from hamnet.runtime.codec import parse
from hamnet.runtime.tensor import from_tensor


class LatestScenes:
    """Per scene key, the payload that last described each environment."""

    def __init__(self) -> None:
        self._latest: dict[str, dict[int, tuple[int, bytes]]] = {}
        """key -> environment -> (arrival number, payload)."""
        self._arrivals = 0

    def add(self, key: str, payload: bytes) -> None:
        """Note a Scene payload published on `key`.

        Raises:
            PayloadError: the payload is not a Scene with env_ids (it is still replayed, as
                recorded, but cannot answer queries).
        """
        env_ids = from_tensor(parse(Scene, payload).env_ids, np.int32, (None,))  # (K,)
        self._arrivals += 1
        rows = self._latest.setdefault(key, {})
        for env in env_ids.tolist():
            rows[env] = (self._arrivals, payload)

    def answers(self, key_expr: str) -> list[tuple[str, bytes]]:
        """(key, payload) to reply to a query on `key_expr`: per matching key, each payload
        still latest for some environment, oldest first (later ones win where they overlap)."""
        wanted = zenoh.KeyExpr(key_expr)
        replies = []
        for key, rows in self._latest.items():
            if wanted.intersects(zenoh.KeyExpr(key)):
                unique = dict(sorted(rows.values()))  # arrival -> payload, each once
                replies += [(key, payload) for _, payload in sorted(unique.items())]
        return replies
