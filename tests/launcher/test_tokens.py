"""The launcher's reading of liveliness tokens (`hamnet.launcher.tokens`), on real Zenoh
tokens, with the check's clock given: a token withdrawn by a service that said it was
stopping is a stop, one withdrawn without a word is a hang once the grace has passed."""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
import zenoh

from hamnet.launcher.stack import ServiceSpec
from hamnet.launcher.supervisor import Outcome, Process
from hamnet.launcher.tokens import TOKEN_GONE_GRACE_S, note_tokens
from hamnet.launcher.watch import ALIVE, HealthBoard, Liveliness
from hamnet.proto.health_pb2 import Health, ServiceState
from hamnet.runtime.transport import TransportConfig, open_session

HUNG = "lost its liveliness token while running"


@dataclass
class Watched:
    """One running process as the launcher sees it, and the session that holds its token."""

    process: Process
    liveliness: Liveliness
    health: HealthBoard
    owner: zenoh.Session
    key: str

    def check(self, now: float, warned: set[str]) -> None:
        note_tokens([self.process], self.liveliness, self.health, 30.0, warned, now)

    def ready_then_withdrawn(self) -> float:
        """Declare the token, see the process ready, withdraw the token; when it went."""
        token = self.owner.liveliness().declare_token(self.key)
        deadline = time.monotonic() + 10
        while self.process.ready_s is None:
            assert time.monotonic() < deadline, "the token was never seen"
            self.check(time.monotonic(), set())
            time.sleep(0.02)
        token.undeclare()
        while (lost := self.liveliness.withdrawn_at("echo", "0", 0.0)) is None:
            assert time.monotonic() < deadline, "the withdrawal was never seen"
            time.sleep(0.02)
        return lost


@pytest.fixture
def watched(transport: TransportConfig) -> Iterator[Watched]:
    launcher, owner = open_session(transport), open_session(transport)
    liveliness = Liveliness(launcher, transport.namespace)
    process = Process("echo", "0", ServiceSpec(command="echo"), ["echo"],
                      outcome=Outcome.RUNNING, started_at=time.monotonic())  # fmt: skip
    yield Watched(process, liveliness, HealthBoard(), owner,
                  ALIVE.key(transport.namespace, service="echo", w="0"))  # fmt: skip
    liveliness.close()
    owner.close()
    launcher.close()


def test_a_token_gone_without_a_word_is_a_hang_once_the_grace_has_passed(watched, caplog):
    lost = watched.ready_then_withdrawn()
    warned: set[str] = set()
    with caplog.at_level(logging.WARNING, logger="hamnet.launcher.tokens"):
        watched.check(lost + TOKEN_GONE_GRACE_S / 2, warned)
        assert HUNG not in caplog.text  # it may still be on its way out
        watched.check(lost + TOKEN_GONE_GRACE_S, warned)
        watched.check(lost + 2 * TOKEN_GONE_GRACE_S, warned)
    assert caplog.text.count(f"echo/0 {HUNG}") == 1


def test_a_token_gone_after_a_stopping_report_is_a_stop(watched, caplog):
    """A service that finishes on its own says so, then may take seconds to exit."""
    lost = watched.ready_then_withdrawn()
    watched.health.add(Health(service="echo", worker="0", state=ServiceState.RUNNING, uptime_s=1))
    watched.health.add(Health(service="echo", worker="0", state=ServiceState.STOPPING, uptime_s=2))
    with caplog.at_level(logging.WARNING, logger="hamnet.launcher.tokens"):
        watched.check(lost + 10 * TOKEN_GONE_GRACE_S, set())
    assert HUNG not in caplog.text


def test_a_process_that_never_announces_itself_is_warned_about_once(watched, caplog):
    started, warned = watched.process.started_at, set()
    with caplog.at_level(logging.WARNING, logger="hamnet.launcher.tokens"):
        watched.check(started + 29.0, warned)
        assert "has not announced itself" not in caplog.text
        watched.check(started + 31.0, warned)
        watched.check(started + 40.0, warned)
    assert caplog.text.count("echo/0 has not announced itself after 30 s") == 1
