"""The operator's requests on `bridge/<w>/reset` applied to the bridge's core, without
Zenoh: `stop` stops the stream, `reset` reconnects and starts a new episode, `status` reads
what the bridge knows (the latch and its queries are `hamnet.safety.estop`'s).

A reset runs beside the loop, in a thread of its own (reconnecting to a robot can take
seconds): until it ends the core is that thread's alone, so requests that come meanwhile
wait, and the loop paces on the wall clock and refuses commands. How the last reset ended
(and why it failed, if it did) stays in `status` as `last_reset`.
"""

from __future__ import annotations

import logging
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

from hamnet.bridge.core import BridgeCore
from hamnet.bridge.driver import RobotReading
from hamnet.safety.estop import EStop

log = logging.getLogger(__name__)


class Resets:
    """Stop and reset requests, the reset under way and the `status` answer."""

    def __init__(self, core: BridgeCore) -> None:
        self.core = core
        self.requests = EStop()
        """The latch the queryable fills and whose `status` it answers."""
        self.executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="bridge-reset")
        self.resetting: Future[RobotReading | None] | None = None
        """The reset under way, if any: until it ends the core is its thread's alone."""
        self.pending: deque[str] = deque()
        """Requests taken but not applied yet (those after a reset wait for its end)."""
        self.last_reset: dict[str, object] | None = None
        """How the last reset ended, for `status`: step, ok, and the reason of a failure."""

    def apply(self, step: int) -> bool:
        """Apply the requests taken by now at state `step` (a reset in its own thread, the
        others once no reset is under way) and update `status`; True when a reset has just
        ended well (a new episode streams)."""
        ended = self.resetting is not None and self.resetting.done() and self._finish(step)
        self.pending.extend(self.requests.take())
        while self.resetting is None and self.pending:
            request = self.pending.popleft()
            if request == "stop":
                self.core.stop("stop requested")
            elif request == "reset":
                self.resetting = self.executor.submit(self.core.reset)
        self.requests.status = {
            "step": step,
            "streaming": self.core.streaming,
            "errors": [e.name for e in self.core.errors],
            "resetting": self.resetting is not None,
            "last_reset": self.last_reset,
        }
        return ended

    def close(self) -> None:
        """Wait for a reset under way, then let the thread go."""
        self.executor.shutdown(wait=True)

    def _finish(self, step: int) -> bool:
        """Take the ended reset's outcome; on failure the bridge stays up, stopped, and
        `status` says why."""
        reading, self.resetting = self.resetting.result(), None
        if reading is None:
            reason = self.core.reset_failure
            log.warning("reset at step %d failed, the stream stays stopped: %s", step, reason)
            self.last_reset = {"step": step, "ok": False, "reason": reason}
            return False
        self.last_reset = {"step": step, "ok": True, "reason": ""}
        log.info("reset at step %d: streaming again, episode %d", step, self.core.episode_id)
        return True
