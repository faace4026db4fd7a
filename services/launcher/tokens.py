"""What the launcher concludes from each process's liveliness token: when it became ready,
and when it is hung or cut off.

A service declares its token once it is ready and withdraws it when it closes. A token that
goes away while its process still runs means a hung process (its lease expired) or one cut
off from the network, unless the service said it was stopping: a service that finishes on
its own (a trainer at its last update) closes its session first, then still has files to
write and an interpreter to tear down before its process ends (about 2 s for the trainer).
"""

from __future__ import annotations

import logging

from hamnet.launcher.supervisor import Outcome, Process
from hamnet.launcher.watch import HealthBoard, Liveliness

log = logging.getLogger(__name__)

TOKEN_GONE_GRACE_S = 2.0
"""How long a running process may be without its token, with no STOPPING health report,
before the launcher warns: the report and the withdrawal travel apart, so either may come
first."""


def note_tokens(
    processes: list[Process],
    liveliness: Liveliness,
    health: HealthBoard,
    ready_timeout_s: float,
    warned: set[str],
    now: float,
) -> None:
    """Record the processes whose token appeared since their latest start; warn once about
    a process whose token has not appeared after `ready_timeout_s`, or has been gone for
    `TOKEN_GONE_GRACE_S` while its process runs and its service did not say it was stopping.

    Args:
        now: time.monotonic() of this check.
    """
    for process in processes:
        if process.outcome is not Outcome.RUNNING:
            continue
        # A service holds its token under its command's name: `hamnet echo` is `alive/echo/<w>`.
        service, worker = process.spec.command, process.worker
        if process.ready_s is not None:
            ready_at = process.started_at + process.ready_s
            lost_at = liveliness.withdrawn_at(service, worker, ready_at)
            gone = lost_at is not None and now - lost_at >= TOKEN_GONE_GRACE_S
            if gone and not health.stopping(service, worker) and process.label not in warned:
                warned.add(process.label)
                log.warning(
                    "%s lost its liveliness token while running: hung or cut off from the network",
                    process.label,
                )
            continue
        seen = liveliness.announced_since(service, worker, process.started_at)
        if seen is not None:
            process.ready_s = round(seen - process.started_at, 3)
            log.info("%s ready after %.1f s", process.label, process.ready_s)
        elif now - process.started_at > ready_timeout_s and process.label not in warned:
            warned.add(process.label)
            log.warning("%s has not announced itself after %.0f s", process.label, ready_timeout_s)
