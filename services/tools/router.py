"""`hamnet router`: a Zenoh router for deployments across machines.

It listens on loopback (tcp/127.0.0.1:7447) unless `--listen` names other endpoints, so
starting one exposes nothing; give it `--listen tcp/<interface address>:7447` (or a tls/
endpoint, see docs/security.md) and services on other machines reach the stack with
`--connect tcp/<router-host>:7447` (in peer or client mode). Runs until SIGINT/SIGTERM.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Annotated

import zenoh

from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RouterConfig:
    """Run a Zenoh router (listens on tcp/127.0.0.1:7447 unless --listen says otherwise)."""

    zenoh_log: str = "warn"
    """Zenoh's own log level on stderr, or a RUST_LOG filter (the environment's RUST_LOG
    wins): TLS handshakes it refuses show at warn, messages access control denies at debug
    (`zenoh::net::routing::interceptor=debug`)."""
    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)


CONFIG = RouterConfig
"""The config `hamnet router` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet router` with command-line arguments `argv`; returns the exit status."""
    config, identity = parse_service(CONFIG, argv, "router", __doc__)
    # Zenoh's own log is where refused links and denied messages show (RUST_LOG refines it).
    zenoh.init_log_from_env_or(config.zenoh_log)
    common = config.common
    transport = replace(common.transport, mode="router")
    with Service(identity, transport) as service:
        log.info("Zenoh router %s listening", service.session.zid())
        while service.running:
            service.receive(timeout=0.5)
    return 0
