"""Stack files: which services `hamnet up` runs, with which arguments, and when it stops.

A stack file is YAML. Its keys are the fields of `Stack`, `ServiceSpec` and
`RestartPolicy` below (their docstrings document them); anything else is rejected with the
key's path. A service's `args` map flag names to values (`num-envs: 4` -> `--num-envs 4`,
lists -> one flag followed by the items, booleans -> `--flag`/`--no-flag`, null -> `None`),
and `<namespace>` in an argument or an output path becomes the stack's namespace, so the
same file runs side by side under `--namespace other` without overwriting files.

    name: demo
    duration_s: 20
    outputs: [runs/<namespace>/stack.mcap]
    services:
      sim: {workers: [0, 1], args: {num-envs: 4}, restart: {max_restarts: 3}}
      record: {args: {output: runs/<namespace>/stack.mcap}}   # auxiliary by default
      watch: {command: echo, args: {period-s: 5}, critical: false}
      policy: {args: {random-init: hamnet}, remap: {state: hamnet/<namespace>-replay/sim/0/state}}
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from hamnet.launcher.schema import SchemaError, build, describe
from hamnet.runtime import keys

Scalar = str | bool | int | float
ArgValue = Scalar | None | tuple[Scalar, ...]
"""What a service's `args` entry may hold."""

RESERVED_ARGS = {
    "worker": "the service's `workers` key",
    "namespace": "the stack's `namespace` key or `hamnet up --namespace`",
    "remap": "the service's `remap` key",
}
"""Flags the launcher sets itself, and where their values come from instead."""

AUXILIARY_COMMANDS = frozenset({"record", "monitor"})
"""Commands whose services are auxiliary unless a stack file says `critical: true`: they
observe the control loop, so their failure must not stop it."""

NAMESPACE = "<namespace>"
"""Placeholder replaced by the stack's namespace in arguments and output paths."""


class StackError(ValueError):
    """A stack file that cannot be run; the message names the file and the key."""


@dataclass(frozen=True)
class RestartPolicy:
    """What the launcher does when a service crashes (non-zero exit or killed by a signal)."""

    max_restarts: int = 3
    """Restarts allowed over the whole run; one more crash stops the stack with an error."""
    backoff_s: float = 0.5
    """Wait before the first restart, doubled after each further crash."""
    backoff_max_s: float = 8.0
    """Longest wait between a crash and the restart."""

    def __post_init__(self) -> None:
        if self.max_restarts < 0:
            raise ValueError(f"max_restarts must be >= 0, got {self.max_restarts}")
        if not 0 <= self.backoff_s <= self.backoff_max_s:
            raise ValueError(
                "need 0 <= backoff_s <= backoff_max_s, "
                f"got {self.backoff_s} and {self.backoff_max_s}"
            )

    def delay_s(self, restart: int) -> float:
        """Seconds to wait before restart number `restart` (0 for the first one)."""
        return min(self.backoff_s * 2.0**restart, self.backoff_max_s)


@dataclass(frozen=True)
class ServiceSpec:
    """One service of a stack: a `hamnet` command run once per worker."""

    command: str
    """`hamnet` command to run (defaults to the service's name in the stack file)."""
    workers: tuple[str, ...] = ("0",)
    """Worker ids: one process per worker, each started with `--worker <id>`."""
    args: Mapping[str, ArgValue] = field(default_factory=dict)
    """Command-line options: flag name (without dashes) -> value."""
    remap: Mapping[str, str] = field(default_factory=dict)
    """Ports rewired: port name -> key (`state: hamnet/<namespace>-replay/sim/0/state`, or a
    path in the stack's namespace such as `sim/1/state`); `hamnet <command> --help` lists a
    service's ports. Each becomes `--remap PORT=KEY`."""
    restart: RestartPolicy = field(default_factory=RestartPolicy)
    """Restart policy of each of its processes."""
    critical: bool | None = None
    """Whether its failure (a crash with no restarts left) stops the stack with exit status 1.
    An auxiliary service (false) fails alone: the launcher logs it, the rest of the stack goes
    on, and the summary lists it. null (default): auxiliary for `record` and `monitor`,
    critical for every other command."""

    def __post_init__(self) -> None:
        if not self.workers:
            raise ValueError("workers must list at least one worker id")
        if len(set(self.workers)) != len(self.workers):
            raise ValueError(f"workers must be distinct, got {list(self.workers)}")
        for worker in self.workers:
            keys.check_segment("worker", worker)
        for flag in self.args:
            if not flag or flag.startswith("-") or any(c.isspace() for c in flag):
                raise ValueError(f"args: {flag!r} is not a flag name (write `num-envs`, no dashes)")
            if flag in RESERVED_ARGS:
                raise ValueError(
                    f"args: {flag!r} is set by the launcher from {RESERVED_ARGS[flag]}"
                )

    @property
    def is_critical(self) -> bool:
        """`critical`, or its default for the command."""
        return self.command not in AUXILIARY_COMMANDS if self.critical is None else self.critical


@dataclass(frozen=True)
class Secure:
    """The stack closed to strangers (docs/security.md): `hamnet up` first starts a router
    with mutual TLS and these access rules, then joins it as a client, as does every service,
    each under its own certificate. Paths are relative to where `hamnet up` runs."""

    tls_dir: str = "certs"
    """Folder of ca.pem and one certificate and key per identity: `router`, `up` and each
    service's command (`hamnet certs stack <stack file>` makes them)."""
    access: str = "compose/secure/router.json5"
    """The router's Zenoh config holding the access rules (`python -m hamnet.security.acl`)."""
    listen: str = "tls/127.0.0.1:7447"
    """tls/<host>:<port> the router listens on and every process connects to (loopback by
    default; a hub's address lets workers on other machines join)."""

    def __post_init__(self) -> None:
        protocol, _, address = self.listen.partition("/")
        host, _, port = address.rpartition(":")
        if protocol != "tls" or not host or not port.isdigit():
            raise ValueError(f"listen must be tls/<host>:<port>, got {self.listen!r}")


ROUTER = "router"
"""The service a `secure` stack gets first: its router (no service of the file may be one)."""


@dataclass(frozen=True)
class Stack:
    """A stack file: services to run together in one namespace, and when the run ends."""

    name: str
    """Name shown in logs and the summary (defaults to the file's stem)."""
    services: Mapping[str, ServiceSpec]
    """Services by name, started in this order."""
    namespace: str
    """Zenoh namespace of every service (defaults to the name; `hamnet up --namespace` wins)."""
    duration_s: float | None = None
    """Stop the stack after this many seconds (`hamnet up --duration-s` wins); null: no bound."""
    until: str | None = None
    """Name of a service whose successful exit (status 0 of every worker) ends the stack."""
    outputs: tuple[str, ...] = ()
    """Files or folders the stack writes, relative to where `hamnet up` runs (for the summary)."""
    ready_timeout_s: float = 30.0
    """Warn when a process has not announced itself (liveliness token) within this time."""
    stop_grace_s: float = 5.0
    """Seconds between SIGTERM and SIGKILL when the stack stops."""
    secure: Secure | None = None
    """Run over mutual TLS with access control, behind a router of its own; null: plain
    links on loopback, open to any local process."""

    def __post_init__(self) -> None:
        if not self.services:
            raise ValueError("services: the stack needs at least one service")
        keys.check_segment("namespace", self.namespace)
        if self.until is not None and self.until not in self.services:
            raise ValueError(f"until: {self.until!r} is not one of the services")
        for name, value in (
            ("duration_s", self.duration_s),
            ("ready_timeout_s", self.ready_timeout_s),
            ("stop_grace_s", self.stop_grace_s),
        ):
            if value is not None and not (value > 0 and math.isfinite(value)):
                raise ValueError(f"{name} must be a positive number of seconds, got {value}")
        owners: dict[tuple[str, str], str] = {}
        for name, spec in self.services.items():
            for worker in spec.workers:
                other = owners.setdefault((spec.command, worker), name)
                if other != name:
                    raise ValueError(
                        f"services {other!r} and {name!r} both run `{spec.command}` as worker "
                        f"{worker!r}: their liveliness tokens would collide; give one other workers"
                    )

    @property
    def output_paths(self) -> tuple[Path, ...]:
        """`outputs` with `<namespace>` replaced."""
        return tuple(Path(expand(path, self.namespace)) for path in self.outputs)


def expand(value: str, namespace: str) -> str:
    """`value` with `<namespace>` replaced by `namespace`."""
    return value.replace(NAMESPACE, namespace)


def parse(document: object, default_name: str) -> Stack:
    """Build a Stack from a parsed YAML document.

    Raises:
        SchemaError: the document does not fit the schema (message: key path and problem).
    """
    if not isinstance(document, Mapping):
        raise SchemaError(f"expected a mapping of stack keys, got {describe(document)}")
    data = {"name": default_name, **document}
    data.setdefault("namespace", data["name"])
    if isinstance(data.get("services"), Mapping):
        # A service's command defaults to its name, so `sim: {}` runs `hamnet sim`.
        data["services"] = {
            name: {"command": name, **body} if isinstance(body, Mapping) else body
            for name, body in data["services"].items()
        }
    stack = build(Stack, data)
    for name, spec in stack.services.items() if stack.secure is not None else ():
        if ROUTER in (name, spec.command):
            raise SchemaError(
                f"services.{name}: a secure stack starts its own router; remove this service"
            )
    return stack


def load(path: Path) -> Stack:
    """Read and validate the stack file at `path` (structure only; see `check` for commands).

    Raises:
        StackError: unreadable file, invalid YAML, or a schema error; the message starts
            with the file's path.
    """
    try:
        document = yaml.safe_load(path.read_text())
        return parse(document, path.stem)
    except OSError as error:
        raise StackError(f"{path}: cannot read the stack file ({error.strerror})") from None
    except yaml.YAMLError as error:
        raise StackError(f"{path}: not valid YAML: {yaml_problem(error)}") from None
    except SchemaError as error:
        raise StackError(f"{path}: {error}") from None


def yaml_problem(error: yaml.YAMLError) -> str:
    """One line for a YAML error: what is wrong and where (line and column, 1-based), without
    the quoted source PyYAML adds on lines of its own."""
    mark = getattr(error, "problem_mark", None)
    problem = getattr(error, "problem", None) or str(error).splitlines()[0]
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    context = getattr(error, "context", None)
    return f"{problem}{where}" + (f" ({context})" if context else "")
