"""Command-line parsing for every `hamnet <command>`: flags generated from the command's
frozen config dataclass (field docstrings become the `--help` text), with the shared
transport and logging options flattened to `--namespace`, `--connect`, `--log-level`..."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Protocol, TypeVar

import tyro

from hamnet.runtime.logs import LogFormat, configure_logging
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.transport import TransportConfig

C = TypeVar("C")
S = TypeVar("S", bound="HasCommon")

Flattened = tyro.conf.OmitArgPrefixes
"""Annotate a nested config field with this to expose its options without a prefix."""


@dataclass(frozen=True)
class LogConfig:
    """Logging options shared by every command."""

    log_level: str = "info"
    """Minimum level printed: debug, info, warning or error."""
    log_format: LogFormat = "text"
    """text (one readable line per event) or json (one object per line)."""


@dataclass(frozen=True)
class CommonConfig:
    """Options every service takes: where it runs on the network and how it logs."""

    worker: str = "0"
    """Worker id of this instance (a key segment), so several instances can run side by side."""
    transport: Annotated[TransportConfig, Flattened] = field(default_factory=TransportConfig)
    logging: Annotated[LogConfig, Flattened] = field(default_factory=LogConfig)


def parse(
    config_type: type[C], argv: Sequence[str], prog: str, description: str, default: C | None = None
) -> C:
    """Build `config_type` from `argv`, starting from `default` (the type's defaults when
    None); `--help` prints every option with its docstring."""
    return tyro.cli(  # type: ignore[call-overload]
        config_type,
        args=list(argv),
        prog=prog,
        description=description,
        default=default,
    )


class HasCommon(Protocol):
    """A service config: it nests the common options."""

    @property
    def common(self) -> CommonConfig: ...


def parse_service(
    config_type: type[S], argv: Sequence[str], service: str, description: str, default: S | None = None
) -> tuple[S, ServiceIdentity]:
    """Parse a service's command line (from `default`, if given) and set up its logging.

    Returns:
        The config and who the service is on the network (`service/worker`).
    """
    config = parse(config_type, argv, f"hamnet {service}", description, default)
    logging = config.common.logging
    identity = ServiceIdentity(service, config.common.worker)
    configure_logging(identity.source, logging.log_level, logging.log_format)
    return config, identity
