"""The replay shell: recorded messages go back onto Zenoh, byte for byte, on their recorded
keys moved into the replay's namespace, at the recorded timing (times `speed`), as fast as
possible, or one step per line read on stdin.

Consumes `RecordedMessage`s in log-time order (`hamnet.runtime.recordings`); produces each
payload unchanged on `remap_key(key, namespace)`, so a monitor or perception service cannot
tell a replay from the live stack. In stepped replay a step starts at each robot state
(`sim/<w>/state`) with a new header step (see `pacing.group_steps`). Like the live sim, a
replay answers queries on `sim/<w>/scene` with the latest replayed scene of every
environment, so services that join halfway catch up (`hamnet.recorder.scenes`).
"""

from __future__ import annotations

import logging
import queue
import sys
import threading
import time
from collections.abc import Iterable
from typing import TextIO

from hamnet.recorder.config import ReplayConfig
from hamnet.recorder.headers import header_of
from hamnet.recorder.pacing import group_steps, remap_key
from hamnet.recorder.scenes import LatestScenes
from hamnet.runtime import contract
from hamnet.runtime.recordings import RecordedMessage, ReplayClock, selected
from hamnet.runtime.service import Service
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

STEP_TOPIC = contract.topic("sim/<w>/state")
"""Messages of this topic mark the steps of stepped replay."""
SCENE = contract.topic("sim/<w>/scene")

QUIT = 0
"""Step request that ends a stepped replay (`q` or end of stdin)."""


def step_of(message: RecordedMessage) -> int | None:
    """Header step of a robot state (a step marker); None for every other message."""
    if not STEP_TOPIC.matches(message.key):
        return None
    try:
        header = header_of(message.key, message.payload)
    except PayloadError:
        return None
    return None if header is None else header.step


def parse_step_request(line: str) -> int | None:
    """Steps asked for by one line of stdin: "" is 1, "N" is N, "q" is QUIT; None if unclear."""
    text = line.strip().lower()
    if text in ("q", "quit"):
        return QUIT
    if not text:
        return 1
    return int(text) if text.isdigit() and int(text) > 0 else None


class ReplayShell:
    """Publishes a recording; `run` returns the exit status."""

    def __init__(
        self,
        service: Service,
        config: ReplayConfig,
        messages: Iterable[RecordedMessage],
        expected: tuple[int, int, int] | None,
        stdin: TextIO | None = None,
    ) -> None:
        """
        Args:
            service: the running service (its namespace is where keys are moved to).
            config: timing, filters, progress.
            messages: the recording, in log-time order.
            expected: (messages, first log ns, last log ns) of the whole recording when its
                files have summaries, for progress lines; None otherwise.
            stdin: where step requests are read (stepped replay); default sys.stdin.
        """
        self.service, self.config, self.expected = service, config, expected
        self.messages = selected(messages, config.topics)
        self.stdin = stdin if stdin is not None else sys.stdin
        self.published = 0
        self._last_progress = time.monotonic()
        self._position_ns = 0
        self.scenes = LatestScenes()
        service.inbox.serve("scene_query", SCENE.pattern_in(service.namespace))

    def run(self) -> int:
        """Replay to the end (or until stopped)."""
        self._wait(time.monotonic() + self.config.start_delay_s)
        if self.config.step:
            self._run_stepped()
        else:
            self._run_timed()
        log.info("replayed %d messages", self.published)
        return 0

    def _run_timed(self) -> None:
        clock = None
        for message in self.messages:
            if not self.service.running:
                return
            if not self.config.fast:
                if clock is None:
                    clock = ReplayClock(message.log_time_ns, time.monotonic(), self.config.speed)
                self._wait(clock.due_s(message.log_time_ns))
            else:
                self._receive(timeout=0)  # health reports and queries stay on time
            self._publish(message)

    def _run_stepped(self) -> None:
        requests: queue.Queue[int] = queue.Queue()
        threading.Thread(target=self._read_requests, args=(requests,), daemon=True).start()
        steps = group_steps(self.messages, step_of)
        print("stepped replay: Enter publishes one step, N publishes N steps, q quits", flush=True)
        while self.service.running:
            try:
                wanted = requests.get(timeout=0.1)
            except queue.Empty:
                self._receive(timeout=0)
                continue
            if wanted == QUIT:
                return
            for _ in range(wanted):
                group = next(steps, None)
                if group is None:
                    print("end of recording", flush=True)
                    return
                for message in group:
                    self._publish(message)
                marker = next((s for s in map(step_of, group) if s is not None), None)
                print(f"step {marker}: {len(group)} messages", flush=True)

    def _read_requests(self, requests: queue.Queue[int]) -> None:
        """Reads stdin on its own thread (a blocking read must not stall the service)."""
        for line in self.stdin:
            wanted = parse_step_request(line)
            if wanted is None:
                print(f"not understood: {line.strip()!r} (Enter, a number or q)", flush=True)
                continue
            requests.put(wanted)
            if wanted == QUIT:
                return
        requests.put(QUIT)

    def _publish(self, message: RecordedMessage) -> None:
        key = remap_key(message.key, self.service.namespace)
        self.service.publisher(key).put_encoded(message.payload)
        if SCENE.matches(key):
            try:
                self.scenes.add(key, message.payload)
            except PayloadError:  # replayed as recorded, but it answers no query
                pass
        self.published += 1
        self._position_ns = message.log_time_ns
        now = time.monotonic()
        if now - self._last_progress >= self.config.progress_s:
            self._last_progress = now
            log.info("%s", self._progress())

    def _progress(self) -> str:
        if self.expected is None:
            return f"replayed {self.published} messages"
        total, first, last = self.expected
        at, span = (self._position_ns - first) / 1e9, (last - first) / 1e9
        return (f"replayed {self.published}/{total} messages, "
                f"{at:.1f}/{span:.1f} s of recording ({100 * at / max(span, 1e-9):.0f}%)")

    def _wait(self, until_s: float) -> None:
        """Sleep until `until_s` (time.monotonic) while health reports go on; returns early
        when the service is stopped."""
        while self.service.running:
            remaining = until_s - time.monotonic()
            if remaining <= 0:
                return
            self._receive(timeout=min(remaining, 0.1))

    def _receive(self, timeout: float) -> None:
        """Let the service report health, and answer a scene query if one came."""
        received = self.service.receive(timeout=timeout)
        if received is not None and received.name == "scene_query":
            query = received.value
            for key, payload in self.scenes.answers(str(query.key_expr)):
                query.reply(key, payload)
            query.drop()
