"""Stacks closed to strangers (`secure:` in a stack file; docs/security.md): the stack's own
router, with mutual TLS and the access rules, is started first and every process, the
launcher included, joins it as a client under its own certificate, so every message
crosses the router's rules. `--check` and the summary say how a stack's processes meet.
"""

from __future__ import annotations

import socket
import ssl
import time
from dataclasses import dataclass, replace
from pathlib import Path

from hamnet.launcher.stack import ROUTER, ServiceSpec, Stack
from hamnet.launcher.supervisor import Supervisor
from hamnet.runtime.cli import CommonConfig
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.tls_files import ca_files, identity_files
from hamnet.runtime.transport import TransportConfig, tls_files

UP = "up"
"""The launcher's identity."""

OPERATOR = "operator"
"""The identity a person uses for the e-stop (`hamnet certs stack` issues it too)."""

PLACEMENT = ("mode", "rendezvous", "connect", "listen")
"""Transport options a secure stack sets itself: where its processes meet."""


class RouterError(RuntimeError):
    """The stack's router did not come up; the message says why in one line."""


def secured(stack: Stack, common: CommonConfig) -> tuple[Stack, CommonConfig]:
    """`stack` with its router as first service, and `common` with the transport of its
    processes (clients of that router over TLS); both unchanged for a stack not secure.

    `--tls-dir` given to `hamnet up` replaces the stack file's folder.

    Raises:
        ConfigError: options of `hamnet up` that would place processes elsewhere.
    """
    if stack.secure is None:
        return stack, common
    transport, default = common.transport, TransportConfig()
    clashing = [
        f"--{name}" for name in PLACEMENT if getattr(transport, name) != getattr(default, name)
    ]
    if clashing:
        raise ConfigError(
            f"stack {stack.name} is secure: it starts its own router and places "
            f"every process; drop {', '.join(clashing)}"
        )
    endpoint = stack.secure.listen
    client = replace(
        transport,
        mode="client",
        rendezvous="",
        connect=(endpoint,),
        tls_dir=transport.tls_dir or Path(stack.secure.tls_dir),
    )
    router = ServiceSpec(
        command=ROUTER,
        args={
            "mode": "router",
            "connect": (),
            "listen": (endpoint,),
            "zenoh-config": stack.secure.access,
        },
    )
    return replace(stack, services={ROUTER: router, **stack.services}), replace(
        common, transport=client
    )


def identities(stack: Stack) -> list[str]:
    """Who presents a certificate when `stack` runs: its router (if secure), the launcher
    and each service's command, sorted."""
    commands = {spec.command for spec in stack.services.values()}
    return sorted({UP, *commands, *([ROUTER] if stack.secure is not None else [])})


def missing_certificates(stack: Stack, tls_dir: Path) -> list[Path]:
    """The CA certificate and the identities' certificates and keys not in `tls_dir`."""
    files = [ca_files(tls_dir).certificate]
    for name in identities(stack):
        own = identity_files(tls_dir, name)
        files += [own.certificate, own.key]
    return [path for path in files if not path.is_file()]


@dataclass(frozen=True)
class Security:
    """How a stack's processes meet, as `--check` and the summary tell it."""

    tls_dir: str | None = None
    """Certificates folder when every link is mutual TLS; None: plain links."""
    access: str | None = None
    """Router config whose access rules the stack's own router enforces; None: none."""
    router: str | None = None
    """Where the stack's own router listens; None: it has none."""

    def text(self) -> str:
        """One line for a person."""
        if self.access is not None:
            return (
                f"secure: mutual TLS (certificates in {self.tls_dir}), access control by "
                f"{self.access} on the stack's router at {self.router}"
            )
        if self.tls_dir is not None:
            return (
                f"mutual TLS (certificates in {self.tls_dir}); no access control of its "
                "own (only what a router it joins enforces)"
            )
        return (
            "not secure: plain links, no access control (any process that reaches them "
            "may publish on any key; docs/security.md)"
        )


def security(stack: Stack, transport: TransportConfig) -> Security:
    """How `stack` runs with `transport` (the processes' transport, after `secured`)."""
    tls_dir = None if transport.tls_dir is None else str(transport.tls_dir)
    if stack.secure is None:
        return Security(tls_dir)
    return Security(tls_dir, stack.secure.access, stack.secure.listen)


def start_router(supervisor: Supervisor, stack: Stack, transport: TransportConfig) -> None:
    """Start the router of a secure stack and wait until it completes a TLS handshake with
    the launcher's certificate (from `transport`): the launcher's own session, a client,
    would otherwise wait for it forever, and a handshake is how a client is let in (a bare
    TCP probe would make Zenoh log a failed handshake).

    Raises:
        RouterError: its port is taken already, the router refuses the handshake, or it
            exited or is not listening after the stack's `ready_timeout_s`.
    """
    if stack.secure is None:
        return
    endpoint = stack.secure.listen
    host, _, port = endpoint.partition("/")[2].rpartition(":")
    address = (host.strip("[]"), int(port))
    ca, own = tls_files(transport.tls_dir, transport.identity)
    context = ssl.create_default_context(cafile=str(ca))
    context.load_cert_chain(own.certificate, own.key)
    if _connects(address):
        raise RouterError(f"something already listens on {endpoint} (another stack's router?)")
    process = next(p for p in supervisor.processes if p.service == ROUTER)
    supervisor.start(process)
    deadline = time.monotonic() + stack.ready_timeout_s
    while not _shakes_hands(address, context):
        if process.popen.poll() is not None:
            raise RouterError(
                f"{process.label} exited (status {process.popen.returncode}) "
                f"before listening on {endpoint}"
            )
        if time.monotonic() > deadline:
            raise RouterError(
                f"{process.label} is not listening on {endpoint} after {stack.ready_timeout_s:g} s"
            )
        time.sleep(0.1)


def _connects(address: tuple[str, int]) -> bool:
    """Whether anything accepts TCP connections at `address` (closed at once)."""
    try:
        with socket.create_connection(address, timeout=1.0):
            return True
    except OSError:
        return False


def _shakes_hands(address: tuple[str, int], context: ssl.SSLContext) -> bool:
    """Whether a mutual-TLS handshake with `address` succeeds (False: nothing listens yet).

    Raises:
        RouterError: something listens but refuses the handshake or fails its check.
    """
    try:
        raw = socket.create_connection(address, timeout=1.0)
    except OSError:
        return False
    try:
        with context.wrap_socket(raw, server_hostname=address[0]):
            return True
    except (ssl.SSLError, ssl.CertificateError) as error:
        raise RouterError(
            f"TLS handshake with the router at {address[0]}:{address[1]} failed: {error}"
        ) from None
    except OSError:
        return False
    finally:
        raw.close()
