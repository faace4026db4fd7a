"""One run of a stack: start its built services, follow their liveliness tokens and health
reports, decide when the run ends, stop every process, and build the report.

The run ends when the user stops it (SIGINT/SIGTERM), when `duration_s` elapses, when the
`until` service has finished, or when every process has finished: exit status 0. It ends
with exit status 1 when a process of a critical service fails (crashes with no restarts
left); a failed process of an auxiliary service (`record`, `monitor` by default) is logged
and listed in the summary while the rest of the stack goes on. The launcher itself is a
service (`up/<worker>`) of the stack's namespace: it holds a token and reports its health.
A secure stack's router is started first (the launcher joins it) and stopped last.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass, replace

from hamnet.launcher.argv import forwarded, service_argv
from hamnet.launcher.check import Verdict, not_built
from hamnet.launcher.output import Output, use_colour
from hamnet.launcher.secure import UP, security, start_router
from hamnet.launcher.stack import ROUTER, Stack
from hamnet.launcher.summary import Report, output_files, output_state, process_report
from hamnet.launcher.supervisor import Outcome, Process, Supervisor
from hamnet.launcher.tokens import note_tokens
from hamnet.launcher.watch import HEALTH, HealthBoard, Liveliness
from hamnet.proto.health_pb2 import Health
from hamnet.runtime.cli import CommonConfig
from hamnet.runtime.service import Service, ServiceIdentity

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Ending:
    """Why a run ended and the exit status of `hamnet up`."""

    reason: str
    exit_code: int


def run(
    stack: Stack, verdicts: list[Verdict], common: CommonConfig, duration_s: float | None
) -> Report:
    """Run the built services of `stack` until the run ends; returns the report.

    Args:
        stack: the stack, namespace already resolved.
        verdicts: `check(stack, ...)` without errors: which services are built.
        common: the launcher's own options; transport and logging options that differ from
            the defaults are forwarded to every process.
        duration_s: bound of the run in seconds, None for none.
    """
    forward = forwarded(common)
    processes = []
    for verdict in verdicts:
        if verdict.built:
            spec = stack.services[verdict.service]
            processes += [
                Process(verdict.service, w, spec, service_argv(spec, w, stack.namespace, forward))
                for w in spec.workers
            ]
    missing = not_built(verdicts)
    log.info(
        "stack %s (namespace %s): processes to start: %d",
        stack.name,
        stack.namespace,
        len(processes),
    )
    log.info("%s", security(stack, common.transport).text())
    if missing:
        log.warning("not built yet, not started: %s", missing)
    output = Output(sys.stdout, [p.label for p in processes], use_colour(sys.stdout))
    supervisor = Supervisor(processes, output)
    started, before = time.monotonic(), output_state(stack.output_paths)
    transport = replace(common.transport, namespace=stack.namespace)
    try:
        start_router(supervisor, stack, transport)
        with Service(ServiceIdentity(UP, common.worker), transport) as service:
            liveliness = Liveliness(service.session, stack.namespace)
            health = HealthBoard()
            service.inbox.subscribe("health", HEALTH.pattern_in(stack.namespace), Health)
            try:
                ending = _supervise(stack, service, supervisor, liveliness, health, duration_s)
            finally:
                supervisor.stop(stack.stop_grace_s, spare=(ROUTER,))
            # The last reports (state STOPPING) hold each process's final counters.
            while (received := service.inbox.get(timeout=0.2)) is not None:
                health.add(received.value)
            liveliness.close()
    finally:
        supervisor.stop(stack.stop_grace_s)  # a secure stack's router, last
    log.info("stack %s ended: %s", stack.name, ending.reason)
    outputs, outputs_missing = output_files(stack.output_paths, before)
    return Report(
        stack=stack.name,
        namespace=stack.namespace,
        ended=ending.reason,
        exit_code=ending.exit_code,
        elapsed_s=round(time.monotonic() - started, 3),
        processes=[process_report(p, liveliness, health) for p in processes],
        not_built=missing,
        outputs=outputs,
        outputs_missing=outputs_missing,
        security=security(stack, transport),
    )


def _supervise(
    stack: Stack,
    service: Service,
    supervisor: Supervisor,
    liveliness: Liveliness,
    health: HealthBoard,
    duration_s: float | None,
) -> Ending:
    """Keep the processes running until the run ends."""
    processes = supervisor.processes
    if not processes:
        return Ending("nothing to run: no service of the stack is built yet", 0)
    until = [p for p in processes if p.service == stack.until]
    started = time.monotonic()
    warned: set[str] = set()
    all_ready = False
    while service.running:
        for process in supervisor.step():
            if process.outcome is not Outcome.FAILED:
                continue
            if process.spec.is_critical:
                return Ending(f"{process.label} crashed with no restarts left", 1)
            log.error(
                "%s failed (%s); it is auxiliary: the rest of the stack goes on without it",
                process.label,
                process.exit_text,
            )
        if until and all(p.outcome is Outcome.FINISHED for p in until):
            return Ending(f"{stack.until} finished", 0)
        if all(p.outcome in (Outcome.FINISHED, Outcome.FAILED) for p in processes):
            return Ending("every process finished", 0)
        if duration_s is not None and time.monotonic() - started >= duration_s:
            return Ending(f"duration of {duration_s:g} s reached", 0)
        note_tokens(processes, liveliness, health, stack.ready_timeout_s, warned, time.monotonic())
        if not all_ready and all(p.ready_s is not None for p in processes):
            all_ready = True
            log.info(
                "stack ready: every process announced itself after %.1f s",
                time.monotonic() - started,
            )
        received = service.receive(timeout=0.05)
        if received is not None:
            health.add(received.value)
    return Ending("stopped by a signal", 0)
