"""Command-line parsing for every `hamnet <command>`: flags generated from the command's
frozen config dataclass (field docstrings become the `--help` text), with the shared
transport and logging options flattened to `--namespace`, `--connect`, `--log-level`...

A value the config refuses is one line on stderr and exit status 2, whichever config it is
in; so is a period (any field named `*period_s`: report, stats, checkpoint...) that is not
a positive number of seconds.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Protocol, TypeVar

import tyro

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.keys import check_segment
from hamnet.runtime.logs import LogFormat, configure_logging
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.shell_config import Flattened
from hamnet.runtime.transport import TransportConfig

C = TypeVar("C")
S = TypeVar("S", bound="HasCommon")


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
    remap: tuple[str, ...] = ()
    """Rewire ports, PORT=KEY each: read or write port PORT on KEY (a whole key such as
    hamnet/replay/sim/0/state, or a path in this namespace such as sim/1/state) instead of
    its own key. The service's ports are listed at the end of --help."""

    def __post_init__(self) -> None:
        try:
            check_segment("worker", self.worker)
        except ValueError as error:
            raise ConfigError(str(error)) from None


def parse(
    config_type: type[C], argv: Sequence[str], prog: str, description: str, default: C | None = None
) -> C:
    """Build `config_type` from `argv`, starting from `default` (the type's defaults when
    None); `--help` prints every option with its docstring.

    A value the config refuses (a `ConfigError`, a ValueError from a config's
    `__post_init__`, nested or not) or a flag tyro cannot parse (`--num-envs abc`) is
    printed as one line, `prog: message`, and raised as SystemExit(2): tyro's own report of
    those is a box of 5-9 lines, which is kept for nothing but its message.
    """
    captured = io.StringIO()
    try:
        with contextlib.redirect_stderr(captured):
            config = tyro.cli(  # type: ignore[call-overload]
                config_type,
                args=list(argv),
                prog=prog,
                description=description,
                default=default,
            )
        check_periods(config)
    except (ConfigError, ValueError) as error:
        print(f"{prog}: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    except SystemExit as leaving:
        if leaving.code == 2:  # tyro's error box
            print(f"{prog}: {boxed_message(captured.getvalue())}", file=sys.stderr)
        else:
            sys.stderr.write(captured.getvalue())
        raise
    sys.stderr.write(captured.getvalue())
    return config


def boxed_message(text: str) -> str:
    """The message of tyro's error box (its first section, the lines joined), without the
    box: `Error parsing run.ppo: lr must be > 0` -> `run.ppo: lr must be > 0`. tyro draws
    the box in lines (a title in the top border) on a terminal, and without borders (the
    title on a line of its own, sections between rules of dashes) into a buffer; text that
    is neither is returned on one line as it is."""
    sections: list[list[str]] = [[]]
    for line in text.splitlines():
        if line.strip().startswith(("╭", "╰")):
            continue  # the box's top (with its title) and bottom
        inner = line.strip().strip("│").strip()
        if inner and set(inner) <= set("─- "):
            sections.append([])
        elif inner:
            sections[-1].append(inner)
    sections = [section for section in sections if section]
    if len(sections) > 1 and len(sections[0]) == 1 and ":" not in sections[0][0]:
        sections = sections[1:]  # the borderless box's title line
    message = " ".join(sections[0]) if sections else " ".join(text.split())
    return message.removeprefix("Error parsing ")


def check_periods(config: object) -> None:
    """Raise ConfigError for any field named `*period_s` in `config` (or a config nested in
    it) that is not a positive number of seconds: a period of 0 or less would make a loop
    report, log or save on every turn."""
    for item in dataclasses.fields(config) if dataclasses.is_dataclass(config) else ():
        value = getattr(config, item.name)
        if item.name.endswith("period_s") and isinstance(value, (int, float)):
            if not value > 0:
                flag = item.name.replace("_", "-")
                raise ConfigError(f"--{flag} must be > 0 s, got {value}")
        elif dataclasses.is_dataclass(value):
            check_periods(value)


def check_remap(common: CommonConfig, ports: Ports | None) -> None:
    """ConfigError unless every `--remap` names one of `ports` (None: the command has none)
    and a key of that port's topic."""
    if ports is not None:
        ports.remapped(common.remap, common.transport.namespace)
    elif common.remap:
        raise ConfigError("this command has no ports to --remap")


class HasCommon(Protocol):
    """A service config: it nests the common options."""

    @property
    def common(self) -> CommonConfig: ...


def parse_service(
    config_type: type[S],
    argv: Sequence[str],
    service: str,
    description: str,
    default: S | None = None,
    ports: Ports | None = None,
) -> tuple[S, ServiceIdentity]:
    """Parse a service's command line (from `default`, if given) and set up its logging.

    With `--tls-dir` and no `--identity`, the identity is the service's name. The service's
    `ports` are listed in `--help`, and a `--remap` of them is checked here (one line, exit 2).

    Returns:
        The config and who the service is on the network (`service/worker`).
    """
    prog = f"hamnet {service}"
    if ports is not None:
        description = f"{description}\n\n{ports.describe()}"
    config = parse(config_type, argv, prog, description, default)
    try:
        check_remap(config.common, ports)
    except ConfigError as error:
        print(f"{prog}: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    transport = config.common.transport
    if transport.tls_dir is not None and not transport.identity:
        # A service presents the certificate named after it unless told otherwise.
        own = dataclasses.replace(transport, identity=service)
        common = dataclasses.replace(config.common, transport=own)
        config = dataclasses.replace(config, common=common)  # type: ignore[type-var]
    logging = config.common.logging
    identity = ServiceIdentity(service, config.common.worker)
    configure_logging(identity.source, logging.log_level, logging.log_format)
    return config, identity
